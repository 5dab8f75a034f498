#include "lmf/mission/offline_mission.hpp"

#include "lmf/local_map/consistency.hpp"
#include "lmf/mission/mission_report.hpp"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <limits>
#include <set>
#include <stdexcept>
#include <utility>

namespace lmf::mission {
namespace {

double elapsed_ms(std::chrono::steady_clock::time_point since) {
  return std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - since).count();
}

}  // namespace

void MissionConfig::validate() const {
  local_map.validate();
  global_map.validate();
  if (!(sighting_noise.sigma_xy_m > 0.0)) throw std::invalid_argument("sighting_noise.sigma_xy_m must be > 0");
  if (!(sighting_noise.sigma_phi_rad > 0.0)) throw std::invalid_argument("sighting_noise.sigma_phi_rad must be > 0");
}

TimingStats timing_stats(std::vector<double> durations_ms) {
  TimingStats stats;
  stats.count = durations_ms.size();
  if (durations_ms.empty()) return stats;
  std::sort(durations_ms.begin(), durations_ms.end());
  // Nearest-rank percentiles.
  const auto rank = [&](double q) {
    const auto k = static_cast<std::size_t>(std::ceil(q * static_cast<double>(durations_ms.size())));
    return durations_ms[std::clamp<std::size_t>(k, 1, durations_ms.size()) - 1];
  };
  stats.p50_ms = rank(0.50);
  stats.p99_ms = rank(0.99);
  stats.max_ms = durations_ms.back();
  double sum = 0.0;
  for (double d : durations_ms) sum += d;
  stats.mean_ms = sum / static_cast<double>(durations_ms.size());
  return stats;
}

OfflineMission::OfflineMission(MissionConfig config, MissionInputs inputs)
    : config_(std::move(config)), inputs_(std::move(inputs)), global_map_(config_.global_map) {
  config_.validate();
  if (inputs_.robots.empty()) throw std::invalid_argument("OfflineMission: no robots");
  std::set<int> ids;
  for (const RobotLog& log : inputs_.robots) {
    if (!ids.insert(log.robot_id).second) {
      throw std::invalid_argument("OfflineMission: robot id " + std::to_string(log.robot_id) + " given twice");
    }
  }
  agents_.reserve(inputs_.robots.size());
  for (RobotLog& log : inputs_.robots) {
    agents_.push_back(Agent{&log, LocalMap(config_.local_map, log.robot_id), 0, {}, {}});
    RobotResult r;
    r.robot_id = log.robot_id;
    r.name = log.name;
    result_.robots.push_back(std::move(r));
  }
}

