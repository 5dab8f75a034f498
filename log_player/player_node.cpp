#include "log_player/player_node.hpp"

#include <algorithm>
#include <cmath>
#include <iomanip>
#include <iostream>
#include <limits>
#include <sstream>
#include <stdexcept>
#include <utility>

#include "runtime/convert.hpp"

namespace lmf::log_player {

namespace rt = lmf::runtime;
using std::to_string;
using namespace std::chrono_literals;

void PlayerOptions::validate() const {
  if (!lockstep && !(rate > 0.0 && std::isfinite(rate))) {
    throw std::invalid_argument("rate must be > 0, got " + to_string(rate));
  }
  if (ack_timeout.count() <= 0) throw std::invalid_argument("ack timeout must be > 0 ms");
  if (min_ack_timeout.count() <= 0) throw std::invalid_argument("min ack timeout must be > 0 ms");
  if (!(drop_scans >= 0.0 && drop_scans < 1.0)) throw std::invalid_argument("drop_scans must be in [0, 1)");
  if (max_attempts < 0) throw std::invalid_argument("max attempts must be >= 0 (0: no limit)");
  if (max_pending_sightings == 0) throw std::invalid_argument("max pending sightings must be > 0");
  if (end_wait.count() < 0) throw std::invalid_argument("end wait must be >= 0 ms (0: until answered)");
  if (start_delay.count() < 0) throw std::invalid_argument("start delay must be >= 0 ms");
  if (mission_end_interval.count() <= 0) throw std::invalid_argument("mission end interval must be > 0 ms");
  if (mission_end_repeats < 1) throw std::invalid_argument("mission end repeats must be >= 1");
  if (progress != Progress::kNone && progress_stream == nullptr) {
    throw std::invalid_argument("progress output needs a stream");
  }
}

PlayerNode::PlayerNode(rt::Bus& bus, rt::EventLoop& loop, mission::MissionInputs inputs, PlayerOptions options)
    : bus_(bus),
      loop_(loop),
      inputs_(std::move(inputs)),
      options_((options.validate(), std::move(options))),
      scan_resend_(rt::RetransmissionConfig{std::min(options_.min_ack_timeout, options_.ack_timeout),
                                            options_.ack_timeout}),
      drop_random_(options_.drop_seed),
      sighting_resend_(rt::RetransmissionConfig{std::min(options_.min_ack_timeout, options_.ack_timeout),
                                                options_.ack_timeout}) {
  if (inputs_.robots.empty()) throw std::invalid_argument("PlayerNode: no robots to replay");
  for (std::size_t i = 0; i < inputs_.robots.size(); ++i) {
    const mission::RobotLog& log = inputs_.robots[i];
    if (log.robot_id < 0) throw std::invalid_argument("PlayerNode: negative robot id " + to_string(log.robot_id));
    if (!robot_index_.emplace(log.robot_id, i).second) {
      throw std::invalid_argument("PlayerNode: robot id " + to_string(log.robot_id) + " given twice");
    }
    for (std::size_t k = 0; k < log.scans.size(); ++k) {
      if (k > 0 && log.scans[k].utime < log.scans[k - 1].utime) {
        throw std::invalid_argument("PlayerNode: robot " + to_string(log.robot_id) + " scan " + to_string(k) +
                                    " is older than the one before");
      }
      events_.push_back({log.scans[k].utime, i, k});
    }
    acks_.emplace_back(log.scans.size());
  }
  // Global time order; ties: lower robot id, then scan order.
  std::stable_sort(events_.begin(), events_.end(), [this](const ScanEvent& a, const ScanEvent& b) {
    if (a.utime != b.utime) return a.utime < b.utime;
    return inputs_.robots[a.robot].robot_id < inputs_.robots[b.robot].robot_id;
  });
  std::stable_sort(inputs_.sightings.begin(), inputs_.sightings.end(),
                   [](const mission::SightingInput& a, const mission::SightingInput& b) { return a.utime < b.utime; });
  counters_.scans_total = static_cast<std::int64_t>(events_.size());
  counters_.sightings_total = static_cast<std::int64_t>(inputs_.sightings.size());
  subscriptions_.push_back(bus_.subscribe(
      options_.channels.scan_ack(), [this](const std::string& c, const void* d, std::size_t n) { on_ack(c, d, n); }));
  robot_done_.assign(inputs_.robots.size(), false);
  if (options_.lockstep) {
    subscriptions_.push_back(bus_.subscribe(options_.channels.agent_status(),
                                            [this](const std::string& c, const void* d, std::size_t n) {
                                              on_agent_status(c, d, n);
                                            }));
  }
  subscriptions_.push_back(bus_.subscribe(options_.channels.sighting_ack(),
                                          [this](const std::string& c, const void* d, std::size_t n) {
                                            on_sighting_ack(c, d, n);
                                          }));
}

PlayerNode::~PlayerNode() {
  if (ack_timer_) loop_.cancel(*ack_timer_);
  if (step_timer_) loop_.cancel(*step_timer_);
  if (sighting_timer_) loop_.cancel(*sighting_timer_);
  if (receipt_timer_) loop_.cancel(*receipt_timer_);
  if (end_wait_timer_) loop_.cancel(*end_wait_timer_);
  for (const int id : timers_) loop_.cancel(id);
  for (const int id : subscriptions_) bus_.unsubscribe(id);
}

void PlayerNode::start() {
  if (started_) throw std::logic_error("PlayerNode::start called twice");
  started_ = true;
  timers_.push_back(loop_.after(options_.start_delay, [this] { begin(); }));
}

void PlayerNode::begin() {
  start_time_ = std::chrono::steady_clock::now();
  last_send_time_ = start_time_;
  last_progress_time_ = start_time_;
  if (options_.lockstep) {
    lockstep_step();
  } else {
    rate_pump();
    timers_.push_back(loop_.every(5ms, [this] { rate_pump(); }));
  }
}

std::optional<rt::ScanAck> PlayerNode::ack(int robot_id, std::int64_t seq) const {
  const auto it = robot_index_.find(robot_id);
  if (it == robot_index_.end() || seq < 0 || static_cast<std::size_t>(seq) >= acks_[it->second].size()) {
    return std::nullopt;
  }
  return acks_[it->second][static_cast<std::size_t>(seq)];
}

std::chrono::milliseconds PlayerNode::wait_for(const rt::RetransmissionTimeout& resend, int sends) {
  return std::chrono::ceil<std::chrono::milliseconds>(resend.timeout(sends));
}

void PlayerNode::send_scan(const ScanEvent& event) {
  const mission::RobotLog& log = inputs_.robots[event.robot];
  rt::RobotScan scan;
  scan.robot_id = log.robot_id;
  scan.seq = static_cast<std::int64_t>(event.scan);
  scan.scan = log.scans[event.scan];
  last_send_time_ = std::chrono::steady_clock::now();
  if (options_.drop_scans > 0.0 && std::uniform_real_distribution<double>(0.0, 1.0)(drop_random_) < options_.drop_scans) {
    ++counters_.scan_transmissions_dropped;
    return;
  }
  bus_.publish(options_.channels.scan(log.robot_id), rt::to_message(scan));
}

void PlayerNode::on_ack(const std::string& channel, const void* data, std::size_t size) {
  auto decoded = rt::decode<rt::ScanAck>(data, size);
  if (!decoded) {
    rejects_.record(decoded.rejection(), channel);
    return;
  }
  const rt::ScanAck& a = decoded.value();
  const auto it = robot_index_.find(a.robot_id);
  if (it == robot_index_.end()) {
    rejects_.record({rt::RejectReason::kUnknownRobot, "ack from robot " + to_string(a.robot_id)}, channel);
    return;
  }
  auto& acks = acks_[it->second];
  if (a.seq >= static_cast<std::int64_t>(acks.size())) {
    rejects_.record({rt::RejectReason::kOutOfRange, "ack of robot " + to_string(a.robot_id) + " scan " +
                                                        to_string(a.seq) + " never sent"},
                    channel);
    return;
  }
  auto& slot = acks[static_cast<std::size_t>(a.seq)];
  if (slot) {
    ++counters_.acks_duplicate;
  } else {
    ++counters_.scans_acked;
  }
  slot = a;
  if (options_.lockstep && !replay_done_ && next_event_ < events_.size()) {
    const ScanEvent& waiting = events_[next_event_];
    if (waiting.robot == it->second && static_cast<std::int64_t>(waiting.scan) == a.seq && attempts_ > 0) {
      if (attempts_ == 1) scan_resend_.on_round_trip(std::chrono::steady_clock::now() - first_sent_);
      if (ack_timer_) loop_.cancel(*ack_timer_);
      ack_timer_.reset();
      attempts_ = 0;
      ++next_event_;
      report_progress(false);
      // Not from inside the bus handler: the next scan goes out from a fresh loop turn.
      step_timer_ = loop_.after(0ms, [this] {
        step_timer_.reset();
        lockstep_step();
      });
    }
  }
}

// ---- lockstep ---------------------------------------------------------------------------------

void PlayerNode::lockstep_step() {
  if (replay_done_) return;
  if (next_event_ >= events_.size()) {
    replay_done_ = true;
    publish_sightings(std::numeric_limits<std::int64_t>::max(), true);
    finish();
    return;
  }
  const ScanEvent& event = events_[next_event_];
  if (receipt_timer_) return;  // waiting for the server's answer to the sightings before it
  // Sightings strictly before the next scan (scans first at equal times): every
  // scan at or before them has been acked (or given up). The scan waits for the
  // server's first answer to them, so nothing overtakes them.
  publish_sightings(event.utime, true);
  if (!awaiting_receipt_.empty()) {
    receipt_timer_ = loop_.after(options_.ack_timeout, [this] {
      receipt_timer_.reset();
      ++counters_.sighting_receipt_waits_expired;
      awaiting_receipt_.clear();
      lockstep_step();
    });
    return;
  }
  attempts_ = 1;
  ++counters_.scans_sent;
  send_scan(event);
  first_sent_ = last_send_time_;
  const std::size_t index = next_event_;
  ack_timer_ = loop_.after(wait_for(scan_resend_, 1), [this, index] { lockstep_timeout(index); });
}

void PlayerNode::lockstep_timeout(std::size_t event_index) {
  ack_timer_.reset();
  if (event_index != next_event_ || replay_done_) return;
  const ScanEvent& event = events_[event_index];
  if (options_.may_send_again(attempts_)) {
    if (options_.max_attempts == 0 && attempts_ % 10 == 0) {
      std::cerr << "lmf-player: no ack for robot " << inputs_.robots[event.robot].robot_id << " scan " << event.scan
                << " after " << attempts_ << " sends; resending every " << options_.ack_timeout.count()
                << " ms (is its lmf-agent running?)\n";
    }
    ++attempts_;
    ++counters_.scan_resends;
    send_scan(event);  // same seq: the agent re-acks it if it already processed it
    ack_timer_ = loop_.after(wait_for(scan_resend_, attempts_), [this, event_index] { lockstep_timeout(event_index); });
    return;
  }
  ++counters_.scans_given_up;
  if (counters_.scans_given_up <= 10 || counters_.scans_given_up % 100 == 0) {
    std::cerr << "lmf-player: no ack for robot " << inputs_.robots[event.robot].robot_id << " scan " << event.scan
              << " after " << attempts_ << " sends; going on (" << counters_.scans_given_up << " given up)\n";
  }
  attempts_ = 0;
  ++next_event_;
  lockstep_step();
}

// ---- rate ---------------------------------------------------------------------------------------

std::chrono::steady_clock::time_point PlayerNode::due_time(std::int64_t utime) const {
  const double offset_us = static_cast<double>(utime - events_.front().utime) / options_.rate;
  return start_time_ + std::chrono::microseconds(static_cast<std::int64_t>(offset_us));
}

void PlayerNode::rate_pump() {
  if (finished_ || replay_done_) return;
  const auto now = std::chrono::steady_clock::now();
  while (next_event_ < events_.size() && due_time(events_[next_event_].utime) <= now) {
    ++counters_.scans_sent;
    send_scan(events_[next_event_++]);
    report_progress(false);  // per scan: a late loop's burst still gives every 10 % its line
  }
  // Sightings whose time has come; after ack_timeout more, an earlier ack may stand in.
  while (next_sighting_ < inputs_.sightings.size()) {
    const mission::SightingInput& s = inputs_.sightings[next_sighting_];
    const auto due = events_.empty() ? now : due_time(s.utime);
    if (due > now) break;
    const SightingOutcome outcome = try_sighting(s, now >= due + options_.ack_timeout);
    if (outcome == SightingOutcome::kWait) break;
    ++next_sighting_;
  }
  if (next_event_ < events_.size()) return;
  // Every scan is out: wait for the last acks (or ack_timeout), then the rest of the sightings.
  const bool all_acked = counters_.scans_acked == counters_.scans_total;
  if (!all_acked && now < last_send_time_ + options_.ack_timeout) return;
  replay_done_ = true;
  publish_sightings(std::numeric_limits<std::int64_t>::max(), true);
  finish();
}

// ---- sightings ------------------------------------------------------------------------------------

void PlayerNode::publish_sightings(std::int64_t before_utime, bool allow_fallback) {
  while (next_sighting_ < inputs_.sightings.size() && inputs_.sightings[next_sighting_].utime < before_utime) {
    if (try_sighting(inputs_.sightings[next_sighting_], allow_fallback) == SightingOutcome::kWait) return;
    ++next_sighting_;
  }
}

std::optional<rt::ScanAck> PlayerNode::ack_at_or_before(std::size_t robot, std::int64_t utime, bool allow_fallback,
                                                        bool* approximate) const {
  const std::vector<LaserScan>& scans = inputs_.robots[robot].scans;
  const auto after = std::upper_bound(scans.begin(), scans.end(), utime,
                                      [](std::int64_t t, const LaserScan& s) { return t < s.utime; });
  if (after == scans.begin()) return std::nullopt;  // not started: no local frame yet
  auto k = static_cast<std::size_t>(after - scans.begin()) - 1;
  if (acks_[robot][k]) return acks_[robot][k];
  if (!allow_fallback) return std::nullopt;
  while (k > 0) {
    --k;
    if (acks_[robot][k]) {
      *approximate = true;
      return acks_[robot][k];
    }
  }
  return std::nullopt;
}

PlayerNode::SightingOutcome PlayerNode::try_sighting(const mission::SightingInput& input, bool allow_fallback) {
  const auto skip = [this](const std::string& why) {
    ++counters_.sightings_skipped;
    if (counters_.sightings_skipped <= 10) std::cerr << "lmf-player: sighting skipped: " << why << "\n";
    return SightingOutcome::kSkipped;
  };
  const auto a = robot_index_.find(input.observer);
  const auto b = robot_index_.find(input.observed);
  if (a == robot_index_.end() || b == robot_index_.end()) {
    return skip("robot " + to_string(input.observer) + " or " + to_string(input.observed) + " is not replayed");
  }
  const std::vector<LaserScan>& scans_a = inputs_.robots[a->second].scans;
  const std::vector<LaserScan>& scans_b = inputs_.robots[b->second].scans;
  const bool a_started = !scans_a.empty() && scans_a.front().utime <= input.utime;
  const bool b_started = !scans_b.empty() && scans_b.front().utime <= input.utime;
  if (!a_started || !b_started) {
    return skip("at " + to_string(input.utime) + " us robot " +
                to_string(a_started ? input.observed : input.observer) + " has not scanned yet");
  }
  bool approximate = false;
  const auto ack_a = ack_at_or_before(a->second, input.utime, allow_fallback, &approximate);
  const auto ack_b = ack_at_or_before(b->second, input.utime, allow_fallback, &approximate);
  if (!ack_a || !ack_b) {
    if (!allow_fallback) return SightingOutcome::kWait;
    return skip("no scan ack of robot " + to_string(ack_a ? input.observed : input.observer) + " by " +
                to_string(input.utime) + " us");
  }
  lmf::fusion::RobotSighting s;
  s.utime = input.utime;
  s.observer_id = input.observer;
  s.observed_id = input.observed;
  s.x_AB = input.x_AB;
  s.cov_AB = input.covariance;
  s.observer_seq = ack_a->local_map_seq;
  s.x_LA = ack_a->x_LR;
  s.cov_LA = ack_a->covariance;
  s.observed_seq = ack_b->local_map_seq;
  s.x_LB = ack_b->x_LR;
  s.cov_LB = ack_b->covariance;
  auto msg = rt::to_message(s);
  if (!msg) return skip(msg.rejection().describe());
  const SightingKey key{s.utime, s.observer_id, s.observed_id};
  if (!published_sightings_.insert(key).second) {
    return skip("robot " + to_string(s.observer_id) + " sighted robot " + to_string(s.observed_id) + " twice at " +
                to_string(s.utime) + " us");
  }
  if (pending_sightings_.size() >= options_.max_pending_sightings) give_up_oldest_sighting();
  PendingSighting& pending = pending_sightings_[key];
  pending.message = std::move(msg.value());
  send_sighting(pending);
  schedule_sighting_resend();
  if (options_.lockstep && !replay_done_) awaiting_receipt_.insert(key);
  ++counters_.sightings_published;
  if (approximate) ++counters_.sightings_approximate;
  return SightingOutcome::kPublished;
}

void PlayerNode::give_up_oldest_sighting() {
  const auto oldest = pending_sightings_.begin();
  ++counters_.sightings_unanswered;
  if (counters_.sightings_unanswered <= 10 || counters_.sightings_unanswered % 100 == 0) {
    const auto& [utime, observer, observed] = oldest->first;
    std::cerr << "lmf-player: " << options_.max_pending_sightings << " sightings unanswered; the sighting of robot "
              << observed << " by robot " << observer << " at " << utime << " us given up after " << oldest->second.attempts
              << " sends (" << counters_.sightings_unanswered << " so far; is lmf-server running?)\n";
  }
  pending_sightings_.erase(oldest);
}

void PlayerNode::send_sighting(PendingSighting& sighting) {
  ++sighting.attempts;
  sighting.last_sent = std::chrono::steady_clock::now();
  bus_.publish(options_.channels.sighting(), sighting.message);
}

std::chrono::steady_clock::duration PlayerNode::resend_wait(const PendingSighting& sighting) const {
  if (sighting.received) return options_.ack_timeout;
  return sighting_resend_.timeout(std::max(1, sighting.attempts));
}

void PlayerNode::schedule_sighting_resend() {
  if (sighting_timer_) loop_.cancel(*sighting_timer_);
  sighting_timer_.reset();
  if (pending_sightings_.empty()) return;
  auto due = std::chrono::steady_clock::time_point::max();
  for (const auto& entry : pending_sightings_) due = std::min(due, entry.second.last_sent + resend_wait(entry.second));
  const auto delay = std::max(due - std::chrono::steady_clock::now(), std::chrono::steady_clock::duration::zero());
  sighting_timer_ = loop_.after(std::chrono::ceil<std::chrono::milliseconds>(delay), [this] { resend_sightings(); });
}

void PlayerNode::resend_sightings() {
  sighting_timer_.reset();
  const auto now = std::chrono::steady_clock::now();
  // When one the server has not received is due, all of those go again, in
  // time order: a server that was down gets them in lmf-offline's order.
  bool unreceived_due = false;
  for (const auto& [key, p] : pending_sightings_) {
    if (!p.received && now - p.last_sent >= resend_wait(p)) unreceived_due = true;
  }
  int oldest = 0;
  bool oldest_unreceived = false;
  for (auto& [key, p] : pending_sightings_) {
    if (p.received ? now - p.last_sent >= resend_wait(p) : unreceived_due) {
      ++counters_.sighting_resends;
      send_sighting(p);
      if (p.attempts > oldest) {
        oldest = p.attempts;
        oldest_unreceived = !p.received;
      }
    }
  }
  if (pending_sightings_.empty()) {
    on_sightings_answered();
    return;
  }
  // Nothing is given up for want of an answer: say so now and then, so a
  // player waiting for a server that is not there does not wait silently.
  if (oldest_unreceived && oldest % 10 == 0) {
    std::cerr << "lmf-player: " << pending_sightings_.size() << " sighting(s) unanswered, the oldest after " << oldest
              << " sends; resending at most every " << options_.ack_timeout.count()
              << " ms (is lmf-server running?)\n";
  }
  schedule_sighting_resend();
}

void PlayerNode::give_up_pending_sightings() {
  end_wait_timer_.reset();
  counters_.sightings_unanswered += static_cast<std::int64_t>(pending_sightings_.size());
  std::cerr << "lmf-player: " << pending_sightings_.size() << " sighting(s) still unanswered "
            << options_.end_wait.count() << " ms after the replay; given up (is lmf-server running?)\n";
  pending_sightings_.clear();
  on_sightings_answered();
}

void PlayerNode::on_sightings_answered() {
  if (sighting_timer_) loop_.cancel(*sighting_timer_);
  sighting_timer_.reset();
  if (!ending_) return;
  if (end_wait_timer_) loop_.cancel(*end_wait_timer_);
  end_wait_timer_.reset();
  end_next_robot();
}

void PlayerNode::on_sighting_ack(const std::string& channel, const void* data, std::size_t size) {
  auto decoded = rt::decode<rt::SightingAck>(data, size);
  if (!decoded) {
    rejects_.record(decoded.rejection(), channel);
    return;
  }
  const rt::SightingAck& a = decoded.value();
  const SightingKey key{a.utime, a.observer_id, a.observed_id};
  const auto it = pending_sightings_.find(key);
  if (it == pending_sightings_.end()) {
    if (published_sightings_.count(key) != 0) {
      ++counters_.sighting_acks_duplicate;  // a resend's answer, or one after giving up
    } else {
      rejects_.record({rt::RejectReason::kOutOfRange, "ack of the sighting of robot " + to_string(a.observed_id) +
                                                          " by robot " + to_string(a.observer_id) + " at " +
                                                          to_string(a.utime) + " us, never sent"},
                      channel);
    }
    return;
  }
  PendingSighting& pending = it->second;
  // Karn's rule: only the first answer to a sighting sent once times the round trip.
  if (pending.attempts == 1 && !pending.received) {
    sighting_resend_.on_round_trip(std::chrono::steady_clock::now() - pending.last_sent);
  }
  on_sighting_received(key);
  if (a.status == rt::SightingAck::Status::kReceived) {
    pending.received = true;
    schedule_sighting_resend();
    return;
  }
  if (a.status == rt::SightingAck::Status::kRejected) {
    ++counters_.sightings_rejected;
    std::cerr << "lmf-player: the server rejected the sighting of robot " << a.observed_id << " by robot "
              << a.observer_id << " at " << a.utime << " us (its log says why)\n";
  } else {
    ++counters_.sightings_acked;
  }
  pending_sightings_.erase(it);
  if (pending_sightings_.empty()) {
    on_sightings_answered();
  } else {
    schedule_sighting_resend();
  }
}

void PlayerNode::on_sighting_received(const SightingKey& key) {
  if (awaiting_receipt_.erase(key) == 0 || !awaiting_receipt_.empty() || !receipt_timer_) return;
  loop_.cancel(*receipt_timer_);
  receipt_timer_.reset();
  // Not from inside the bus handler: the next scan goes out from a fresh loop turn.
  step_timer_ = loop_.after(0ms, [this] {
    step_timer_.reset();
    lockstep_step();
  });
}

// ---- the end ----------------------------------------------------------------------------------------

void PlayerNode::finish() {
  if (ack_timer_) loop_.cancel(*ack_timer_);
  ack_timer_.reset();
  report_progress(true);
  ending_ = true;
  if (pending_sightings_.empty()) {
    end_next_robot();
  } else if (options_.end_wait.count() > 0) {  // else once the last one is answered or given up
    end_wait_timer_ = loop_.after(options_.end_wait, [this] { give_up_pending_sightings(); });
  }
}

void PlayerNode::end_next_robot() {
  if (step_timer_) loop_.cancel(*step_timer_);
  step_timer_.reset();
  if (!options_.lockstep) {
    send_mission_end();
    return;
  }
  const auto now = std::chrono::steady_clock::now();
  while (ending_robot_ < robot_done_.size() && robot_done_[ending_robot_]) {
    ++ending_robot_;
    ending_robot_since_ = now;
  }
  if (ending_robot_ >= robot_done_.size()) {
    send_mission_end();
    return;
  }
  if (ending_robot_since_ == std::chrono::steady_clock::time_point{}) ending_robot_since_ = now;
  if (now - ending_robot_since_ >= options_.ack_timeout) {
    ++counters_.mission_end_waits_expired;
    std::cerr << "lmf-player: no mission_done from robot " << inputs_.robots[ending_robot_].robot_id << " within "
              << options_.ack_timeout.count() << " ms of its mission end; going on\n";
    robot_done_[ending_robot_] = true;
    end_next_robot();
    return;
  }
  rt::MissionEnd end;
  end.utime = events_.empty() ? 0 : std::max<std::int64_t>(0, events_.back().utime);
  end.robot_ids = {inputs_.robots[ending_robot_].robot_id};
  if (auto msg = rt::to_message(end)) bus_.publish(options_.channels.mission_end(), msg.value());
  step_timer_ = loop_.after(options_.mission_end_interval, [this] {
    step_timer_.reset();
    end_next_robot();
  });
}

void PlayerNode::on_agent_status(const std::string& channel, const void* data, std::size_t size) {
  auto status = rt::decode<rt::AgentStatus>(data, size);
  if (!status) {
    rejects_.record(status.rejection(), channel);
    return;
  }
  const auto it = robot_index_.find(status.value().robot_id);
  if (it == robot_index_.end() || !status.value().mission_done || robot_done_[it->second]) return;
  robot_done_[it->second] = true;
  if (!ending_ || finished_ || it->second != ending_robot_ || counters_.mission_end_sent > 0) return;
  // Not from inside the bus handler.
  if (step_timer_) loop_.cancel(*step_timer_);
  step_timer_ = loop_.after(0ms, [this] {
    step_timer_.reset();
    end_next_robot();
  });
}

void PlayerNode::send_mission_end() {
  rt::MissionEnd end;
  end.utime = events_.empty() ? 0 : std::max<std::int64_t>(0, events_.back().utime);
  for (const mission::RobotLog& log : inputs_.robots) end.robot_ids.push_back(log.robot_id);
  auto msg = rt::to_message(end);
  if (msg) bus_.publish(options_.channels.mission_end(), msg.value());  // ids were checked in the constructor
  ++counters_.mission_end_sent;
  if (counters_.mission_end_sent < options_.mission_end_repeats) {
    step_timer_ = loop_.after(options_.mission_end_interval, [this] {
      step_timer_.reset();
      send_mission_end();
    });
    return;
  }
  finished_ = true;
  if (options_.on_finished) options_.on_finished();
}

void PlayerNode::report_progress(bool force) {
  if (options_.progress == PlayerOptions::Progress::kNone) return;
  std::ostream& out = *options_.progress_stream;
  const auto now = std::chrono::steady_clock::now();
  const std::int64_t done = options_.lockstep ? static_cast<std::int64_t>(next_event_) : counters_.scans_sent;
  const std::int64_t total = std::max<std::int64_t>(1, counters_.scans_total);
  const int decile = static_cast<int>(10 * done / total);
  if (options_.progress == PlayerOptions::Progress::kLine) {
    if (!force && now - last_progress_time_ < 100ms) return;
  } else if (!force && decile <= last_progress_decile_) {
    return;
  }
  const double elapsed_s = std::chrono::duration<double>(now - start_time_).count();
  const double rate = elapsed_s > 0.0 ? static_cast<double>(done) / elapsed_s : 0.0;
  const double eta_s = rate > 0.0 ? static_cast<double>(total - done) / rate : 0.0;
  const double percent = 100.0 * static_cast<double>(done) / static_cast<double>(total);
  std::ostringstream line;
  line << std::fixed << std::setprecision(1) << "lmf-player: " << done << "/" << counters_.scans_total
       << " scans (" << percent << " %), " << rate << " scans/s, ETA " << std::setprecision(0) << eta_s << " s, "
       << counters_.sightings_published << " sightings";
  if (options_.progress == PlayerOptions::Progress::kLine) {
    last_progress_time_ = now;
    out << "\r" << line.str() << "\033[K" << (force ? "\n" : "") << std::flush;
    return;
  }
  if (force && decile <= last_progress_decile_ && last_progress_decile_ == 10) return;
  last_progress_decile_ = decile;
  out << line.str() << "\n" << std::flush;
}

std::string PlayerNode::summary() const {
  const PlayerCounters& c = counters_;
  std::ostringstream out;
  out << "scans sent " << c.scans_sent << "/" << c.scans_total << ", acked " << c.scans_acked << ", resends "
      << c.scan_resends << ", given up " << c.scans_given_up << "; sightings published " << c.sightings_published
      << "/" << c.sightings_total << " (approximate " << c.sightings_approximate << ", skipped "
      << c.sightings_skipped << ", resends " << c.sighting_resends << ", acked " << c.sightings_acked
      << ", rejected by the server " << c.sightings_rejected << ", unanswered " << c.sightings_unanswered
      << "); acks rejected " << rejects_.total();
  return out.str();
}

}  // namespace lmf::log_player
