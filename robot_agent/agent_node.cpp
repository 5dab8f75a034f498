#include "robot_agent/agent_node.hpp"

#include <algorithm>
#include <cmath>
#include <iostream>
#include <stdexcept>
#include <system_error>
#include <utility>

#include "lmf/mission/offline_mission.hpp"
#include "runtime/convert.hpp"

namespace lmf::robot_agent {

namespace rt = lmf::runtime;
using std::to_string;

namespace {

std::int64_t now_utime() {
  // Status and ack messages carry the sender's time; the core never sees it.
  return std::chrono::duration_cast<std::chrono::microseconds>(
             std::chrono::system_clock::now().time_since_epoch())
      .count();
}

}  // namespace

void AgentOptions::validate() const {
  if (robot_id < 0) throw std::invalid_argument("robot id must be >= 0, got " + to_string(robot_id));
  local_map.validate();
  if (resend_interval.count() <= 0) throw std::invalid_argument("resend interval must be > 0 ms");
  if (min_resend_interval.count() <= 0 || min_resend_interval > resend_interval) {
    throw std::invalid_argument("min resend interval must be > 0 ms and at most the resend interval (" +
                                to_string(resend_interval.count()) + " ms), got " +
                                to_string(min_resend_interval.count()) + " ms");
  }
  if (ack_hold.count() <= 0) throw std::invalid_argument("ack hold must be > 0 ms");
  if (status_interval.count() <= 0) throw std::invalid_argument("status interval must be > 0 ms");
  if (max_seq_gap <= 0) throw std::invalid_argument("max_seq_gap must be > 0");
  if (ack_history == 0) throw std::invalid_argument("ack_history must be > 0");
  if (test_stall_after_scan && *test_stall_after_scan < 0) throw std::invalid_argument("stall scan seq must be >= 0");
  if (!(drop_local_maps >= 0.0 && drop_local_maps < 1.0)) {
    throw std::invalid_argument("drop fraction must be in [0, 1), got " + to_string(drop_local_maps));
  }
}

AgentNode::AgentNode(rt::Bus& bus, rt::EventLoop& loop, AgentOptions options)
    : bus_(bus),
      loop_(loop),
      options_((options.validate(), std::move(options))),
      local_map_(options_.local_map, options_.robot_id),
      drop_random_(options_.drop_seed),
      map_resend_(rt::RetransmissionConfig{options_.min_resend_interval, options_.resend_interval}) {
  if (!options_.state_dir.empty()) {
    std::error_code error;
    std::filesystem::create_directories(options_.state_dir, error);
    if (error) {
      throw AgentStateError("cannot create the state folder " + options_.state_dir.string() + ": " + error.message());
    }
    state_file_ = agent_state_file(options_.state_dir, options_.robot_id);
    if (const std::optional<AgentState> state = load_agent_state(state_file_)) restore(*state);
  }
  const rt::Channels& ch = options_.channels;
  subscriptions_.push_back(bus_.subscribe(ch.scan(options_.robot_id), [this](const std::string& c, const void* d,
                                                                             std::size_t n) {
    if (!stalled_) on_scan(c, d, n);
  }));
  subscriptions_.push_back(bus_.subscribe(
      ch.local_map_ack(), [this](const std::string& c, const void* d, std::size_t n) {
        if (!stalled_) on_local_map_ack(c, d, n);
      }));
  subscriptions_.push_back(bus_.subscribe(ch.corrected_frames(), [this](const std::string& c, const void* d,
                                                                        std::size_t n) {
    if (!stalled_) on_corrected_frames(c, d, n);
  }));
  subscriptions_.push_back(bus_.subscribe(
      ch.mission_end(), [this](const std::string& c, const void* d, std::size_t n) {
        if (!stalled_) on_mission_end(c, d, n);
      }));
  timers_.push_back(loop_.every(options_.status_interval, [this] {
    if (!stalled_) publish_status();
  }));
  // Restarted: what the server may never have received goes out at once.
  for (auto& [seq, map] : pending_) {
    ++counters_.map_resends;
    transmit(seq, map);
  }
}

void AgentNode::restore(const AgentState& state) {
  if (state.robot_id != options_.robot_id) {
    throw AgentStateError(state_file_.string() + " holds the state of robot " + to_string(state.robot_id) +
                          ", not " + to_string(options_.robot_id));
  }
  if (state.origin) {
    const AgentState::Origin& o = *state.origin;
    local_map_.resume(state.local_map_seq, o.utime, o.odometry);
    origin_ = o;
    last_processed_ = ProcessedScan{o.scan_seq, o.utime, o.odometry};
    next_scan_seq_ = o.scan_seq + 1;
    last_scan_utime_ = o.utime;
    acks_.push_back(o.ack);
    any_gap_once_ = true;
  }
  for (const auto& [seq, bytes] : state.unacknowledged) pending_[seq].bytes = bytes;
  shipped_final_x_LR_ = state.shipped_final_x_LR;
  frame_ = state.frame;
  mission_ended_ = state.mission_ended;
  counters_.maps_shipped = state.maps_shipped;
  counters_.maps_acknowledged = state.maps_acknowledged;
  counters_.resumed = true;
  std::cerr << "lmf-agent " << options_.robot_id << ": resumed from " << state_file_.string() << ": local map "
            << local_map_.seq()
            << (origin_ ? " from its origin at scan " + to_string(origin_->scan_seq) : std::string(" (no scan yet)"))
            << ", " << counters_.maps_shipped << " local map(s) shipped, " << counters_.maps_acknowledged
            << " acknowledged, " << pending_.size() << " unacknowledged to resend"
            << (mission_ended_ ? ", mission ended" : "") << "\n";
}

void AgentNode::persist() {
  if (state_file_.empty()) return;
  AgentState state;
  state.robot_id = options_.robot_id;
  state.local_map_seq = local_map_.seq();
  state.origin = origin_;
  for (const auto& [seq, map] : pending_) state.unacknowledged[seq] = map.bytes;
  state.shipped_final_x_LR = shipped_final_x_LR_;
  state.frame = frame_;
  state.mission_ended = mission_ended_;
  state.maps_shipped = counters_.maps_shipped;
  state.maps_acknowledged = counters_.maps_acknowledged;
  try {
    save_agent_state(state_file_, state);
    ++counters_.state_writes;
  } catch (const AgentStateError& e) {
    // A full or failing disk must not stop the robot: it runs on, without the
    // guarantee of a restart, and says so.
    if (counters_.state_write_failures++ == 0 || counters_.state_write_failures % 100 == 0) {
      std::cerr << "lmf-agent " << options_.robot_id << ": state not saved (" << counters_.state_write_failures
                << " failure(s)): " << e.what() << "\n";
    }
  }
}

AgentNode::~AgentNode() {
  if (resend_timer_) loop_.cancel(*resend_timer_);
  if (hold_timer_) loop_.cancel(*hold_timer_);
  for (const int id : timers_) loop_.cancel(id);
  for (const int id : subscriptions_) bus_.unsubscribe(id);
}

void AgentNode::reject(rt::RejectReason reason, std::string detail, std::string_view source) {
  rejects_.record(rt::Rejection{reason, std::move(detail)}, source);
}

// ---- scans ----------------------------------------------------------------------------

void AgentNode::on_scan(const std::string& channel, const void* data, std::size_t size) {
  auto scan = rt::decode<rt::RobotScan>(data, size);
  if (!scan) {
    rejects_.record(scan.rejection(), channel);
    return;
  }
  const rt::RobotScan& s = scan.value();
  if (s.robot_id != options_.robot_id) {
    reject(rt::RejectReason::kUnknownRobot, "scan of robot " + to_string(s.robot_id) + " on my channel", channel);
    return;
  }
  if (s.seq < next_scan_seq_) {
    const auto earlier = std::lower_bound(acks_.begin(), acks_.end(), s.seq,
                                          [](const rt::ScanAck& a, std::int64_t seq) { return a.seq < seq; });
    if (earlier != acks_.end() && earlier->seq == s.seq) {
      if (earlier->utime == s.scan.utime) {
        // A lockstep resend (our ack was lost or late), or a player restarted on this log.
        ++counters_.scans_duplicate;
        if (held_ack_ && held_ack_->ack.seq == s.seq) return;  // its ack follows the map's answer
        send_ack(*earlier);
        return;
      }
      reject(rt::RejectReason::kStaleSequence,
             "scan seq " + to_string(s.seq) + " at " + to_string(s.scan.utime) + " us: seq " + to_string(s.seq) +
                 " was processed as the scan at " + to_string(earlier->utime) + " us (a player on another log?)",
             channel);
      return;
    }
    reject(rt::RejectReason::kStaleSequence,
           "scan seq " + to_string(s.seq) + " after " + to_string(next_scan_seq_ - 1) +
               " was processed (not among the acks kept)",
           channel);
    return;
  }
  if (!any_gap_once_ && s.seq - next_scan_seq_ > options_.max_seq_gap) {
    reject(rt::RejectReason::kOutOfRange,
           "scan seq " + to_string(s.seq) + " is more than " + to_string(options_.max_seq_gap) + " ahead of " +
               to_string(next_scan_seq_),
           channel);
    return;
  }
  if (last_scan_utime_ && s.scan.utime < *last_scan_utime_) {
    reject(rt::RejectReason::kOutOfRange,
           "scan seq " + to_string(s.seq) + " at " + to_string(s.scan.utime) + " us is older than the last one (" +
               to_string(*last_scan_utime_) + " us)",
           channel);
    return;
  }
  if (held_ack_) release_held_ack(held_ack_->map_seq);  // the player went on without it (--rate)
  process(s);
}

void AgentNode::process(const rt::RobotScan& scan) {
  ScanReport report;
  const auto start = std::chrono::steady_clock::now();
  try {
    report = local_map_.process_scan(scan.scan);
  } catch (const std::invalid_argument& e) {
    // LocalMap leaves its state unchanged; the converter already refused what
    // it knows, so this is a scan the core found unusable.
    ++counters_.scan_errors;
    reject(rt::RejectReason::kOutOfRange, std::string("local map refused the scan: ") + e.what(),
           options_.channels.scan(options_.robot_id));
    return;
  }
  const double elapsed_ms =
      std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - start).count();
  if (any_gap_once_) {
    any_gap_once_ = false;
    std::cerr << "lmf-agent " << options_.robot_id << ": first scan after the restart: " << scan.seq << ", "
              << scan.seq - next_scan_seq_ << " scan(s) since the persisted origin bridged by odometry\n";
  }
  window_scan_times_ms_.push_back(elapsed_ms);
  all_scan_times_ms_.push_back(elapsed_ms);
  counters_.scans_missed += scan.seq - next_scan_seq_;
  next_scan_seq_ = scan.seq + 1;
  last_scan_utime_ = scan.scan.utime;
  map_has_scans_ = true;
  ++counters_.scans_processed;
  if (report.scan_skipped) ++counters_.scans_skipped;
  if (report.scan_match_tried) ++counters_.scans_match_tried;
  if (report.scan_matched) ++counters_.scans_matched;
  if (report.scan_match_escalated) ++counters_.scans_match_escalated;
  if (report.scan_match_from_escalation) ++counters_.scans_matched_from_escalation;
  counters_.segments_seen_through += report.segments_seen_through;
  if (!report.covariance_health.ok()) {
    window_covariance_ok_ = false;
    if (counters_.covariance_always_ok) {
      std::cerr << "lmf-agent " << options_.robot_id << ": local map covariance check failed at scan " << scan.seq
                << ": " << report.covariance_health.describe() << "\n";
    }
    counters_.covariance_always_ok = false;
  }