MissionResult OfflineMission::run() {
  if (ran_) throw std::logic_error("OfflineMission::run called twice");
  ran_ = true;

  // The first robot defines W; the others join through sightings.
  // W is L_r of its first local map, which begins at its first scan (the
  // others may join and fuse before that map ships).
  const RobotLog& first = inputs_.robots.front();
  if (!first.scans.empty()) world_in_reference_ = reference_pose(first.robot_id, first.scans.front().utime);
  record(global_map_.join_robot(first.robot_id, Pose2()));

  std::size_t next_sighting = 0;
  while (true) {
    // The earliest pending scan over all robots (ties: lower robot index).
    std::size_t best = agents_.size();
    int64_t best_time = std::numeric_limits<int64_t>::max();
    for (std::size_t i = 0; i < agents_.size(); ++i) {
      const Agent& a = agents_[i];
      if (a.next_scan < a.log->scans.size() && a.log->scans[a.next_scan].utime < best_time) {
        best = i;
        best_time = a.log->scans[a.next_scan].utime;
      }
    }
    // Sightings strictly before the next scan (scans first at equal times).
    while (next_sighting < inputs_.sightings.size() && inputs_.sightings[next_sighting].utime < best_time) {
      apply_sighting(inputs_.sightings[next_sighting++]);
    }
    if (best == agents_.size()) break;
    process_scan(agents_[best], result_.robots[best]);
  }

  // Ship what is left so every scan belongs to a fused local map.
  for (std::size_t i = 0; i < agents_.size(); ++i) {
    if (agents_[i].local_map.snapshot().scan_poses.empty()) continue;
    if (agents_[i].local_map.take_skipped_scan()) --result_.robots[i].scans_skipped;  // the map ends at its last scan
    ship(agents_[i], result_.robots[i]);
  }

  std::vector<double> fusion_ms;
  for (const auto& report : result_.fusions) fusion_ms.push_back(report.time.total_s * 1e3);
  result_.fusion_timing = timing_stats(std::move(fusion_ms));
  for (std::size_t i = 0; i < agents_.size(); ++i) {
    RobotResult& r = result_.robots[i];
    r.joined = global_map_.is_joined(r.robot_id);
    r.join = global_map_.how_joined(r.robot_id);
    r.trajectory = trajectories_.final_trajectory(global_map_, r.robot_id);
    r.scan_timing = timing_stats(r.scan_times_ms);
    r.odometry_model = agents_[i].local_map.odometry_model();
    r.odometry_learning = agents_[i].local_map.odometry_learning_stats();
    const FrontEnd& front_end = agents_[i].local_map.front_end();
    r.point_sigma_m = agents_[i].local_map.config().scan_matching.point_sigma_m;
    r.range_noise_per_m = front_end.range_noise_per_m();
    r.range_noise_matches = front_end.range_noise_measured() ? front_end.range_noise().matches() : 0;
    // Single matches are chains of one.
    for (const eval::ChainError& e : eval::chain_errors(agents_[i].matched_steps, agents_[i].reference_poses, 1)) {
      r.match_nees.push_back(e.nees);
    }
    for (const eval::ChainError& e :
         eval::chain_errors(agents_[i].matched_steps, agents_[i].reference_poses, kMatchChainSteps)) {
      r.match_chain_nees.push_back(e.nees);
    }
  }
  return result_;
}

void OfflineMission::process_scan(Agent& agent, RobotResult& result) {
  // As an agent receives it over LCM (laser_scan_t), so both give the same map.
  const LaserScan scan = at_message_precision(agent.log->scans[agent.next_scan++]);
  const auto start = std::chrono::steady_clock::now();
  const ScanReport report = agent.local_map.process_scan(scan);
  result.scan_times_ms.push_back(elapsed_ms(start));
  ++result.scans;
  if (report.scan_skipped) {
    // Not a new view: the matches' and local maps' checks see the scans taken.
    ++result.scans_skipped;
    return;
  }
  if (report.scan_match_tried) ++(report.scan_matched ? result.scan_matches : result.match_fallbacks);
  result.match_escalations += report.scan_match_escalated ? 1 : 0;
  result.matches_from_escalation += report.scan_match_from_escalation ? 1 : 0;
  agent.matched_steps.push_back(report.scan_matched ? std::optional<eval::RelativePose>(eval::RelativePose{
                                                          report.scan_match_increment, report.scan_match_covariance})
                                                    : std::nullopt);
  agent.reference_poses.push_back(reference_pose(result.robot_id, scan.utime));
  result.segments_seen_through += static_cast<std::size_t>(report.segments_seen_through);
  if (!report.covariance_health.ok() && result.covariance_always_ok) {
    result.covariance_always_ok = false;
    result.first_covariance_problem = report.covariance_health.describe();
  }
  if (report.should_ship) ship(agent, result);
}

void OfflineMission::ship(Agent& agent, RobotResult& result) {
  LocalMapSnapshot snapshot = agent.local_map.snapshot();
  // As the server receives it (local_map_t carries segment lengths as float).
  for (SegmentEstimate& segment : snapshot.segments) {
    segment.length_m = static_cast<double>(static_cast<float>(segment.length_m));
  }
  agent.local_map.reset();
  ++result.local_maps_shipped;
  check_consistency(snapshot, result);
  trajectories_.add(snapshot);
  frame_utimes_[{snapshot.robot_id, snapshot.seq}] = snapshot.first_utime;
  record(global_map_.fuse(snapshot));  // lockstep: fused before the next scan
}

