#include "fusion_server/server_node.hpp"

#include <algorithm>
#include <cmath>
#include <exception>
#include <fstream>
#include <iostream>
#include <limits>
#include <sstream>
#include <stdexcept>
#include <string_view>

#include <nlohmann/json.hpp>

#include "lmf/fusion/global_map_archive.hpp"
#include "lmf/fusion/map_export.hpp"
#include "lmf/mission/mission_report.hpp"
#include "lmf/io/trajectory.hpp"

namespace lmf::server {
namespace {

using Clock = std::chrono::steady_clock;
using nlohmann::json;

double ms_since(Clock::time_point since, Clock::time_point now = Clock::now()) {
  return std::chrono::duration<double, std::milli>(now - since).count();
}

std::int64_t wall_utime() {
  return std::chrono::duration_cast<std::chrono::microseconds>(
             std::chrono::system_clock::now().time_since_epoch())
      .count();
}

// The fusion's own validation failed (after runtime's passed): its typed reason
// names the counter, whatever the message says.
runtime::RejectReason reason_of(fusion::InvalidInput::Reason reason) {
  using R = fusion::InvalidInput::Reason;
  switch (reason) {
    case R::kDuplicate: return runtime::RejectReason::kStaleSequence;
    case R::kNotSymmetricPsd: return runtime::RejectReason::kCovarianceNotPsd;
    case R::kNonFinite: return runtime::RejectReason::kNonFinite;
    case R::kMalformed: return runtime::RejectReason::kWrongSize;
    case R::kOutOfRange: return runtime::RejectReason::kOutOfRange;
  }
  return runtime::RejectReason::kOutOfRange;
}

}  // namespace

void ServerOptions::validate() const {
  global_map.validate();
  if (first_robot && *first_robot < 0) throw std::invalid_argument("--first-robot must be >= 0");
  if (max_robots < 1) throw std::invalid_argument("--max-robots must be >= 1");
  if (first_robot && *first_robot >= max_robots) {
    throw std::invalid_argument("--first-robot " + std::to_string(*first_robot) + " is not below --max-robots " +
                                std::to_string(max_robots));
  }
  if (queue_capacity < 1) throw std::invalid_argument("--queue-capacity must be >= 1");
  if (status_interval.count() <= 0) throw std::invalid_argument("--status-interval-ms must be > 0");
  if (frames_interval.count() <= 0) throw std::invalid_argument("--frames-interval-ms must be > 0");
  if (map_interval.count() <= 0) throw std::invalid_argument("--map-interval-ms must be > 0");
  if (map_min_interval.count() < 0) throw std::invalid_argument("map_min_interval must be >= 0");
  if (write_interval.count() < 0) throw std::invalid_argument("--write-interval-s must be >= 0");
  if (snapshot_interval.count() < 0) throw std::invalid_argument("--snapshot-interval-ms must be >= 0");
  if (state_test_pause_at < 0 || state_test_pause.count() < 0) {
    throw std::invalid_argument("--state-test-pause: snapshot number and milliseconds must be >= 0");
  }
}

// What one worker task produced, handed to the loop thread.
struct ServerNode::Outcome {
  enum class Kind { kLocalMap, kSighting, kWrite } kind = Kind::kLocalMap;
  int robot_id = 0;
  std::int64_t seq = 0;
  std::optional<runtime::Rejection> rejection;  // the GlobalMap refused the input
  std::optional<fusion::RobotSighting> sighting;    // kSighting: the one applied
  bool queued_in_map = false;                   // local map held until its robot joins
  std::vector<std::pair<int, std::int64_t>> fused;  // (robot, seq) fused by this task
  MapView view;
};

ServerNode::ServerNode(runtime::Bus& bus, runtime::EventLoop& loop, runtime::Channels channels,
                       ServerOptions options)
    : bus_(bus), loop_(loop), channels_(std::move(channels)), options_(std::move(options)),
      fusion_(fusion::GlobalMap((options_.validate(), options_.global_map))) {
  if (!options_.state_dir.empty()) {
    recover_state();  // joins the first robot itself when the state is new
  } else if (options_.first_robot) {
    fusion_.join_first_robot(*options_.first_robot);
  }
  if (options_.first_robot) seqs_[*options_.first_robot];
  view_ = fusion_.view();

  subscriptions_.push_back(bus_.subscribe(
      channels_.local_map(), [this](const std::string&, const void* data, std::size_t size) { on_local_map(data, size); }));
  subscriptions_.push_back(bus_.subscribe(
      channels_.sighting(), [this](const std::string&, const void* data, std::size_t size) { on_sighting(data, size); }));

  timers_.push_back(loop_.every(options_.status_interval, [this] { publish_status(); }));
  timers_.push_back(loop_.every(options_.frames_interval, [this] { publish_frames(); }));
  timers_.push_back(loop_.every(options_.map_interval, [this] { publish_global_map(); }));
  if (options_.write_interval.count() > 0) {
    timers_.push_back(loop_.every(std::chrono::duration_cast<std::chrono::milliseconds>(options_.write_interval),
                                  [this] { request_write(); }));
  }
  if (store_) {
    // An idle server still snapshots what it applied (bounds the journal to replay).
    timers_.push_back(loop_.every(std::max(options_.snapshot_interval, std::chrono::milliseconds(1000)), [this] {
      if (!stopped_) worker_->try_push([this] { snapshot_now(); }, FusionWorker::Bound::kUnbounded);
    }));
  }
  worker_ = std::make_unique<FusionWorker>(options_.queue_capacity);
}

ServerNode::~ServerNode() { shutdown(false); }

// ---- loop thread: receiving -------------------------------------------------

void ServerNode::on_local_map(const void* data, std::size_t size) {
  ++stats_.local_maps_received;
  if (stopped_) return;
  auto decoded = runtime::decode<LocalMapSnapshot>(data, size, options_.limits);
  if (!decoded) {
    rejects_.record(decoded.rejection(), channels_.local_map());
    return;
  }
  LocalMapSnapshot& snapshot = decoded.value();
  const int robot_id = snapshot.robot_id;
  const std::int64_t seq = snapshot.seq;
  const std::string where = "local map (" + std::to_string(robot_id) + ", " + std::to_string(seq) + ")";
  if (robot_id >= options_.max_robots) {
    rejects_.record({runtime::RejectReason::kUnknownRobot,
                     where + ": robot id not below --max-robots " + std::to_string(options_.max_robots)},
                    channels_.local_map());
    return;
  }
  RobotSeqs& seqs = seqs_[robot_id];
  if (seqs.applied.count(seq) != 0) {
    // A resend whose ack was lost, or a replay: answer, never re-apply.
    rejects_.record({runtime::RejectReason::kStaleSequence, where + ": already applied"}, channels_.local_map());
    publish_ack(robot_id, seq, runtime::LocalMapAck::Status::kDuplicate);
    return;
  }
  if (seqs.waiting.count(seq) != 0) {
    ++stats_.resends_while_waiting;  // its RECEIVED was lost or is late: again; FUSED or QUEUED follows
    publish_ack(robot_id, seq, runtime::LocalMapAck::Status::kReceived);
    return;
  }
  const auto arrived = Clock::now();
  const bool room = worker_->has_room();
  std::int64_t lsn = 0;
  const auto [journaled, signer] = as_journaled(data, size);
  if (room && store_) {
    // On disk before the worker sees it (so before any ack); in FIFO order.
    try {
      lsn = store_->append(channels_.local_map(), journaled.data(), journaled.size(), wall_utime());
    } catch (const StateError& e) {
      ++stats_.journal_failures;
      std::cerr << "lmf-server: " << where << " NOT taken (the agent will resend it): " << e.what() << '\n';
      return;
    }
  }
  const bool taken = room && worker_->try_push([this, snapshot = std::move(snapshot), arrived, lsn, signer]() mutable {
    fuse_task(std::move(snapshot), arrived);
    after_task(lsn, signer);
  });
  if (!taken) {
    // Back-pressure: not acked, so the agent resends it (never dropped silently).
    ++stats_.deferred_queue_full;
    if (stats_.deferred_queue_full <= 10 || stats_.deferred_queue_full % 100 == 0) {
      std::cerr << "lmf-server: fusion queue full (" << options_.queue_capacity << "), " << where
                << " deferred until resent (" << stats_.deferred_queue_full << " so far)\n";
    }
    return;
  }
  seqs.waiting.insert(seq);
  // Taken (on disk with --state): the agent stops resending at its learned
  // pace, and a lockstep agent releases the scan ack it held for this map.
  publish_ack(robot_id, seq, runtime::LocalMapAck::Status::kReceived);
}

void ServerNode::on_sighting(const void* data, std::size_t size) {
  ++stats_.sightings_received;
  if (stopped_) return;
  auto decoded = runtime::decode<fusion::RobotSighting>(data, size, options_.limits);
  if (!decoded) {
    rejects_.record(decoded.rejection(), channels_.sighting());
    return;
  }
  const fusion::RobotSighting& s = decoded.value();
  const std::string where = "sighting " + std::to_string(s.observer_id) + " -> " + std::to_string(s.observed_id) +
                            " at " + std::to_string(s.utime);
  if (s.observer_id >= options_.max_robots || s.observed_id >= options_.max_robots) {
    rejects_.record({runtime::RejectReason::kUnknownRobot,
                     where + ": robot id not below --max-robots " + std::to_string(options_.max_robots)},
                    channels_.sighting());
    publish_sighting_ack(s, runtime::SightingAck::Status::kRejected);
    return;
  }
  if (s.observer_id == s.observed_id) {
    rejects_.record({runtime::RejectReason::kOutOfRange, where + ": a robot cannot sight itself"},
                    channels_.sighting());
    publish_sighting_ack(s, runtime::SightingAck::Status::kRejected);
    return;
  }
  const SightingKey key{s.utime, s.observer_id, s.observed_id};
  if (sightings_answered_.count(key) != 0) {
    // A resend whose ack was lost, or a replay: answer, never re-apply.
    rejects_.record({runtime::RejectReason::kStaleSequence, where + ": already received"}, channels_.sighting());
    publish_sighting_ack(s, runtime::SightingAck::Status::kDuplicate);
    return;
  }
  if (sightings_waiting_.count(key) != 0) {
    ++stats_.resends_while_waiting;  // its RECEIVED was lost or is late: again; APPLIED or REJECTED follows
    publish_sighting_ack(s, runtime::SightingAck::Status::kReceived);
    return;
  }
  const auto arrived = Clock::now();
  std::int64_t lsn = 0;
  const auto [journaled, signer] = as_journaled(data, size);
  if (store_) {
    try {
      lsn = store_->append(channels_.sighting(), journaled.data(), journaled.size(), wall_utime());
    } catch (const StateError& e) {
      ++stats_.journal_failures;
      std::cerr << "lmf-server: " << where << " NOT taken (the player will resend it): " << e.what() << '\n';
      return;
    }
  }
  sightings_waiting_.insert(key);
  // Unbounded: a sighting is tiny, and one waiting is not taken twice (FusionWorker header).
  worker_->try_push(
      [this, s, arrived, lsn, signer] {
        sighting_task(s, arrived);
        after_task(lsn, signer);
      },
      FusionWorker::Bound::kUnbounded);
  publish_sighting_ack(s, runtime::SightingAck::Status::kReceived);
}

std::pair<std::span<const std::uint8_t>, std::optional<runtime::auth::SignedBy>> ServerNode::as_journaled(
    const void* data, std::size_t size) const {
  const std::span<const std::uint8_t> payload(static_cast<const std::uint8_t*>(data), size);
  if (!store_ || !bus_.authenticated()) return {payload, std::nullopt};
  const std::span<const std::uint8_t> received = bus_.message_as_received();
  if (received.size() < size) return {payload, std::nullopt};  // not inside a Bus handler
  return {received, runtime::auth::signed_by(received)};
}

void ServerNode::on_outcome(Outcome& outcome) {
  view_ = std::move(outcome.view);
  switch (outcome.kind) {
    case Outcome::Kind::kWrite:
      write_pending_ = false;
      return;
    case Outcome::Kind::kSighting: {
      const fusion::RobotSighting& s = *outcome.sighting;
      // Answered either way: a repeat gets DUPLICATE (resending a rejected one cannot help).
      sightings_waiting_.erase({s.utime, s.observer_id, s.observed_id});
      sightings_answered_.insert({s.utime, s.observer_id, s.observed_id});
      if (outcome.rejection) {
        rejects_.record(*outcome.rejection, channels_.sighting());
        publish_sighting_ack(s, runtime::SightingAck::Status::kRejected);
      } else {
        ++stats_.sightings_applied;
        publish_sighting_ack(s, runtime::SightingAck::Status::kApplied);
      }
      break;
    }
    case Outcome::Kind::kLocalMap: {
      RobotSeqs& seqs = seqs_[outcome.robot_id];
      seqs.waiting.erase(outcome.seq);
      if (outcome.rejection) {
        rejects_.record(*outcome.rejection, channels_.local_map());
      } else if (outcome.queued_in_map) {
        seqs.applied.insert(outcome.seq);
        publish_ack(outcome.robot_id, outcome.seq, runtime::LocalMapAck::Status::kQueued);
      }
      break;
    }
  }
  for (const auto& [robot_id, seq] : outcome.fused) {
    seqs_[robot_id].applied.insert(seq);
    publish_ack(robot_id, seq, runtime::LocalMapAck::Status::kFused);
  }
  if (!outcome.fused.empty()) {
    publish_frames();
    publish_global_map_rate_limited();
  }
}

// ---- worker thread ------------------------------------------------------------

void ServerNode::fuse_task(LocalMapSnapshot snapshot, Clock::time_point arrived) {
  const double wait_ms = ms_since(arrived);
  auto outcome = std::make_shared<Outcome>();
  outcome->kind = Outcome::Kind::kLocalMap;
  outcome->robot_id = snapshot.robot_id;
  outcome->seq = snapshot.seq;
  try {
    const std::vector<fusion::FusionReport> reports = fusion_.fuse(snapshot, wait_ms);
    for (const auto& r : reports) outcome->fused.emplace_back(r.robot_id, r.seq);
    outcome->queued_in_map = fusion_.map().is_queued(snapshot.robot_id, snapshot.seq);
  } catch (const fusion::InvalidInput& e) {
    outcome->rejection = runtime::Rejection{reason_of(e.reason()), e.what()};
  } catch (const std::invalid_argument& e) {  // from below the fusion's own checks: never fatal
    outcome->rejection = runtime::Rejection{runtime::RejectReason::kOutOfRange, e.what()};
  }
  outcome->view = fusion_.view();
  post_outcome(std::move(outcome));
}

void ServerNode::sighting_task(const fusion::RobotSighting& sighting, Clock::time_point arrived) {
  const double wait_ms = ms_since(arrived);
  auto outcome = std::make_shared<Outcome>();
  outcome->kind = Outcome::Kind::kSighting;
  outcome->robot_id = sighting.observed_id;
  outcome->sighting = sighting;
  try {
    const fusion::SightingResult result = fusion_.add_sighting(sighting, wait_ms);
    for (const auto& r : result.fused) outcome->fused.emplace_back(r.robot_id, r.seq);
  } catch (const fusion::InvalidInput& e) {  // recorded as rejected
    outcome->rejection = runtime::Rejection{reason_of(e.reason()), e.what()};
  } catch (const std::invalid_argument& e) {  // from below the fusion's own checks: never fatal
    outcome->rejection = runtime::Rejection{runtime::RejectReason::kOutOfRange, e.what()};
  }
  outcome->view = fusion_.view();
  post_outcome(std::move(outcome));
}

// ---- durable state (constructor, then worker thread) ---------------------------

void ServerNode::recover_state() {
  const auto started = Clock::now();
  store_ = std::make_unique<StateStore>(
      StateStoreOptions{options_.state_dir, options_.state_test_pause_at, options_.state_test_pause});
  Recovery rec = store_->recover();
  if (rec.state) {
    ServerState& st = *rec.state;
    if (!fusion::same_config(st.fusion.map().config(), options_.global_map)) {
      throw StateError("the state in " + options_.state_dir.string() +
                       " was made with another global_map configuration; start with the same --config, or use a "
                       "new --state directory");
    }
    fusion_ = std::move(st.fusion);
    taken_high_water_ = std::move(st.taken_high_water);
    applied_lsn_ = rec.snapshot_lsn;
    recovery_.from = rec.snapshot_file;
  } else {
    if (options_.first_robot) fusion_.join_first_robot(*options_.first_robot);
    recovery_.from = rec.fresh ? "new" : "journal";
  }
  recovery_.snapshot_lsn = rec.snapshot_lsn;
  recovery_.problems = rec.problems;
  // The loop side's bookkeeping: every local map in the book was fused or
  // queued (acked), every recorded sighting was received.
  for (const auto& [robot_id, maps] : fusion_.book().shipped()) {
    for (const auto& entry : maps) seqs_[robot_id].applied.insert(entry.first);
  }
  for (const SightingRecord& r : fusion_.records().sightings) {
    sightings_answered_.insert({r.sighting.utime, r.sighting.observer_id, r.sighting.observed_id});
  }
  for (const JournalRecord& r : rec.records) {
    replay(r);
    applied_lsn_ = r.lsn;
  }
  // What was taken before the restart stays refused by the replay windows
  // (auth.hpp): a capture of it cannot be replayed to this server.
  bus_.refuse_through(taken_high_water_);
  store_->start(rec, applied_lsn_, encode_state());
  last_snapshot_ = Clock::now();
  recovery_.lsn = applied_lsn_;
  recovery_.fusions = static_cast<std::int64_t>(fusion_.records().fusions.size());
  recovery_.ms = ms_since(started);

  std::cerr << "lmf-server: state " << options_.state_dir << ": ";
  if (recovery_.from == "new") {
    std::cerr << "new\n";
  } else {
    std::cerr << "recovered from " << (rec.state ? recovery_.from + " (lsn " + std::to_string(rec.snapshot_lsn) + ")"
                                                 : std::string("the journal alone"))
              << " + " << rec.records.size() << " journal records (" << recovery_.replayed_local_maps
              << " local maps, " << recovery_.replayed_sightings << " sightings): lsn " << recovery_.lsn << ", "
              << recovery_.fusions << " fusions, " << fusion_.map().counts().segments << " segments, in " << recovery_.ms
              << " ms\n";
  }
  for (const std::string& p : recovery_.problems) std::cerr << "lmf-server: state: PROBLEM: " << p << '\n';
}

void ServerNode::replay(const JournalRecord& record) {
  const std::string at = "journal record lsn " + std::to_string(record.lsn);
  // An authenticated server journals the trailer too; it was verified on receipt.
  const std::span<const std::uint8_t> received(reinterpret_cast<const std::uint8_t*>(record.data.data()),
                                               record.data.size());
  if (auto signer = runtime::auth::signed_by(received)) runtime::auth::raise(taken_high_water_, *signer);
  const std::size_t size = runtime::auth::unverified_payload_size(received.data(), received.size());
  if (record.channel == channels_.local_map()) {
    auto decoded = runtime::decode<LocalMapSnapshot>(record.data.data(), size, options_.limits);
    if (!decoded) {
      recovery_.problems.push_back(at + ": no longer decodes (" + decoded.rejection().describe() + "): skipped");
      return;
    }
    const int robot_id = decoded.value().robot_id;
    const std::int64_t seq = decoded.value().seq;
    ++recovery_.replayed_local_maps;
    fuse_task(std::move(decoded.value()), Clock::now());
    // Applied now (its outcome, and the FUSED/QUEUED ack, follow on the loop).
    if (fusion_.map().has_fused(robot_id, seq) || fusion_.map().is_queued(robot_id, seq)) {
      seqs_[robot_id].applied.insert(seq);
    }
  } else if (record.channel == channels_.sighting()) {
    auto decoded = runtime::decode<fusion::RobotSighting>(record.data.data(), size, options_.limits);
    if (!decoded) {
      recovery_.problems.push_back(at + ": no longer decodes (" + decoded.rejection().describe() + "): skipped");
      return;
    }
    const fusion::RobotSighting& s = decoded.value();
    sightings_waiting_.insert({s.utime, s.observer_id, s.observed_id});  // its outcome (and ack) follows on the loop
    ++recovery_.replayed_sightings;
    sighting_task(s, Clock::now());
  } else {
    throw StateError(at + " is on channel '" + record.channel + "', not one of this server's (" +
                     channels_.local_map() + ", " + channels_.sighting() + "): another --channel-prefix?");
  }
}

std::string ServerNode::encode_state() const {
  return encode_server_state(fusion_, taken_high_water_);
}

void ServerNode::after_task(std::int64_t lsn, const std::optional<runtime::auth::SignedBy>& signer) {
  if (!store_) return;
  applied_lsn_ = std::max(applied_lsn_, lsn);
  if (signer) runtime::auth::raise(taken_high_water_, *signer);
  state_dirty_ = true;
  if (options_.snapshot_interval.count() == 0 || Clock::now() - last_snapshot_ >= options_.snapshot_interval) {
    snapshot_now();
  }
}

void ServerNode::snapshot_now(bool at_stop) {
  if (!store_ || (!state_dirty_ && !at_stop)) return;
  if (at_stop) {
    store_->wait_idle();
  } else if (store_->writer_busy()) {
    return;  // stays dirty: the next task or the idle timer tries again
  }
  const auto started = Clock::now();
  std::string payload = encode_state();
  const double encode_ms = ms_since(started);
  last_snapshot_ = Clock::now();
  encode_ms_max_ = std::max(encode_ms_max_, encode_ms);
  std::ostringstream note;
  note << "; " << fusion_.records().fusions.size() << " fusions, " << fusion_.map().counts().segments
       << " segments, encoded in " << encode_ms
       << " ms on the fusion worker";
  if (at_stop) {
    if (store_->write_snapshot(applied_lsn_, payload)) {
      state_dirty_ = false;
      std::cerr << "lmf-server: state: final snapshot at lsn " << applied_lsn_ << note.str() << '\n';
    }
  } else if (store_->submit_snapshot(applied_lsn_, std::move(payload), note.str())) {
    state_dirty_ = false;
  }
}

void ServerNode::post_outcome(std::shared_ptr<Outcome> outcome) {
  // The loop may outlive this node (or keep running after shutdown()): the
  // weak token makes a late outcome a no-op instead of a use after free.
  loop_.post([this, alive = std::weak_ptr<bool>(alive_), outcome = std::move(outcome)] {
    if (alive.lock() && !stopped_) on_outcome(*outcome);
  });
}

bool ServerNode::write_outputs(const LoopSnapshot& loop_side) const {
  try {
    json report = fusion_.write_outputs(options_.out_dir, options_.map_svg_graph);
    const ServerStats& s = loop_side.stats;
    report["messages"] = {{"local_maps_received", s.local_maps_received},
                          {"sightings_received", s.sightings_received},
                          {"sightings_applied", s.sightings_applied},
                          {"acks_fused", s.acks_fused},
                          {"acks_duplicate", s.acks_duplicate},
                          {"acks_queued", s.acks_queued},
                          {"acks_received", s.acks_received},
                          {"sighting_acks_applied", s.sighting_acks_applied},
                          {"sighting_acks_duplicate", s.sighting_acks_duplicate},
                          {"sighting_acks_rejected", s.sighting_acks_rejected},
                          {"sighting_acks_received", s.sighting_acks_received},
                          {"resends_while_waiting", s.resends_while_waiting},
                          {"deferred_queue_full", s.deferred_queue_full},
                          {"discarded_at_stop", s.discarded_at_stop}};
    json rejects = json::object();
    for (const auto& [name, count] : loop_side.rejects) rejects[name] = count;
    report["rejects"] = std::move(rejects);
    if (store_) {
      const SnapshotStats st = store_->snapshot_stats();
      report["state"] = {{"dir", options_.state_dir.string()},
                         {"recovered_from", recovery_.from},
                         {"recovered_snapshot_lsn", recovery_.snapshot_lsn},
                         {"replayed_local_maps", recovery_.replayed_local_maps},
                         {"replayed_sightings", recovery_.replayed_sightings},
                         {"recovered_lsn", recovery_.lsn},
                         {"recovery_ms", recovery_.ms},
                         {"problems", recovery_.problems},
                         {"journal_records", store_->journal_records()},
                         {"journal_failures", s.journal_failures},
                         {"snapshots_written", st.written},
                         {"snapshots_failed", st.failed},
                         {"snapshot_last_bytes", st.last_bytes},
                         {"snapshot_last_ms", st.last_ms},
                         {"snapshot_max_ms", st.max_ms},
                         {"snapshot_mean_ms", st.written > 0 ? st.total_ms / static_cast<double>(st.written) : 0.0},
                         {"snapshot_encode_max_ms", encode_ms_max_}};
    }

    const auto file = options_.out_dir / "report.json";
    std::ofstream out(file);
    out << report.dump(2) << '\n';
    if (!out) throw std::runtime_error(file.string() + ": cannot write");
    return true;
  } catch (const std::exception& e) {
    std::cerr << "lmf-server: writing outputs into " << options_.out_dir << " failed: " << e.what() << '\n';
    return false;
  }
}

// ---- loop thread: writing, publishing -------------------------------------------

void ServerNode::request_write() {
  if (stopped_ || write_pending_) return;
  write_pending_ = true;
  const LoopSnapshot loop_side = loop_snapshot();
  worker_->try_push(
      [this, loop_side] {
        write_outputs(loop_side);
        auto outcome = std::make_shared<Outcome>();
        outcome->kind = Outcome::Kind::kWrite;
        outcome->view = fusion_.view();
        post_outcome(std::move(outcome));
      },
      FusionWorker::Bound::kUnbounded);
}

bool ServerNode::shutdown(bool write_outputs_now) {
  if (stopped_) return true;
  stopped_ = true;
  for (int id : timers_) loop_.cancel(id);
  timers_.clear();
  if (map_timer_) loop_.cancel(*map_timer_);
  map_timer_.reset();
  for (int id : subscriptions_) bus_.unsubscribe(id);
  subscriptions_.clear();
  if (worker_) {
    stats_.discarded_at_stop += static_cast<std::int64_t>(worker_->stop());
    stats_.worker_errors = worker_->task_errors();
  }
  // The worker is joined: its state is ours now.
  snapshot_now(/*at_stop=*/true);
  if (!write_outputs_now) return true;
  return write_outputs(loop_snapshot());
}

ServerNode::LoopSnapshot ServerNode::loop_snapshot() const {
  LoopSnapshot s;
  s.stats = stats_;
  if (worker_) s.stats.worker_errors = worker_->task_errors();
  s.rejects = reject_counts();
  return s;
}

runtime::RejectCounts ServerNode::reject_counts() const {
  runtime::RejectCounter all = rejects_;
  all.merge(bus_.rejects());
  return all.nonzero();
}

void ServerNode::publish_ack(int robot_id, std::int64_t seq, runtime::LocalMapAck::Status status) {
  runtime::LocalMapAck ack;
  ack.utime = wall_utime();
  ack.robot_id = robot_id;
  ack.seq = seq;
  ack.status = status;
  switch (status) {
    case runtime::LocalMapAck::Status::kFused: ++stats_.acks_fused; break;
    case runtime::LocalMapAck::Status::kDuplicate: ++stats_.acks_duplicate; break;
    case runtime::LocalMapAck::Status::kQueued: ++stats_.acks_queued; break;
    case runtime::LocalMapAck::Status::kReceived: ++stats_.acks_received; break;
  }
  bus_.publish(channels_.local_map_ack(), runtime::to_message(ack));
}

void ServerNode::publish_sighting_ack(const fusion::RobotSighting& s, runtime::SightingAck::Status status) {
  runtime::SightingAck ack;
  ack.utime = s.utime;
  ack.observer_id = s.observer_id;
  ack.observed_id = s.observed_id;
  ack.status = status;
  switch (status) {
    case runtime::SightingAck::Status::kApplied: ++stats_.sighting_acks_applied; break;
    case runtime::SightingAck::Status::kDuplicate: ++stats_.sighting_acks_duplicate; break;
    case runtime::SightingAck::Status::kRejected: ++stats_.sighting_acks_rejected; break;
    case runtime::SightingAck::Status::kReceived: ++stats_.sighting_acks_received; break;
  }
  bus_.publish(channels_.sighting_ack(), runtime::to_message(ack));
}

void ServerNode::publish_frames() {
  if (stopped_) return;
  auto msg = runtime::to_message(view_.frames);
  if (!msg) {
    std::cerr << "lmf-server: corrected frames not published: " << msg.rejection().describe() << '\n';
    return;
  }
  bus_.publish(channels_.corrected_frames(), msg.value());
}

runtime::GlobalMapSummary ServerNode::make_global_map() const {
  runtime::GlobalMapSummary map;
  map.utime = view_.latest_utime;
  map.fusion_count = view_.fusion_count;
  map.submaps = view_.counts.submaps;
  map.graph_edges = view_.counts.graph_edges;
  map.endpoints.reserve(view_.endpoints.size());
  for (const auto& e : view_.endpoints) map.endpoints.push_back({e[0], e[1], e[2], e[3]});
  return map;
}

void ServerNode::publish_global_map() {
  if (stopped_) return;
  last_map_publish_ = Clock::now();
  auto msg = runtime::to_message(make_global_map());
  if (!msg) {
    std::cerr << "lmf-server: global map not published: " << msg.rejection().describe() << '\n';
    return;
  }
  bus_.publish(channels_.global_map(), msg.value());
}

void ServerNode::publish_global_map_rate_limited() {
  const auto since = Clock::now() - last_map_publish_;
  if (since >= options_.map_min_interval) {
    publish_global_map();
    return;
  }
  if (map_publish_scheduled_) return;
  map_publish_scheduled_ = true;
  const auto delay = std::chrono::duration_cast<std::chrono::milliseconds>(options_.map_min_interval - since) +
                     std::chrono::milliseconds(1);
  map_timer_ = loop_.after(delay, [this] {
    map_publish_scheduled_ = false;
    map_timer_.reset();
    publish_global_map();
  });
}

runtime::ServerStatus ServerNode::make_status() const {
  runtime::ServerStatus s;
  s.utime = wall_utime();
  s.robots_joined = view_.counts.robots_joined;
  s.segments = view_.counts.segments;
  s.submaps = view_.counts.submaps;
  s.graph_edges = view_.counts.graph_edges;
  s.fusions = view_.fusion_count;
  s.last_fusion_ms = view_.last_fusion_ms;
  s.mean_fusion_ms = view_.mean_fusion_ms;
  s.queue_length = static_cast<int>(queue_length());
  s.covariance_ok = view_.covariance_ok;
  // The message carries a finite float: a pivot beyond (a NaN comes with
  // covariance_ok false) reads as the lowest or largest float.
  if (view_.min_pivot) {
    constexpr double kLowest = std::numeric_limits<float>::lowest();
    constexpr double kMax = std::numeric_limits<float>::max();
    s.min_eigenvalue = std::isnan(*view_.min_pivot) ? kLowest : std::clamp(*view_.min_pivot, kLowest, kMax);
  }
  s.rejects = reject_counts();
  return s;
}

void ServerNode::publish_status() {
  if (stopped_) return;
  auto msg = runtime::to_message(make_status());
  if (!msg) {
    std::cerr << "lmf-server: status not published: " << msg.rejection().describe() << '\n';
    return;
  }
  bus_.publish(channels_.server_status(), msg.value());
}

}  // namespace lmf::server