  // The protocol: the map a scan made ship goes out before that scan's ack;
  // and it is on disk before it goes out (nothing shipped is lost by a crash).
  std::optional<std::int64_t> shipped;
  const bool new_origin = report.should_ship || !origin_;
  if (report.should_ship) shipped = ship();
  last_processed_ = ProcessedScan{scan.seq, scan.scan.utime, scan.scan.odometry};

  rt::ScanAck ack;
  ack.utime = scan.scan.utime;
  ack.robot_id = options_.robot_id;
  ack.seq = scan.seq;
  ack.local_map_seq = local_map_.seq();
  ack.x_LR = local_map_.x_LR();  // at the last scan taken (the motion filter)
  ack.covariance = local_map_.robot_covariance();
  acks_.push_back(ack);
  if (acks_.size() > options_.ack_history) acks_.pop_front();
  if (new_origin) {
    origin_ = AgentState::Origin{scan.seq, scan.scan.utime, scan.scan.odometry, ack};
    persist();
  }
  if (shipped) {
    hold_ack(*shipped, ack);
    transmit(*shipped, pending_.at(*shipped));
    return;
  }
  if (shipped) transmit(*shipped, pending_.at(*shipped));
  send_ack(ack);
  acknowledged(scan.seq);
}

void AgentNode::acknowledged(std::int64_t scan_seq) {
  if (options_.test_stall_after_scan && scan_seq >= *options_.test_stall_after_scan) {
    stalled_ = true;
    std::cerr << "lmf-agent " << options_.robot_id << ": stalled after scan " << scan_seq
              << " (--test-stall-after-scan): waiting to be killed\n";
  }
}

