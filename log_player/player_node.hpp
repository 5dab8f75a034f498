// The log player (docs/design.md §1): replays recorded or simulated robots over LCM as
// if they were running now, with the robot-robot sightings that let robots join.
//
//   LMF_SCAN_<id>   out  each robot's scans, seq from 0 (the scan's index)
//   LMF_SCAN_ACK    in   the agents' acks with their state after each scan
//   LMF_SIGHTING    out  robot B seen by robot A, with each robot's local map
//                        seq, x_L? and covariance taken from the ack of its last
//                        scan at or before the sighting's time; resent until
//                        the server answers, however long it is down: when one
//                        not received is due, all not received in time order
//                        (a server started late or restarted gets them in the
//                        order lmf-offline applies them). Bounded by a queue,
//                        not by a send count: once max_pending_sightings wait,
//                        publishing another gives up the oldest
//   LMF_SIGHTING_ACK in  the server's answer to a sighting: RECEIVED (taken:
//                        resend only every ack_timeout), else stop resending
//   LMF_MISSION_END out  at the end, repeated mission_end_repeats times (lockstep:
//                        first robot by robot, below)
//   LMF_AGENT_STATUS in  lockstep: an agent's mission_done ends its wait
//
// Two pacings:
//  * lockstep: one scan at a time in global time order (ties: lower robot id),
//    the next only after the agent acked it (resent after the learned resend
//    wait, given up after max_attempts sends, never with 0); sightings strictly
//    before the next scan's time are published first, and the scan waits for
//    the server's first answer to them (at most ack_timeout). An agent acks a
//    scan that shipped a local map once the server answered that map
//    (robot_agent/agent_node.hpp), so each local map and sighting reaches the
//    server before the scans and sightings that follow it, lost datagrams
//    included, and a FIFO server fuses exactly as lmf-offline.
//  * rate R: each scan at (its time - first scan time) / R after the start,
//    without waiting; a sighting once its time has come and both robots acked
//    their last scan at or before it (after ack_timeout more, the latest ack
//    before it stands in).
// Resend waits (runtime/retransmission_timeout.hpp) are learned from round
// trips, between min_ack_timeout and ack_timeout, doubled per further send;
// before the first answer, 200 ms backed off the same way (within those
// bounds): for lockstep scans from the scans'
// acks, for sightings from the server's RECEIVED (sent on receipt, before the
// worker applies it). A sighting received waits for its final answer, resent
// every ack_timeout.
// The end in lockstep: each agent ships its unfinished map on the mission end,
// so, for those maps too to reach the server in one order, the mission end
// goes to one robot at a time in id order, each once the previous agent's
// status said mission_done (every map it shipped answered), waiting at most
// ack_timeout per robot; then to all, as in rate mode.
// A sighting whose robot has not scanned yet (no local frame to relate) is
// skipped, as lmf-offline does. The mission end goes out once every published
// sighting was answered or given up (a server that was down when a sighting
// went out still gets it: robots join only through sightings); while it waits,
// the player says on stderr every 10 resends what it still waits for, and
// after end_wait (if set) it gives the rest up.
//
// Progress goes to an optional stream: one refreshed line (a terminal) or a
// line every 10 % (anything else). Threading: everything runs on the loop's thread.
#pragma once

#include <chrono>
#include <cstdint>
#include <functional>
#include <map>
#include <optional>
#include <ostream>
#include <random>
#include <set>
#include <string>
#include <tuple>
#include <vector>

#include "lmf/mission/mission_inputs.hpp"
#include "lmf/sighting_t.hpp"
#include "runtime/bus.hpp"
#include "runtime/channels.hpp"
#include "runtime/event_loop.hpp"
#include "runtime/messages.hpp"
#include "runtime/rejection.hpp"
#include "runtime/retransmission_timeout.hpp"

