// The fusion server (docs/design.md §1, §5, §7): LCM in,
// GlobalMap in a background worker, acknowledgements, corrected frames, map
// summaries and status out, map/trajectory/report files on request and at exit.
//
// Receiving a local map (LMF_LOCAL_MAP), on the loop thread:
//   decode + validate (runtime/convert) -> reject by reason;
//   robot id >= max_robots               -> reject unknown_robot;
//   (robot, seq) already applied         -> ack DUPLICATE, count stale_sequence, never re-applied;
//   (robot, seq) waiting in the worker   -> ack RECEIVED again (the final ack follows);
//   worker queue full                    -> nothing: no ack, so the agent resends later;
//   else journaled, queued to the worker and acked RECEIVED at once (so the
//   agent's resend wait can follow the round trip, not the fusion time). The
//   worker calls GlobalMap::fuse; an invalid_argument from it is a counted
//   reject (the map is unchanged). The final ack (FUSED, or QUEUED when the
//   GlobalMap holds it for a robot that has not joined) is sent on the loop
//   thread once the GlobalMap accepted it. Local maps fused later (when their
//   robot joins) get a FUSED ack then too.
// Sightings (LMF_SIGHTING), named by (utime, observer, observed), are validated
// the same way and go through the SAME worker FIFO, so a lockstep replay fuses
// in lmf-offline's order. Each is answered on LMF_SIGHTING_ACK (the player
// resends it until then): RECEIVED once taken, APPLIED once the worker gave it
// to the GlobalMap, REJECTED when the GlobalMap or the checks here refused it
// (robot id >= max_robots, a robot sighting itself), DUPLICATE for a repeat of
// one already answered (also counted stale_sequence); a repeat still waiting
// in the worker gets RECEIVED again.
//
// Ownership across threads: the FusionContext (fusion_context.hpp: the
// GlobalMap, the TrajectoryBook, the fusion records, the outputs) belongs to the
// worker thread (and to the caller of shutdown() once the worker is joined); the
// loop thread never touches it. After each task the
// worker posts a MapView (counts, corrected frames, segment end points, timing)
// back to the loop with EventLoop::post; everything published comes from it.
//
// Publications: corrected_frames_t after each fusion and every frames_interval;
// global_map_t after fusions (at most one per map_min_interval) and every
// map_interval; server_status_t every status_interval.
//
// Durable state (state_dir set; fusion_server/state_store.hpp): every local
// map and sighting that passes the checks above is appended to the journal
// (fsync'ed) on the loop thread just before it enters the worker FIFO, so the
// journal order is the fusion order and nothing is acked before it is on disk.
// The worker encodes a snapshot (map, book and records) after a task once
// snapshot_interval has passed since the last one (0: after every task; a
// snapshot still being written is not waited for: the next task or the idle
// timer tries again), and at shutdown; the store's writer thread writes it. At construction the snapshot is loaded and the
// journal after it replayed through fuse_task/sighting_task, the same code path
// as live input; resent local maps that it already applied are then acked
// DUPLICATE.
#pragma once

#include <array>
#include <chrono>
#include <cstdint>
#include <filesystem>
#include <map>
#include <memory>
#include <optional>
#include <set>
#include <span>
#include <string>
#include <tuple>
#include <utility>
#include <vector>

#include "fusion_server/fusion_context.hpp"
#include "fusion_server/fusion_worker.hpp"
#include "fusion_server/state_store.hpp"
#include "lmf/fusion/global_map.hpp"
#include "lmf/mission/trajectory_book.hpp"
#include "runtime/bus.hpp"
#include "runtime/channels.hpp"
#include "runtime/convert.hpp"
#include "runtime/event_loop.hpp"
#include "runtime/messages.hpp"
#include "runtime/rejection.hpp"