void AgentNode::hold_ack(std::int64_t map_seq, const rt::ScanAck& ack) {
  ++counters_.scan_acks_held;
  held_ack_ = HeldAck{map_seq, ack};
  hold_timer_ = loop_.after(options_.ack_hold, [this] {
    hold_timer_.reset();
    if (stalled_ || !held_ack_) return;
    ++counters_.scan_ack_holds_expired;
    release_held_ack(held_ack_->map_seq);
  });
}

void AgentNode::release_held_ack(std::int64_t map_seq) {
  if (!held_ack_ || held_ack_->map_seq != map_seq) return;
  if (hold_timer_) loop_.cancel(*hold_timer_);
  hold_timer_.reset();
  const rt::ScanAck ack = held_ack_->ack;
  held_ack_.reset();
  send_ack(ack);
  acknowledged(ack.seq);
}

void AgentNode::send_ack(const rt::ScanAck& ack) {
  auto msg = rt::to_message(ack);
  if (!msg) {
    ++counters_.ack_failures;
    std::cerr << "lmf-agent " << options_.robot_id << ": cannot acknowledge scan " << ack.seq << ": "
              << msg.rejection().describe() << "\n";
    return;
  }
  bus_.publish(options_.channels.scan_ack(), msg.value());
}

// ---- local maps -------------------------------------------------------------------------

