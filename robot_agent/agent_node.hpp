// The robot agent (docs/design.md §1, §4, §7): LCM <-> one robot's LocalMap.
//
//   LMF_SCAN_<id>        in   every scan goes through LocalMap::process_scan
//                             (timed with steady_clock); when the map should
//                             ship: snapshot, reset, publish local_map_t
//   LMF_SCAN_ACK         out  after every processed scan (and after the map it
//                             shipped, if any), with the state after the scan
//   LMF_LOCAL_MAP        out  each shipped map, resent until the server
//                             acknowledges it (waits below)
//   LMF_LOCAL_MAP_ACK    in   RECEIVED: resend only every resend_interval;
//                             FUSED / DUPLICATE / QUEUED: stop resending
//   LMF_CORRECTED_FRAMES in   x_WL of this robot: global pose = x_WL ⊕ x_LR
//   LMF_MISSION_END      in   ship the unfinished map, resend until acked
//   LMF_AGENT_STATUS     out  every status_interval
//
// Scan sequence numbers: the next expected seq is processed; one already
// processed again, with the same time, is a duplicate (a lockstep resend, or
// a player restarted on the same log): re-acked with the answer it had then
// (the last ack_history acks are kept), not reprocessed, so a restarted player
// is led through what the agent has done and continues where it stopped.
// Older ones with another time, or beyond the history, are stale_sequence. A later seq
// (scans lost on the network, --rate replay) is processed and the gap counted,
// unless it is more than max_seq_gap ahead (out_of_range: a forged or foreign
// number). A scan older in time than the last one processed is out_of_range.
// Every refusal is counted by reason (rejects()) and logged rate-limited;
// nothing a message holds can stop the agent.
//
// Local map resends (runtime/retransmission_timeout.hpp): until the server
// answers RECEIVED (on receipt, before the fusion), a map is resent after a
// wait learned from those answers' round trips, between min_resend_interval
// and resend_interval, doubled per further send; once received, every
// resend_interval until its final answer (which waits for the fusion).
//
// A scan that made a map ship is acknowledged once the server has answered
// that map (any answer), so a lockstep player, which sends the next scan only
// after this ack, cannot let anything overtake the map on its way to the
// server: a FIFO server then fuses in lmf-offline's order even when datagrams
// are lost. The hold ends early when the next scan arrives (a --rate player
// does not wait), and after ack_hold (a server that is down or late costs
// that much per map, not a stall). Status goes out at once when the
// mission is done (a lockstep player ends the robots one by one on it).
//
// Corrected frames: x_WL is the origin of local map map_seq. The
// agent may be ahead (it shipped maps the server has not fused yet); it then
// chains the final x_LR of the maps in between (kept since shipping).
//
// Restart (AgentOptions::state_dir, robot_agent/agent_state.hpp): the agent
// persists its chain of local maps at each new map origin (the first scan, each
// ship — before the map is published), each acknowledgement and the mission
// end. A new agent on the same state resumes: it resends the unacknowledged
// maps at once, continues local map `seq` from the persisted origin (the scans
// processed since are lost; the first scan after the restart predicts with the
// odometry since the origin: LocalMap::resume) and re-acks the origin scan if
// the player resends it. The first scan after a restart may be any number of
// seqs ahead (the gap is what was lost; max_seq_gap applies from then on).
//
// Never blocks: publishing is LCM's non-blocking send, resends and status run
// on the event loop's timers (state writes are synchronous: a few per local
// map, each an fsync). Threading: everything runs on the loop's thread.
#pragma once

#include <chrono>
#include <cstdint>
#include <deque>
#include <filesystem>
#include <map>
#include <optional>
#include <random>
#include <string>
#include <vector>

#include "lmf/local_map/local_map.hpp"
#include "robot_agent/agent_state.hpp"
#include "runtime/bus.hpp"
#include "runtime/channels.hpp"
#include "runtime/event_loop.hpp"
#include "runtime/messages.hpp"
#include "runtime/rejection.hpp"
#include "runtime/retransmission_timeout.hpp"