namespace lmf::server {

struct ServerOptions {
  fusion::GlobalMapConfig global_map;
  std::filesystem::path out_dir = "out/server";
  bool map_svg_graph = false;  // draw the environment graph in out_dir/map.svg (fusion::MapSvgOptions::graph)
  // Joins at start with L = W (zero covariance, local map 0). nullopt: the
  // first local map received defines W (GlobalMapConfig::first_robot_defines_world).
  std::optional<int> first_robot = 0;
  int max_robots = 64;                      // robot ids 0 .. max_robots-1 are known
  std::size_t queue_capacity = 32;          // local maps waiting for the worker
  std::chrono::milliseconds status_interval{500};
  std::chrono::milliseconds frames_interval{1000};
  std::chrono::milliseconds map_interval{2000};
  std::chrono::milliseconds map_min_interval{250};  // rate limit of global_map_t after fusions
  std::chrono::seconds write_interval{0};           // 0: only on request and at shutdown
  runtime::DecodeLimits limits;
  // Durable state: empty = none. See the header comment and state_store.hpp.
  std::filesystem::path state_dir;
  std::chrono::milliseconds snapshot_interval{5000};  // 0: after every fusion / sighting
  int state_test_pause_at = 0;                        // StateStoreOptions::test_pause_at
  std::chrono::milliseconds state_test_pause{0};

  // Throws std::invalid_argument naming the bad field.
  void validate() const;
};

struct ServerStats {
  std::int64_t acks_fused = 0;
  std::int64_t acks_duplicate = 0;
  std::int64_t acks_queued = 0;
  std::int64_t acks_received = 0;           // RECEIVED: taken, the final answer follows
  std::int64_t sighting_acks_applied = 0;
  std::int64_t sighting_acks_duplicate = 0;
  std::int64_t sighting_acks_rejected = 0;
  std::int64_t sighting_acks_received = 0;
  std::int64_t local_maps_received = 0;  // every LMF_LOCAL_MAP message, good or bad
  std::int64_t sightings_received = 0;
  std::int64_t sightings_applied = 0;    // handed to the GlobalMap without error
  std::int64_t resends_while_waiting = 0;  // local maps and sightings repeated while in the worker (answered RECEIVED)
  std::int64_t deferred_queue_full = 0;  // not acked because the worker queue was full
  std::int64_t discarded_at_stop = 0;    // waiting tasks never started (never acked)
  std::int64_t worker_errors = 0;
  std::int64_t journal_failures = 0;     // not journaled (I/O error): not applied, not acked
};

// What the server found in its state directory at start.
struct StateRecovery {
  std::string from = "none";            // "new", "snapshot", "snapshot.prev", "journal"
  std::int64_t snapshot_lsn = 0;
  std::int64_t replayed_local_maps = 0;
  std::int64_t replayed_sightings = 0;
  std::int64_t lsn = 0;                 // the state after recovery
  std::int64_t fusions = 0;             // fusions in the recovered state
  double ms = 0.0;                      // load + replay + first snapshot
  std::vector<std::string> problems;
};

class ServerNode {
 public:
  // Subscribes, joins the first robot, starts the worker and the timers.
  // Throws std::invalid_argument for bad options.
  ServerNode(runtime::Bus& bus, runtime::EventLoop& loop, runtime::Channels channels, ServerOptions options);
  // shutdown() without writing if it was not called.
  ~ServerNode();
  ServerNode(const ServerNode&) = delete;
  ServerNode& operator=(const ServerNode&) = delete;

  // Queues a write of the outputs behind the tasks already waiting (SIGUSR1,
  // the write timer). Loop thread.
  void request_write();

  // Stops taking messages, lets the running fusion finish, discards the tasks
  // not started (they were never acknowledged), then writes the outputs into
  // out_dir (if `write_outputs`). Call after the loop stopped. Idempotent.
  // Returns false if writing failed (the error is on stderr).
  bool shutdown(bool write_outputs = true);

  // Loop-thread views (tests, status).
  const MapView& view() const { return view_; }
  const ServerStats& stats() const { return stats_; }
  const runtime::RejectCounter& rejects() const { return rejects_; }
  // Rejections of this node and of the bus (decode failures, handler errors), by name.
  runtime::RejectCounts reject_counts() const;
  // Tasks waiting or running in the worker (any thread).
  bool worker_busy() const { return worker_ && worker_->busy(); }
  std::size_t queue_length() const { return worker_ ? worker_->waiting() : 0; }
  const ServerOptions& options() const { return options_; }
  // The GlobalMap once shutdown() joined the worker (nullptr before): for
  // tests and tools that compare the final map.
  const fusion::GlobalMap* map_after_shutdown() const { return stopped_ ? &fusion_.map() : nullptr; }
  // The durable state (nullptr without state_dir) and what recovery found.
  const StateStore* state_store() const { return store_.get(); }
  const StateRecovery& recovery() const { return recovery_; }