namespace lmf::log_player {

struct PlayerOptions {
  runtime::Channels channels;
  bool lockstep = false;
  double rate = 1.0;                                // --rate pacing: log time / rate (> 0)
  std::chrono::milliseconds ack_timeout{2000};      // > 0: the longest resend wait
  std::chrono::milliseconds min_ack_timeout{5};     // > 0: the shortest (at most ack_timeout)
  int max_attempts = 10;  // lockstep: sends of one scan before going on without its ack (0: no limit)
  // Sightings sent and not answered yet, at most (> 0); beyond, the oldest is given up.
  std::size_t max_pending_sightings = 1000;
  // After the last scan, how long sightings still unanswered may wait before
  // they are given up and the mission end goes out (>= 0; 0: until answered).
  std::chrono::milliseconds end_wait{0};
  std::chrono::milliseconds start_delay{0};         // before the first scan (subscribers starting)
  std::chrono::milliseconds mission_end_interval{200};
  int mission_end_repeats = 5;                      // >= 1
  enum class Progress { kNone, kLine, kSteps } progress = Progress::kNone;
  std::ostream* progress_stream = nullptr;          // required unless progress is kNone
  std::function<void()> on_finished;                // after the last mission_end_t
  // Simulated loss (tests): each scan transmission, first or resend, is
  // dropped with this probability (seeded), never reaching the bus.
  double drop_scans = 0.0;
  std::uint64_t drop_seed = 1;
  // Throws std::invalid_argument naming the bad field.
  void validate() const;
  // Whether something already sent `attempts` times may be sent once more.
  bool may_send_again(int attempts) const { return max_attempts == 0 || attempts < max_attempts; }
};

struct PlayerCounters {
  std::int64_t scans_total = 0;
  std::int64_t scans_sent = 0;       // first sends
  std::int64_t scan_resends = 0;     // lockstep resends after a timeout
  std::int64_t scans_acked = 0;      // distinct scans acknowledged
  std::int64_t scans_given_up = 0;   // lockstep: no ack after max_attempts sends
  std::int64_t scan_transmissions_dropped = 0;  // by the simulated loss (drop_scans)
  std::int64_t acks_duplicate = 0;
  std::int64_t sightings_total = 0;
  std::int64_t sightings_published = 0;
  std::int64_t sightings_approximate = 0;  // published with an earlier ack standing in
  std::int64_t sightings_skipped = 0;      // a robot had not scanned yet (or unknown / bad values)
  std::int64_t sighting_resends = 0;       // sends after a resend wait without answer
  std::int64_t sighting_receipt_waits_expired = 0;  // lockstep: the next scan went out without their answer
  std::int64_t sightings_acked = 0;        // answered APPLIED or DUPLICATE
  std::int64_t sightings_rejected = 0;     // answered REJECTED (the server refused it)
  std::int64_t sightings_unanswered = 0;   // given up unanswered: the queue was full, or end_wait passed
  std::int64_t sighting_acks_duplicate = 0;  // answers to a sighting already answered
  std::int64_t mission_end_sent = 0;
  std::int64_t mission_end_waits_expired = 0;  // lockstep: a robot's mission_done not seen within ack_timeout
};

class PlayerNode {
 public:
  // Throws std::invalid_argument for bad options or inputs (no robots,
  // duplicate or negative ids, scans out of time order).
  PlayerNode(runtime::Bus& bus, runtime::EventLoop& loop, mission::MissionInputs inputs, PlayerOptions options);
  ~PlayerNode();
  PlayerNode(const PlayerNode&) = delete;
  PlayerNode& operator=(const PlayerNode&) = delete;

  // Starts the replay after options.start_delay. Call once.
  void start();
  // The last mission_end_t went out.
  bool finished() const { return finished_; }
  const PlayerCounters& counters() const { return counters_; }
  const runtime::RejectCounter& rejects() const { return rejects_; }
  const mission::MissionInputs& inputs() const { return inputs_; }
  // The latest ack of (robot id, seq), if received.
  std::optional<runtime::ScanAck> ack(int robot_id, std::int64_t seq) const;
  // A one-line summary for logs.
  std::string summary() const;

 private:
  struct ScanEvent {
    std::int64_t utime = 0;
    std::size_t robot = 0;  // index into inputs_.robots
    std::size_t scan = 0;   // index = seq
  };
  enum class SightingOutcome { kPublished, kSkipped, kWait };