namespace lmf::robot_agent {

struct AgentOptions {
  int robot_id = 0;
  LocalMapConfig local_map;
  runtime::Channels channels;
  std::chrono::milliseconds resend_interval{1000};  // > 0: the longest resend wait
  std::chrono::milliseconds min_resend_interval{5};  // > 0, <= resend_interval: the shortest
  std::chrono::milliseconds ack_hold{1000};          // > 0: the longest a scan's ack waits for its map's answer
  std::chrono::milliseconds status_interval{200};   // > 0
  std::int64_t max_seq_gap = 1000;  // a scan further ahead than this is refused (> 0)
  // Acks kept to answer scans sent again (> 0; ~130 bytes each: 100000 is
  // 2.8 h of a 10 Hz laser, 13 MB).
  std::size_t ack_history = 100'000;
  // Simulated loss (tests): each local-map transmission, first or resend, is
  // dropped with this probability in [0, 1), from a generator seeded with drop_seed.
  double drop_local_maps = 0.0;
  std::uint64_t drop_seed = 1;
  // Folder of the persisted state (agent_state_file(state_dir, robot_id));
  // empty: nothing persisted. Created if missing.
  std::filesystem::path state_dir;
  // Crash tests only: after acknowledging the scan with this seq the agent
  // stops reacting to anything (scans, acks, resends, status), as a hung
  // process, so a test can kill -9 it at a known point of a lockstep replay.
  std::optional<std::int64_t> test_stall_after_scan;
  // Throws std::invalid_argument naming the bad field.
  void validate() const;
};

// What the agent has done, for status messages, logs and tests.
struct AgentCounters {
  std::int64_t scans_processed = 0;
  std::int64_t scans_skipped = 0;      // of those, taken as no new view by the motion filter (dead-reckoned)
  std::int64_t scans_match_tried = 0;  // scans matched against the previous one (scan_matching) ...
  std::int64_t scans_matched = 0;      // ... and those whose prediction used the match
  std::int64_t scans_match_escalated = 0;  // scans whose search escalated to its wider window ...
  std::int64_t scans_matched_from_escalation = 0;  // ... and whose match is the wider window's
  std::int64_t segments_seen_through = 0;  // local map segments removed on free-space evidence (see_through)
  std::int64_t scans_duplicate = 0;  // resent scans re-acked
  std::int64_t scans_missed = 0;     // seq numbers skipped (lost on the way)
  std::int64_t maps_shipped = 0;
  std::int64_t maps_acknowledged = 0;  // distinct maps acked (any status)
  std::int64_t maps_queued = 0;        // of those, acked QUEUED at first
  std::int64_t map_transmissions = 0;  // publish attempts, resends included
  std::int64_t map_transmissions_dropped = 0;  // by the simulated loss
  std::int64_t map_resends = 0;
  std::int64_t scan_acks_held = 0;       // acks of scans that shipped a map, held for its answer
  std::int64_t scan_ack_holds_expired = 0;  // of those, sent after ack_hold without an answer
  std::int64_t ship_failures = 0;      // snapshots the converter refused (lost maps)
  std::int64_t ack_failures = 0;       // scan acks the converter refused
  std::int64_t scan_errors = 0;        // LocalMap threw on a scan that decoded fine
  std::int64_t corrected_frames = 0;   // frame updates applied
  bool covariance_always_ok = true;    // every scan's covariance check passed
  bool resumed = false;                // started from a persisted state
  std::int64_t state_writes = 0;
  std::int64_t state_write_failures = 0;  // logged; the agent keeps going
};

class AgentNode {
 public:
  // Loads the persisted state (if state_dir is set and holds one), subscribes,
  // starts the timers and resends the unacknowledged maps. Throws
  // std::invalid_argument for bad options, AgentStateError for a state that
  // cannot be read or trusted (corrupt, another robot's): never silently
  // started afresh, which would resend seqs the server already holds. The bus
  // and loop must outlive the node.
  AgentNode(runtime::Bus& bus, runtime::EventLoop& loop, AgentOptions options);
  ~AgentNode();
  AgentNode(const AgentNode&) = delete;
  AgentNode& operator=(const AgentNode&) = delete;

