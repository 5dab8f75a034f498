#include "lmf/fusion/global_map.hpp"

#include <chrono>
#include <cmath>
#include <limits>
#include <stdexcept>
#include <string>
#include <unordered_map>
#include <utility>

#include "lmf/common/config_check.hpp"
#include "lmf/fusion/fusion_steps.hpp"
#include "lmf/spmap/covariance_check.hpp"

namespace lmf::fusion {
namespace {

using Clock = std::chrono::steady_clock;

// Measures phases for FusionReport::time; never used for a decision.
class PhaseClock {
 public:
  PhaseClock() : start_(Clock::now()), last_(start_) {}
  double lap() {
    const Clock::time_point now = Clock::now();
    const double s = std::chrono::duration<double>(now - last_).count();
    last_ = now;
    return s;
  }
  double total() const { return std::chrono::duration<double>(Clock::now() - start_).count(); }

 private:
  Clock::time_point start_;
  Clock::time_point last_;
};

std::string where(int robot_id, std::int64_t seq) {
  return "local map of robot " + std::to_string(robot_id) + " seq " + std::to_string(seq);
}

using Reason = InvalidInput::Reason;

// The config once validate() has passed it (it throws), before any member is built from it.
GlobalMapConfig validated(const GlobalMapConfig& config) {
  config.validate();
  return config;
}

// Why P is not a covariance (symmetric PSD within tolerance · max(1, max |P_ii|)), if it is not.
std::optional<std::pair<Reason, std::string>> covariance_problem(const Eigen::MatrixXd& P, double tolerance) {
  if (!P.allFinite()) return std::pair{Reason::kNonFinite, std::string("has NaN or inf entries")};
  const spmap::CovarianceHealth health = spmap::check_covariance(P, tolerance);
  if (!health.symmetric) {
    return std::pair{Reason::kNotSymmetricPsd,
                     "is not symmetric (max |P - P^T| = " + std::to_string(health.max_asymmetry) + ")"};
  }
  if (!health.positive_semidefinite) {
    return std::pair{Reason::kNotSymmetricPsd, "is not positive semidefinite (smallest eigenvalue " +
                                                   std::to_string(health.min_eigenvalue.value_or(std::numeric_limits<double>::quiet_NaN())) + ")"};
  }
  return std::nullopt;
}

}  // namespace

// ---------------------------------------------------------------------------
// Configuration and validation

void GlobalMapConfig::validate() const {
  const ConfigCheck require("GlobalMapConfig");
  require(alpha > 0.0 && alpha < 1.0, "alpha must be in (0, 1)");
  require(std::isfinite(local_map_covariance_scale) && local_map_covariance_scale > 0.0,
          "local_map_covariance_scale must be finite and > 0");
  require(std::isfinite(gate_angle_rad) && gate_angle_rad >= 0.0, "gate_angle_rad must be finite and >= 0");
  require(std::isfinite(gate_distance_m) && gate_distance_m >= 0.0, "gate_distance_m must be finite and >= 0");
  require(std::isfinite(gate_gap_m) && gate_gap_m >= 0.0, "gate_gap_m must be finite and >= 0");
  require(std::isfinite(gate_sigmas) && gate_sigmas >= 0.0, "gate_sigmas must be finite and >= 0");
  require(std::isfinite(min_overlap_m), "min_overlap_m must be finite");
  require(careful_relative_tolerance > 0.0 && careful_relative_tolerance < 1.0,
          "careful_relative_tolerance must be in (0, 1)");
  require(std::isfinite(careful_absolute_floor) && careful_absolute_floor >= 0.0,
          "careful_absolute_floor must be finite and >= 0");
  require(std::isfinite(snapshot_tolerance) && snapshot_tolerance >= 0.0,
          "snapshot_tolerance must be finite and >= 0");
  require(std::isfinite(max_coordinate_m) && max_coordinate_m > 0.0, "max_coordinate_m must be finite and > 0");
  require(frame_history_per_robot >= 0, "frame_history_per_robot must be >= 0");
  require(std::isfinite(footprint_radius_m) && footprint_radius_m >= 0.0,
          "footprint_radius_m must be finite and >= 0");
  require(std::isfinite(crossing_margin_m) && crossing_margin_m >= 0.0, "crossing_margin_m must be finite and >= 0");
  require(crossing_max_angle_rad > 0.0 && crossing_max_angle_rad <= std::numbers::pi / 2,
          "crossing_max_angle_rad must be in (0, pi/2]");
  registration.validate();
  place_recognition.validate();
}

const char* to_string(RegistrationOutcome outcome) {
  switch (outcome) {
    case RegistrationOutcome::kNotRun: return "not_run";
    case RegistrationOutcome::kNothingNearby: return "nothing_nearby";
    case RegistrationOutcome::kAgrees: return "agrees";
    case RegistrationOutcome::kAmbiguous: return "ambiguous";
    case RegistrationOutcome::kDegenerate: return "degenerate";
    case RegistrationOutcome::kRelocated: return "relocated";
  }
  return "unknown";
}

const char* to_string(JoinKind kind) {
  switch (kind) {
    case JoinKind::kFirst: return "first";
    case JoinKind::kKnownFrame: return "known_frame";
    case JoinKind::kSighting: return "sighting";
    case JoinKind::kPlace: return "place";
  }
  return "unknown";
}

bool FusionReport::covariance_ok() const {
  if (min_eigenvalue) return *min_eigenvalue >= -kPsdTolerance;
  return !min_ldlt_pivot || *min_ldlt_pivot >= -kPsdTolerance;
}

GlobalMap::GlobalMap(GlobalMapConfig config)
    : config_(validated(config)),
      arrivals_(config_.local_map_covariance_scale, config_.frame_history_per_robot) {
  if (config_.footprint_radius_m > 0.0) footprints_.emplace(config_.footprint_radius_m);
}

std::optional<std::pair<Reason, std::string>> GlobalMap::pose_problem(const Pose2& pose) const {
  if (!finite(pose)) return std::pair{Reason::kNonFinite, std::string(" is not finite")};
  if (std::abs(pose.x) > config_.max_coordinate_m || std::abs(pose.y) > config_.max_coordinate_m) {
    return std::pair{Reason::kOutOfRange, std::string(" is beyond max_coordinate_m")};
  }
  return std::nullopt;
}

void GlobalMap::check_pose(const Pose2& pose, const std::string& what) const {
  if (const auto problem = pose_problem(pose)) throw InvalidInput(problem->first, what + problem->second);
}

void GlobalMap::check_covariance(const Eigen::MatrixXd& P, const std::string& what) const {
  if (const auto problem = covariance_problem(P, config_.snapshot_tolerance)) {
    throw InvalidInput(problem->first, what + " " + problem->second);
  }
  // A standard deviation beyond max_coordinate_m is garbage like such a
  // coordinate; a finite but absurd variance (1e268) overflowed the fusion
  // into a NaN map (found by fuzzing).
  const double max_variance = config_.max_coordinate_m * config_.max_coordinate_m;
  if (P.size() > 0 && P.diagonal().maxCoeff() > max_variance) {
    throw InvalidInput(Reason::kOutOfRange, what + " has a variance above max_coordinate_m²");
  }
}

void GlobalMap::validate(const LocalMapSnapshot& s) const {
  // This runs on every local map: the messages are built only for a rejection.
  const auto at = [&s] { return where(s.robot_id, s.seq); };
  if (s.seq < 0) throw InvalidInput(Reason::kOutOfRange, at() + ": negative sequence number");
  if (const auto problem = pose_problem(s.x_LR)) {
    throw InvalidInput(problem->first, at() + ": robot pose x_LR" + problem->second);
  }
  for (std::size_t j = 0; j < s.segments.size(); ++j) {
    const SegmentEstimate& seg = s.segments[j];
    const auto name = [&] { return at() + ": segment " + std::to_string(j); };
    if (const auto problem = pose_problem(seg.location)) {
      throw InvalidInput(problem->first, name() + " location" + problem->second);
    }
    if (!std::isfinite(seg.length_m)) throw InvalidInput(Reason::kNonFinite, name() + " length is not finite");
    if (seg.length_m <= 0.0 || seg.length_m > config_.max_coordinate_m) {
      throw InvalidInput(Reason::kOutOfRange,
                         name() + " has length " + std::to_string(seg.length_m) + " (must be > 0)");
    }
  }
  for (std::size_t i = 0; i < s.scan_poses.size(); ++i) {
    if (const auto problem = pose_problem(s.scan_poses[i].x_LR)) {
      throw InvalidInput(problem->first, at() + ": scan pose " + std::to_string(i) + problem->second);
    }
  }
  const auto expected = static_cast<Eigen::Index>(3 + 2 * s.segments.size());
  if (s.covariance.rows() != expected || s.covariance.cols() != expected) {
    throw InvalidInput(Reason::kMalformed, at() + ": covariance is " + std::to_string(s.covariance.rows()) + "x" +
                                               std::to_string(s.covariance.cols()) + ", expected " +
                                               std::to_string(expected) + " (3 + 2 x " +
                                               std::to_string(s.segments.size()) + " segments)");
  }
  check_covariance(s.covariance, at() + ": covariance");
}

// ---------------------------------------------------------------------------
// Queries

bool GlobalMap::is_joined(int robot_id) const { return arrivals_.is_joined(robot_id); }

std::optional<RobotJoin> GlobalMap::how_joined(int robot_id) const {
  const auto it = joins_.find(robot_id);
  if (it == joins_.end()) return std::nullopt;
  return it->second;
}

bool GlobalMap::has_fused(int robot_id, std::int64_t seq) const { return arrivals_.has_fused(robot_id, seq); }

std::optional<Pose2> GlobalMap::fused_frame(int robot_id, std::int64_t seq) const {
  return arrivals_.fused_frame(robot_id, seq);
}

bool GlobalMap::is_queued(int robot_id, std::int64_t seq) const { return arrivals_.is_queued(robot_id, seq); }

int GlobalMap::queued_count() const { return arrivals_.queued_count(); }

std::vector<int> GlobalMap::robots() const { return arrivals_.joined(); }

std::optional<CorrectedFrame> GlobalMap::corrected_frame(int robot_id) const {
  if (!is_joined(robot_id)) return std::nullopt;
  const auto [seq, L] = arrivals_.current_frame(robot_id);
  CorrectedFrame f;
  f.robot_id = robot_id;
  f.map_seq = seq;
  f.x_WL = state_.root_location(L);
  f.covariance = frame_world_covariance(state_, L);
  return f;
}

std::vector<CorrectedFrame> GlobalMap::corrected_frames() const {
  std::vector<CorrectedFrame> out;
  for (const int id : robots()) out.push_back(*corrected_frame(id));
  return out;
}

std::vector<SegmentView> GlobalMap::segments() const {
  std::vector<SegmentView> out;
  for (const Entity& e : state_.entities()) {
    if (e.kind != EntityKind::kSegment) continue;
    SegmentView v;
    v.id = e.id;
    v.submap = e.parent.value_or(-1);
    v.x_WS = state_.root_location(e.id);
    v.length_m = e.length_m;
    v.start_W = v.x_WS.transform_point({-0.5 * e.length_m, 0.0});
    v.end_W = v.x_WS.transform_point({0.5 * e.length_m, 0.0});
    v.covariance = segment_world_covariance(state_, e.id);
    out.push_back(v);
  }
  return out;
}

std::vector<SubmapView> GlobalMap::submaps() const {
  std::unordered_map<EntityId, int> children;
  for (const Entity& e : state_.entities()) {
    if (e.parent) ++children[*e.parent];
  }
  std::vector<SubmapView> out;
  for (const SubmapRecord& r : graph_.submaps()) {
    SubmapView v;
    v.frame = r.frame;
    v.robot_id = r.robot_id;
    v.seq = r.seq;
    v.x_WF = state_.root_location(r.frame);
    v.covariance = frame_world_covariance(state_, r.frame);
    const auto it = children.find(r.frame);
    v.segments = it == children.end() ? 0 : it->second;
    out.push_back(v);
  }
  return out;
}

std::vector<GraphEdge> GlobalMap::graph_edges() const { return graph_.edges(); }

MapCounts GlobalMap::counts() const {
  MapCounts c;
  for (const Entity& e : state_.entities()) {
    if (e.kind == EntityKind::kSegment) ++c.segments;
  }
  c.submaps = static_cast<int>(graph_.submaps().size());
  c.robots_joined = static_cast<int>(robots().size());
  c.graph_edges = static_cast<int>(graph_edges().size());
  c.queued_local_maps = queued_count();
  c.state_dimension = state_.dimension();
  return c;
}

// ---------------------------------------------------------------------------
// Joining

std::vector<FusionReport> GlobalMap::join_robot(int robot_id, const Pose2& x_WL, const Eigen::Matrix3d& covariance,
                                                std::int64_t seq) {
  const std::string at = "join_robot(robot " + std::to_string(robot_id) + ")";
  if (is_joined(robot_id)) throw InvalidInput(Reason::kDuplicate, at + ": the robot has already joined");
  if (seq < 0) throw InvalidInput(Reason::kOutOfRange, at + ": negative sequence number");
  check_pose(x_WL, at + ": x_WL");
  check_covariance(covariance, at + ": covariance");

  std::vector<FusionReport> out;
  const EntityId L = state_.add(EntityKind::kFrame, x_WL);
  state_.set_block(L, L, covariance);
  joins_[robot_id] = {JoinKind::kKnownFrame, seq};
  join(robot_id, L, seq, Sightings::kResolveAfterEachFusion, out);
  resolve_sightings(out);
  return out;
}

void GlobalMap::join(int robot_id, EntityId frame, std::int64_t seq, Sightings sightings,
                     std::vector<FusionReport>& out) {
  arrivals_.join(robot_id, frame, seq, state_);
  drain(robot_id, sightings, out);
}

void GlobalMap::drain(int robot_id, Sightings sightings, std::vector<FusionReport>& out) {
  while (const std::optional<LocalMapSnapshot> snapshot = arrivals_.take_next(robot_id, state_)) {
    out.push_back(fuse_one(robot_id, *snapshot));
    if (sightings == Sightings::kResolveAfterEachFusion) resolve_sightings(out);
  }
}

// ---------------------------------------------------------------------------
// Sightings

SightingResult GlobalMap::add_sighting(const RobotSighting& s) {
  const std::string at = "sighting of robot " + std::to_string(s.observed_id) + " by robot " +
                         std::to_string(s.observer_id);
  if (s.observer_id == s.observed_id) throw InvalidInput(Reason::kMalformed, at + ": a robot cannot sight itself");
  if (s.observer_seq < 0 || s.observed_seq < 0) {
    throw InvalidInput(Reason::kOutOfRange, at + ": negative sequence number");
  }
  check_pose(s.x_LA, at + ": x_LA");
  check_pose(s.x_AB, at + ": x_AB");
  check_pose(s.x_LB, at + ": x_LB");
  check_covariance(s.cov_LA, at + ": cov_LA");
  check_covariance(s.cov_AB, at + ": cov_AB");
  check_covariance(s.cov_LB, at + ": cov_LB");

  SightingResult result;
  if (is_joined(s.observed_id)) {
    result.status = SightingStatus::kIgnored;
    return result;
  }
  const std::optional<SightingStatus> status = resolve(s, Sightings::kResolveAfterEachFusion, result.fused);
  if (!status) {
    arrivals_.add_pending(s);
    result.status = SightingStatus::kPending;
    return result;
  }
  result.status = *status;
  resolve_sightings(result.fused);
  return result;
}

std::optional<SightingStatus> GlobalMap::resolve(const RobotSighting& s, Sightings sightings,
                                                 std::vector<FusionReport>& out) {
  if (is_joined(s.observed_id)) return SightingStatus::kIgnored;
  const std::optional<RobotArrivals::SightedJoin> placed = arrivals_.place_sighted_frame(s, graph_, state_);
  if (!placed) return std::nullopt;
  joins_[s.observed_id] = {JoinKind::kSighting, s.observed_seq};
  join(s.observed_id, placed->frame, s.observed_seq, sightings, out);
  return placed->approximate ? SightingStatus::kJoinedApproximately : SightingStatus::kJoined;
}

void GlobalMap::resolve_sightings(std::vector<FusionReport>& out) {
  // The drains below leave the sightings to this loop, which takes the first
  // resolvable one again after each.
  while (const std::optional<RobotSighting> s = arrivals_.take_resolvable(graph_)) {
    resolve(*s, Sightings::kLeaveToCaller, out);
  }
}

// ---------------------------------------------------------------------------
// Fusion

std::vector<FusionReport> GlobalMap::fuse(const LocalMapSnapshot& snapshot) {
  validate(snapshot);
  if (has_fused(snapshot.robot_id, snapshot.seq)) {
    throw InvalidInput(Reason::kDuplicate, where(snapshot.robot_id, snapshot.seq) + ": already fused");
  }
  if (is_queued(snapshot.robot_id, snapshot.seq)) {
    throw InvalidInput(Reason::kDuplicate, where(snapshot.robot_id, snapshot.seq) + ": already queued");
  }
  std::vector<FusionReport> out;
  arrivals_.enqueue(snapshot);
  if (!arrivals_.any_joined() && config_.first_robot_defines_world) {
    // docs/design.md §5: the first robot defines the global frame.
    const EntityId L = state_.add(EntityKind::kFrame, Pose2());
    joins_[snapshot.robot_id] = {JoinKind::kFirst, snapshot.seq};
    join(snapshot.robot_id, L, snapshot.seq, Sightings::kResolveAfterEachFusion, out);
  } else if (is_joined(snapshot.robot_id)) {
    drain(snapshot.robot_id, Sightings::kResolveAfterEachFusion, out);
  } else if (arrivals_.any_joined() && config_.place_recognition.enabled) {
    join_by_place(snapshot.robot_id, out);
  }
  resolve_sightings(out);
  if (!out.empty() && config_.place_recognition.enabled) retry_places(out);
  return out;
}

void GlobalMap::join_by_place(int robot_id, std::vector<FusionReport>& out) {
  std::vector<RegistrationSegment> global;
  for (const Entity& e : state_.entities()) {
    if (e.kind == EntityKind::kSegment) global.push_back({state_.root_location(e.id), e.length_m});
  }
  for (const LocalMapSnapshot* snapshot :
       arrivals_.oldest_waiting_maps(robot_id, 1 + config_.registration.own_recent_maps)) {
    std::vector<RegistrationSegment> local;
    for (const SegmentEstimate& s : snapshot->segments) local.push_back({s.location, s.length_m});
    const PlaceRecognition place = recognise_place(local, global, config_.registration, config_.place_recognition);
    switch (place.outcome) {
      case PlaceOutcome::kPlaced: ++place_counts_.placed; break;
      case PlaceOutcome::kNotFound: ++place_counts_.not_found; continue;
      case PlaceOutcome::kAmbiguous: ++place_counts_.ambiguous; continue;
      case PlaceOutcome::kDegenerate: ++place_counts_.degenerate; continue;
    }
    // L_r where the local map was found, with the registration field's σ (two
    // cells) and two angular steps as its standard deviations: the pairing
    // tests then judge the local map's segments against the map's near it.
    const double sigma_xy = 2.0 * place.resolution_m;
    const double sigma_phi = 2.0 * place.angular_step_rad;
    const EntityId L = state_.add(EntityKind::kFrame, place.x_WL);
    state_.set_block(L, L, Eigen::Vector3d(sigma_xy * sigma_xy, sigma_xy * sigma_xy, sigma_phi * sigma_phi).asDiagonal());
    const std::int64_t seq = snapshot->seq;  // the snapshot leaves the queue as it fuses
    joins_[robot_id] = {JoinKind::kPlace, seq, place.score};
    join(robot_id, L, seq, Sightings::kResolveAfterEachFusion, out);
    return;
  }
}

void GlobalMap::retry_places(std::vector<FusionReport>& out) {
  for (const int robot_id : arrivals_.waiting()) {
    if (!is_joined(robot_id)) join_by_place(robot_id, out);  // (an earlier one's fusions may have joined it)
  }
}

FusionReport GlobalMap::fuse_one(int robot_id, const LocalMapSnapshot& snapshot) {
  PhaseClock clock;
  FusionContext f(state_, config_, robot_id, snapshot, arrivals_.frame_slot(robot_id, snapshot.seq));
  PhaseTimes& time = f.report.time;
  time.validate_s = clock.lap();
  // Steps 1-4 of docs/design.md §5, each timed on its own.
  const std::pair<void (*)(FusionContext&), double PhaseTimes::*> pairing_steps[] = {
      {augment, &PhaseTimes::augment_s},                           // step 1
      {gate, &PhaseTimes::gate_s},                                 // step 2
      {test_individual_compatibility, &PhaseTimes::individual_s},  // step 2
      {test_joint_compatibility, &PhaseTimes::joint_s},            // step 3
      {update_with_pairings, &PhaseTimes::update_s},               // step 3
      {update_geometry, &PhaseTimes::geometric_s},                 // step 4
  };
  for (const auto& [step, phase] : pairing_steps) {
    step(f);
    time.*phase = clock.lap();
    if (step == augment) {
      relocate_frame(f, graph_);  // beyond the paper
      time.registration_s = clock.lap();
    }
  }
  make_new_submap(f, graph_);                                        // step 5
  advance_robot_frame(f, arrivals_, graph_);                         // step 6
  connect_submaps(f, graph_);                                        // step 7
  if (footprints_) remove_footprint_segments(f, *footprints_);       // beyond the paper
  if (config_.crossing_margin_m > 0.0) remove_crossing_segments(f);  // beyond the paper
  time.frames_s = clock.lap();
  state_.remove(f.removals);
  time.remove_s = clock.lap();
  check_health(f, arrivals_.current_frame(robot_id).second);
  time.health_s = clock.lap();
  f.report.size_after = counts();
  time.total_s = clock.total();
  return f.report;
}

}  // namespace lmf::fusion