std::optional<std::int64_t> AgentNode::ship() {
  LocalMapSnapshot snapshot = local_map_.snapshot();
  local_map_.reset();
  map_has_scans_ = false;
  ++counters_.maps_shipped;
  shipped_final_x_LR_[snapshot.seq] = snapshot.x_LR;
  auto msg = rt::to_message(snapshot);
  if (!msg) {
    // An indefinite covariance must not leave (docs/design.md §8); the map is lost
    // and the server will see a gap in this robot's seq numbers.
    ++counters_.ship_failures;
    std::cerr << "lmf-agent " << options_.robot_id << ": local map " << snapshot.seq
              << " not shipped: " << msg.rejection().describe() << "\n";
    return std::nullopt;
  }
  pending_[snapshot.seq].bytes = rt::encode_message(msg.value());
  return snapshot.seq;
}

void AgentNode::transmit(std::int64_t seq, PendingMap& map) {
  (void)seq;
  map.last_sent = std::chrono::steady_clock::now();
  ++map.sends;
  ++counters_.map_transmissions;
  if (options_.drop_local_maps > 0.0 &&
      std::uniform_real_distribution<double>(0.0, 1.0)(drop_random_) < options_.drop_local_maps) {
    ++counters_.map_transmissions_dropped;
  } else {
    bus_.publish_raw(options_.channels.local_map(), map.bytes);
  }
  schedule_resend();
}