  // What the status and map messages carry, public for tests.
  runtime::ServerStatus make_status() const;
  runtime::GlobalMapSummary make_global_map() const;

 private:
  // Worker-side results, posted back to the loop.
  struct Outcome;
  // Loop-side snapshot of the counters that go into report.json.
  struct LoopSnapshot {
    ServerStats stats;
    std::vector<std::pair<std::string, std::int64_t>> rejects;
  };
  void on_local_map(const void* data, std::size_t size);
  void on_sighting(const void* data, std::size_t size);
  void on_outcome(Outcome& outcome);
  void post_outcome(std::shared_ptr<Outcome> outcome);

  // Worker side.
  void fuse_task(LocalMapSnapshot snapshot, std::chrono::steady_clock::time_point arrived);
  void sighting_task(const fusion::RobotSighting& sighting, std::chrono::steady_clock::time_point arrived);
  // Durable state: load + replay (constructor), after each journaled task, snapshots.
  void recover_state();
  void replay(const JournalRecord& record);
  // `signer`: who signed the journaled input (authenticated servers), whose
  // number the persisted replay windows then refuse.
  void after_task(std::int64_t lsn, const std::optional<runtime::auth::SignedBy>& signer);
  // The bytes an input is journaled as (its trailer kept when signatures are
  // verified) and who signed it; loop thread, inside a handler.
  std::pair<std::span<const std::uint8_t>, std::optional<runtime::auth::SignedBy>> as_journaled(const void* data,
                                                                                               std::size_t size) const;
  // Encodes and submits a snapshot if anything was applied since the last one
  // and the store's writer is free; `at_stop`: waits for the writer and writes
  // synchronously, dirty or not.
  void snapshot_now(bool at_stop = false);
  std::string encode_state() const;
  bool write_outputs(const LoopSnapshot& loop_side) const;

  void publish_ack(int robot_id, std::int64_t seq, runtime::LocalMapAck::Status status);
  void publish_sighting_ack(const fusion::RobotSighting& s, runtime::SightingAck::Status status);
  void publish_frames();
  void publish_global_map();
  void publish_global_map_rate_limited();
  void publish_status();
  LoopSnapshot loop_snapshot() const;

  runtime::Bus& bus_;
  runtime::EventLoop& loop_;
  runtime::Channels channels_;
  ServerOptions options_;

  // ---- worker side (see the header comment) ----
  FusionContext fusion_;
  std::unique_ptr<StateStore> store_;  // its append() is called from the loop thread
  std::int64_t applied_lsn_ = 0;       // last journal record applied
  runtime::auth::HighWater taken_high_water_;  // per signer, the highest seq of an input applied
  bool state_dirty_ = false;           // applied something since the last snapshot
  double encode_ms_max_ = 0.0;
  std::chrono::steady_clock::time_point last_snapshot_{};
  StateRecovery recovery_;             // set in the constructor, read-only after

  // ---- loop side ----
  struct RobotSeqs {
    std::set<std::int64_t> applied;  // acked FUSED or QUEUED
    std::set<std::int64_t> waiting;  // in the worker queue
  };
  std::map<int, RobotSeqs> seqs_;
  using SightingKey = std::tuple<std::int64_t, int, int>;  // (utime, observer, observed)
  std::set<SightingKey> sightings_answered_;  // acked (or applied before a restart)
  std::set<SightingKey> sightings_waiting_;   // in the worker queue
  runtime::RejectCounter rejects_;
  ServerStats stats_;
  MapView view_;
  std::chrono::steady_clock::time_point last_map_publish_{};
  bool map_publish_scheduled_ = false;
  std::optional<int> map_timer_;
  std::shared_ptr<bool> alive_ = std::make_shared<bool>(true);
  bool write_pending_ = false;
  bool stopped_ = false;
  std::vector<int> timers_;
  std::vector<int> subscriptions_;

  std::unique_ptr<FusionWorker> worker_;  // last: joined first on destruction
};

}  // namespace lmf::server