  int robot_id() const { return options_.robot_id; }
  const AgentCounters& counters() const { return counters_; }
  // Messages the node refused (bad content, old seq, another robot's).
  const runtime::RejectCounter& rejects() const { return rejects_; }
  // Those plus the ones its Bus refused before decoding (authentication, undecodable).
  runtime::RejectCounter all_rejects() const;
  const LocalMap& local_map() const { return local_map_; }
  // Seq of the next scan expected (0 before any).
  std::int64_t next_scan_seq() const { return next_scan_seq_; }
  // Maps shipped and not yet acknowledged, ascending.
  std::vector<std::int64_t> unacknowledged_maps() const;
  bool joined() const { return frame_.has_value(); }
  // x_WR from the latest corrected frame, if it can be related to the current map.
  std::optional<Pose2> global_pose() const;
  bool mission_ended() const { return mission_ended_; }
  // AgentOptions::test_stall_after_scan was reached.
  bool stalled() const { return stalled_; }
  // The mission ended and every shipped map was acknowledged.
  bool mission_done() const { return mission_ended_ && pending_.empty(); }
  // Every per-scan processing time so far (ms), in scan order.
  const std::vector<double>& scan_times_ms() const { return all_scan_times_ms_; }

  // Publishes a status message now (also done by the timer).
  void publish_status();

 private:
  struct PendingMap {
    std::vector<std::uint8_t> bytes;  // the encoded local_map_t
    std::chrono::steady_clock::time_point last_sent;
    int sends = 0;                    // in this process
    bool received = false;            // answered RECEIVED: the final answer follows a fusion
  };
  struct HeldAck {                    // the ack of the scan that shipped map_seq
    std::int64_t map_seq = 0;
    runtime::ScanAck ack;
  };
  using Frame = AgentState::Frame;

  struct ProcessedScan {  // the latest scan processed: the next map's origin if it ships
    std::int64_t seq = 0;
    std::int64_t utime = 0;
    Pose2 odometry;
  };

  void on_scan(const std::string& channel, const void* data, std::size_t size);
  void process(const runtime::RobotScan& scan);
  // Snapshot, reset, keep the encoded map as pending (not yet sent); its seq
  // if it could be encoded.
  std::optional<std::int64_t> ship();
  void restore(const AgentState& state);
  void persist();
  void transmit(std::int64_t seq, PendingMap& map);
  std::chrono::steady_clock::duration resend_wait(const PendingMap& map) const;
  void schedule_resend();  // the timer, at the earliest resend due
  void resend_due();
  void hold_ack(std::int64_t map_seq, const runtime::ScanAck& ack);
  void release_held_ack(std::int64_t map_seq);  // sends it, if it waits for map_seq
  // A new scan ack went out (sent now or released from its hold).
  void acknowledged(std::int64_t scan_seq);
  void on_local_map_ack(const std::string& channel, const void* data, std::size_t size);
  void on_corrected_frames(const std::string& channel, const void* data, std::size_t size);
  void on_mission_end(const std::string& channel, const void* data, std::size_t size);
  void send_ack(const runtime::ScanAck& ack);
  void reject(runtime::RejectReason reason, std::string detail, std::string_view source);

  runtime::Bus& bus_;
  runtime::EventLoop& loop_;
  AgentOptions options_;
  LocalMap local_map_;
  runtime::RejectCounter rejects_;
  AgentCounters counters_;
  std::mt19937_64 drop_random_;

  std::int64_t next_scan_seq_ = 0;
  std::optional<std::int64_t> last_scan_utime_;
  std::deque<runtime::ScanAck> acks_;  // the last ack_history acks, ascending seq: re-sent for duplicate scans
  bool map_has_scans_ = false;                // the current local map holds a scan
  std::optional<ProcessedScan> last_processed_;
  std::optional<AgentState::Origin> origin_;  // of the local map in progress
  bool any_gap_once_ = false;                 // restarted: the next scan may be any seq ahead
  std::filesystem::path state_file_;          // empty: not persisted
  bool stalled_ = false;

  std::map<std::int64_t, PendingMap> pending_;        // shipped, not acked
  runtime::RetransmissionTimeout map_resend_;
  std::optional<int> resend_timer_;
  std::optional<HeldAck> held_ack_;
  std::optional<int> hold_timer_;
  std::map<std::int64_t, Pose2> shipped_final_x_LR_;  // per shipped map, for chaining frames
  std::optional<Frame> frame_;
  bool mission_ended_ = false;

  std::vector<double> window_scan_times_ms_;
  std::vector<double> all_scan_times_ms_;
  bool window_covariance_ok_ = true;

  std::vector<int> subscriptions_;
  std::vector<int> timers_;
};

}  // namespace lmf::robot_agent