  void begin();
  void send_scan(const ScanEvent& event);
  static std::chrono::milliseconds wait_for(const runtime::RetransmissionTimeout& resend, int sends);
  void on_ack(const std::string& channel, const void* data, std::size_t size);
  void on_sighting_ack(const std::string& channel, const void* data, std::size_t size);
  // Lockstep.
  void lockstep_step();
  void lockstep_timeout(std::size_t event_index);
  // Rate.
  void rate_pump();
  // Publishes sightings in order while they resolve (before `before_utime`, and
  // due by wall time in rate mode); stops at the first that must wait.
  void publish_sightings(std::int64_t before_utime, bool allow_fallback);
  SightingOutcome try_sighting(const mission::SightingInput& sighting, bool allow_fallback);
  using SightingKey = std::tuple<std::int64_t, int, int>;  // (utime, observer, observed)
  void resend_sightings();
  void give_up_oldest_sighting();  // the queue of pending sightings is full
  void give_up_pending_sightings();  // end_wait passed after the replay
  void on_sightings_answered();  // none pending any more
  void on_sighting_received(const SightingKey& key);  // any answer: the lockstep wait for it ends
  std::optional<runtime::ScanAck> ack_at_or_before(std::size_t robot, std::int64_t utime, bool allow_fallback,
                                                   bool* approximate) const;
  void finish();
  void end_next_robot();  // lockstep: the mission end to one robot at a time
  void on_agent_status(const std::string& channel, const void* data, std::size_t size);
  void send_mission_end();
  void report_progress(bool force);
  std::chrono::steady_clock::time_point due_time(std::int64_t utime) const;

  runtime::Bus& bus_;
  runtime::EventLoop& loop_;
  mission::MissionInputs inputs_;
  PlayerOptions options_;
  runtime::RejectCounter rejects_;
  PlayerCounters counters_;

  std::map<int, std::size_t> robot_index_;           // robot id -> index
  std::vector<ScanEvent> events_;                     // global time order
  std::vector<std::vector<std::optional<runtime::ScanAck>>> acks_;  // [robot][seq]
  std::size_t next_event_ = 0;
  std::size_t next_sighting_ = 0;
  int attempts_ = 0;                                  // lockstep: sends of events_[next_event_]
  std::chrono::steady_clock::time_point first_sent_;  // lockstep: of events_[next_event_]
  runtime::RetransmissionTimeout scan_resend_;
  std::mt19937_64 drop_random_;
  std::optional<int> ack_timer_;
  std::optional<int> step_timer_;                     // the next lockstep step or mission_end_t repeat

  // Published sightings not answered yet, and every one published.
  struct PendingSighting {
    lmf::sighting_t message;
    int attempts = 0;
    std::chrono::steady_clock::time_point last_sent;
    bool received = false;  // answered RECEIVED: the final answer follows
  };
  std::chrono::steady_clock::duration resend_wait(const PendingSighting& sighting) const;
  void schedule_sighting_resend();
  void send_sighting(PendingSighting& sighting);
  std::map<SightingKey, PendingSighting> pending_sightings_;  // in time order
  runtime::RetransmissionTimeout sighting_resend_;
  std::set<SightingKey> awaiting_receipt_;  // lockstep: published before the next scan, not answered yet
  std::optional<int> receipt_timer_;        // lockstep: the longest wait for them (ack_timeout)
  std::optional<int> sighting_timer_;
  std::optional<int> end_wait_timer_;
  std::set<SightingKey> published_sightings_;
  bool ending_ = false;  // the replay is over; mission_end_t once no sighting is pending
  std::size_t ending_robot_ = 0;                      // lockstep: index of the robot being ended
  std::chrono::steady_clock::time_point ending_robot_since_;
  std::vector<bool> robot_done_;                      // [robot]: its agent reported mission_done

  bool started_ = false;
  bool replay_done_ = false;  // every scan sent (and, lockstep, acked or given up)
  bool finished_ = false;
  std::chrono::steady_clock::time_point start_time_;
  std::chrono::steady_clock::time_point last_send_time_;
  std::chrono::steady_clock::time_point last_progress_time_;
  int last_progress_decile_ = 0;

  std::vector<int> subscriptions_;
  std::vector<int> timers_;
};

}  // namespace lmf::log_player