std::chrono::steady_clock::duration AgentNode::resend_wait(const PendingMap& map) const {
  if (map.received) return options_.resend_interval;
  return map_resend_.timeout(std::max(1, map.sends));
}

void AgentNode::schedule_resend() {
  if (resend_timer_) loop_.cancel(*resend_timer_);
  resend_timer_.reset();
  if (pending_.empty()) return;
  auto due = std::chrono::steady_clock::time_point::max();
  for (const auto& entry : pending_) due = std::min(due, entry.second.last_sent + resend_wait(entry.second));
  const auto delay = std::max(due - std::chrono::steady_clock::now(), std::chrono::steady_clock::duration::zero());
  resend_timer_ = loop_.after(std::chrono::ceil<std::chrono::milliseconds>(delay), [this] {
    resend_timer_.reset();
    if (!stalled_) resend_due();
  });
}

void AgentNode::resend_due() {
  const auto now = std::chrono::steady_clock::now();
  for (auto& [seq, map] : pending_) {
    if (now - map.last_sent >= resend_wait(map)) {
      ++counters_.map_resends;
      transmit(seq, map);
    }
  }
  schedule_resend();
}

std::vector<std::int64_t> AgentNode::unacknowledged_maps() const {
  std::vector<std::int64_t> out;
  for (const auto& entry : pending_) out.push_back(entry.first);
  return out;
}

void AgentNode::on_local_map_ack(const std::string& channel, const void* data, std::size_t size) {
  auto ack = rt::decode<rt::LocalMapAck>(data, size);
  if (!ack) {
    rejects_.record(ack.rejection(), channel);
    return;
  }
  const rt::LocalMapAck& a = ack.value();
  if (a.robot_id != options_.robot_id) return;  // another agent's
  const auto it = pending_.find(a.seq);
  if (it == pending_.end()) {
    if (a.seq >= local_map_.seq()) {
      reject(rt::RejectReason::kOutOfRange, "ack of local map " + to_string(a.seq) + " never shipped", channel);
    }
    return;  // an ack of a map acked before (a resend crossed the first ack): nothing to do
  }
  PendingMap& map = it->second;
  // Karn's rule: only the first answer to a map sent once times the round trip.
  if (map.sends == 1 && !map.received) map_resend_.on_round_trip(std::chrono::steady_clock::now() - map.last_sent);
  release_held_ack(a.seq);
  if (a.status == rt::LocalMapAck::Status::kReceived) {
    map.received = true;
    schedule_resend();
    return;
  }
  pending_.erase(it);
  ++counters_.maps_acknowledged;
  if (a.status == rt::LocalMapAck::Status::kQueued) ++counters_.maps_queued;
  persist();  // a restart will not resend it
  schedule_resend();
  if (mission_done()) publish_status();  // a lockstep player waits for it to end the next robot
}

// ---- corrected frames ----------------------------------------------------------------------

void AgentNode::on_corrected_frames(const std::string& channel, const void* data, std::size_t size) {
  auto frames = rt::decode<rt::CorrectedFrames>(data, size);
  if (!frames) {
    rejects_.record(frames.rejection(), channel);
    return;
  }
  for (const lmf::fusion::CorrectedFrame& f : frames.value().frames) {
    if (f.robot_id != options_.robot_id) continue;
    const std::int64_t map_seq = f.map_seq;  // x_WL is the origin of this map
    if (map_seq > local_map_.seq()) {
      reject(rt::RejectReason::kOutOfRange,
             "corrected frame for local map " + to_string(map_seq) + " but map " + to_string(local_map_.seq()) +
                 " is in progress",
             channel);
      return;
    }
    // Frames only move forward: an older fusion's message (reordered or late) is ignored.
    if (frame_ && (map_seq < frame_->map_seq ||
                   (map_seq == frame_->map_seq && frames.value().fusion_count < frame_->fusion_count))) {
      return;
    }
    frame_ = Frame{map_seq, frames.value().fusion_count, f.x_WL};
    ++counters_.corrected_frames;
    // Final poses of maps the server has fused are no longer needed for chaining.
    shipped_final_x_LR_.erase(shipped_final_x_LR_.begin(), shipped_final_x_LR_.lower_bound(map_seq));
    return;
  }
}