std::optional<Pose2> OfflineMission::reference_pose(int robot_id, std::int64_t utime) const {
  // The reference is matched to scans by time (mission_inputs.hpp).
  const auto ref = inputs_.reference.find(robot_id);
  if (ref == inputs_.reference.end()) return std::nullopt;
  const auto it = std::lower_bound(ref->second.begin(), ref->second.end(), utime,
                                   [](const StampedPose& p, std::int64_t t) { return p.utime < t; });
  if (it == ref->second.end() || it->utime != utime) return std::nullopt;
  return it->pose;
}

void OfflineMission::check_consistency(const LocalMapSnapshot& snapshot, RobotResult& result) const {
  if (snapshot.covariance.rows() < 3) return;
  const std::optional<Pose2> start = reference_pose(snapshot.robot_id, snapshot.first_utime);
  const std::optional<Pose2> end = reference_pose(snapshot.robot_id, snapshot.last_utime);
  if (!start || !end) return;
  const Pose2 truth = between(*start, *end);
  const std::optional<double> nees = pose_nees(snapshot.x_LR, snapshot.covariance.topLeftCorner<3, 3>(), truth);
  if (!nees) return;
  const Pose2 e = between(snapshot.x_LR, truth);
  result.local_map_consistency.push_back(
      {snapshot.seq, std::hypot(e.x, e.y), std::abs(wrap_angle(e.phi)), *nees});
}

void OfflineMission::check_fusion_frame(const fusion::FusionReport& report) {
  if (!world_in_reference_) return;
  const auto utime = frame_utimes_.find({report.robot_id, report.seq});
  if (utime == frame_utimes_.end()) return;
  const std::optional<Pose2> reference = reference_pose(report.robot_id, utime->second);
  if (!reference) return;
  const Pose2 x_WL_true = between(*world_in_reference_, *reference);
  const Pose2 before = between(x_WL_true, report.x_WL_predicted);
  const Pose2 after = between(x_WL_true, report.x_WL_fused);
  result_.fusion_frame_checks.push_back({report.robot_id, report.seq, std::hypot(before.x, before.y),
                                         std::abs(wrap_angle(before.phi)), std::hypot(after.x, after.y),
                                         std::abs(wrap_angle(after.phi))});
}

void OfflineMission::record(const std::vector<fusion::FusionReport>& reports) {
  for (const fusion::FusionReport& report : reports) {
    for (RobotResult& r : result_.robots) {
      if (r.robot_id == report.robot_id) ++r.local_maps_fused;
    }
    if (!covariance_ok(report)) result_.global_covariance_always_ok = false;
    check_fusion_frame(report);
    result_.fusions.push_back(report);
  }
}

void OfflineMission::apply_sighting(const SightingInput& sighting) {
  SightingEvent event{sighting, fusion::SightingStatus::kPending};
  const auto find = [&](int id) -> Agent* {
    for (Agent& a : agents_) {
      if (a.log->robot_id == id) return &a;
    }
    return nullptr;
  };
  Agent* observer = find(sighting.observer);
  Agent* observed = find(sighting.observed);
  // A robot that has not scanned yet has no local frame to relate.
  if (observer == nullptr || observed == nullptr || observer->next_scan == 0 || observed->next_scan == 0) {
    event.status = fusion::SightingStatus::kIgnored;
    result_.sightings.push_back(event);
    return;
  }
  fusion::RobotSighting s;
  s.utime = sighting.utime;
  s.observer_id = sighting.observer;
  s.observed_id = sighting.observed;
  s.observer_seq = observer->local_map.seq();
  // The robot in the filter: after a scan the motion filter skipped, at the
  // last scan taken, up to a keyframe behind (docs/design.md §10, "The motion
  // filter"), as the agent's acks say.
  s.x_LA = observer->local_map.x_LR();
  s.cov_LA = observer->local_map.robot_covariance();
  s.x_AB = sighting.x_AB;
  s.cov_AB = sighting.covariance;
  s.observed_seq = observed->local_map.seq();
  s.x_LB = observed->local_map.x_LR();
  s.cov_LB = observed->local_map.robot_covariance();
  fusion::SightingResult r = global_map_.add_sighting(s);
  record(r.fused);
  event.status = r.status;
  result_.sightings.push_back(event);
}

}  // namespace lmf::mission