std::optional<Pose2> AgentNode::global_pose() const {
  if (!frame_) return std::nullopt;
  Pose2 x_WL = frame_->x_WL;
  // The server may be behind: L(k+1) = L(k) ⊕ x_LR(k) for the maps shipped since.
  for (std::int64_t k = frame_->map_seq; k < local_map_.seq(); ++k) {
    const auto it = shipped_final_x_LR_.find(k);
    if (it == shipped_final_x_LR_.end()) return std::nullopt;
    x_WL = compose(x_WL, it->second);
  }
  return compose(x_WL, local_map_.x_LR_at_last_scan());
}

// ---- mission end ----------------------------------------------------------------------------

void AgentNode::on_mission_end(const std::string& channel, const void* data, std::size_t size) {
  auto end = rt::decode<rt::MissionEnd>(data, size);
  if (!end) {
    rejects_.record(end.rejection(), channel);
    return;
  }
  const auto& ids = end.value().robot_ids;
  if (mission_ended_ || std::find(ids.begin(), ids.end(), options_.robot_id) == ids.end()) return;
  mission_ended_ = true;
  if (!map_has_scans_) {
    persist();
    if (mission_done()) publish_status();
    return;
  }
  // Ship the unfinished map so every scan belongs to a fused local map; the
  // next (empty) map begins at the last scan processed.
  if (local_map_.take_skipped_scan()) --counters_.scans_skipped;  // the map ends at the last scan
  const std::optional<std::int64_t> shipped = ship();
  if (last_processed_ && !acks_.empty()) {
    origin_ = AgentState::Origin{last_processed_->seq, last_processed_->utime, last_processed_->odometry, acks_.back()};
  }
  persist();
  if (shipped) transmit(*shipped, pending_.at(*shipped));
  if (mission_done()) publish_status();
}

// ---- status -----------------------------------------------------------------------------------

runtime::RejectCounter AgentNode::all_rejects() const {
  runtime::RejectCounter all = rejects_;
  all.merge(bus_.rejects());
  return all;
}

void AgentNode::publish_status() {
  const mission::TimingStats timing = mission::timing_stats(window_scan_times_ms_);
  rt::AgentStatus status;
  status.utime = now_utime();
  status.robot_id = options_.robot_id;
  status.joined = frame_.has_value();
  status.scans = counters_.scans_processed;
  status.local_map_segments = static_cast<int>(local_map_.num_segments());
  status.maps_shipped = counters_.maps_shipped;
  status.maps_acknowledged = counters_.maps_acknowledged;
  status.scan_time_p50_ms = timing.p50_ms;
  status.scan_time_p99_ms = timing.p99_ms;
  status.scan_time_max_ms = timing.max_ms;
  status.window_scans = static_cast<int>(timing.count);
  status.covariance_ok = window_covariance_ok_;
  status.x_WR = global_pose().value_or(Pose2());
  status.odometry = rt::odometry_model_report(local_map_.odometry_model(), local_map_.odometry_learning_stats());
  status.mission_done = mission_done();
  status.rejects = all_rejects().nonzero();
  if (auto msg = rt::to_message(status)) {
    bus_.publish(options_.channels.agent_status(), msg.value());
  } else {
    std::cerr << "lmf-agent " << options_.robot_id << ": status not published: " << msg.rejection().describe() << '\n';
  }
  window_scan_times_ms_.clear();
  window_covariance_ok_ = true;
}

}  // namespace lmf::robot_agent
