#include "lmf/local_map/local_map.hpp"

#include <algorithm>
#include <cmath>
#include <map>
#include <numeric>
#include <set>
#include <stdexcept>
#include <string>
#include <utility>

#include <Eigen/Cholesky>
#include <Eigen/Eigenvalues>
#include <Eigen/LU>

#include "lmf/local_map/local_map_measurements.hpp"
#include "lmf/scan/segment_extraction.hpp"
#include "lmf/spmap/segment_ops.hpp"

namespace lmf {
namespace {

using spmap::EntityId;
using spmap::EntityKind;

// An observation the filter can use: finite, positive length, covariance
// symmetric positive semidefinite. Sensor data never aborts: others are skipped.
bool usable(const ObservedSegment& e) {
  if (!finite(e.location) || !std::isfinite(e.length_m) || e.length_m <= 0.0) return false;
  const Eigen::Matrix2d& C = e.covariance;
  if (!C.allFinite()) return false;
  const double scale = std::max({1e-300, std::abs(C(0, 0)), std::abs(C(1, 1))});
  if (std::abs(C(0, 1) - C(1, 0)) > 1e-9 * scale) return false;
  return C(0, 0) >= 0.0 && C(1, 1) >= 0.0 && C(0, 0) * C(1, 1) - C(0, 1) * C(1, 0) >= -1e-12 * scale * scale;
}

void require_finite_odometry(int64_t utime, const Pose2& odometry) {
  if (!finite(odometry)) {
    throw std::invalid_argument("LocalMap::update: non-finite odometry pose in the scan at utime " +
                                std::to_string(utime));
  }
}

}  // namespace

LocalMap::LocalMap(const LocalMapConfig& config, int robot_id)
    : config_(config),
      robot_id_(robot_id),
      front_end_((config.validate(),
                  FrontEndConfig{{local_map::odometry_prior(config), config.odometry_learning, config.scan_matching,
                                  config.scans_have_odometry},
                                 config.motion_filter})),
      careful_{config.careful_inverse_tolerance, 0.0},
      pairing_chi2_(config.pairing_alpha),
      joint_chi2_(config.joint_alpha),
      constraint_chi2_(config.constraint_alpha) {
  pairing_threshold_ = spmap::chi2_threshold(2, config_.pairing_alpha);
  robot_ = map_.add(EntityKind::kRobot, Pose2());
}

Pose2 LocalMap::x_LR() const { return map_.entity(robot_).location; }

Eigen::Matrix3d LocalMap::robot_covariance() const { return map_.block(robot_, robot_); }

Pose2 LocalMap::x_LR_at_last_scan() const {
  return motion_to_skipped_ ? compose(x_LR(), motion_to_skipped_->u) : x_LR();
}

Eigen::Matrix3d LocalMap::robot_covariance_at_last_scan() const {
  if (!motion_to_skipped_) return robot_covariance();
  const local_map::PredictionJacobians pj = local_map::prediction_jacobians(x_LR(), motion_to_skipped_->u);
  const Eigen::Matrix3d& Q = motion_to_skipped_->Q;
  const Eigen::Matrix3d P = pj.J_R * robot_covariance() * pj.J_R.transpose() +
                            pj.J_u * (0.5 * (Q + Q.transpose())) * pj.J_u.transpose();
  return 0.5 * (P + P.transpose());
}

std::size_t LocalMap::num_segments() const { return map_.entities().size() - 1; }

std::vector<EntityId> LocalMap::segment_ids() const {
  std::vector<EntityId> ids;
  ids.reserve(num_segments());
  for (const spmap::Entity& e : map_.entities()) {
    if (e.kind == EntityKind::kSegment) ids.push_back(e.id);
  }
  return ids;
}

EntityId LocalMap::add_segment_for_test(const Pose2& x_LS, double length_m, const Eigen::Matrix2d& covariance) {
  if (!finite(x_LS) || !std::isfinite(length_m) || length_m <= 0.0 || !covariance.allFinite()) {
    throw std::invalid_argument("LocalMap::add_segment_for_test: location, length (> 0) and covariance must be finite");
  }
  const EntityId id = map_.add(EntityKind::kSegment, x_LS, std::nullopt, length_m);
  const Eigen::Index off = map_.entity(id).offset;
  map_.mutable_covariance().block<2, 2>(off, off) = 0.5 * (covariance + covariance.transpose());
  groups_.find(id);  // a group of its own
  return id;
}

// ---------------------------------------------------------------------------
// Step 1: prediction.

void LocalMap::predict(const Pose2& u) {
  if (!finite(u)) throw std::invalid_argument("LocalMap::predict: non-finite odometry increment");
  const OdometryErrorModel& model = odometry_model();
  predict(model.corrected(u), model.covariance(u));
}

void LocalMap::predict(const Pose2& u, const Eigen::Matrix3d& Q) {
  if (!finite(u)) throw std::invalid_argument("LocalMap::predict: non-finite odometry increment");
  if (!Q.allFinite()) throw std::invalid_argument("LocalMap::predict: non-finite increment covariance");
  const local_map::PredictionJacobians pj = local_map::prediction_jacobians(x_LR(), u);
  // p_R ← J_R p_R transforms P_RR and every cross term P_R,x exactly (docs/design.md §4.1) ...
  map_.replace_perturbation(robot_, {{robot_, pj.J_R}});
  map_.mutable_entity(robot_).location = pj.x_LR;
  // ... and the increment's noise, independent of the state, adds J_u Q J_uᵀ to P_RR.
  const Eigen::Index off = map_.entity(robot_).offset;
  map_.mutable_covariance().block<3, 3>(off, off) += pj.J_u * (0.5 * (Q + Q.transpose())) * pj.J_u.transpose();
  span_m_ += std::hypot(u.x, u.y);
}

// ---------------------------------------------------------------------------
// The scan.

ScanReport LocalMap::update(int64_t utime, const Pose2& odometry, const std::vector<ObservedSegment>& observations) {
  require_finite_odometry(utime, odometry);
  return update_with(utime, observations, front_end_.odometry_step(utime, odometry), ScanReport{});
}

ScanReport LocalMap::update_with(int64_t utime, const std::vector<ObservedSegment>& observations,
                                 const std::optional<MotionIncrement>& motion, ScanReport report) {
  report.utime = utime;
  report.observations = static_cast<int>(observations.size());
  report.map_segments_before = static_cast<int>(num_segments());
  last_scan_skipped_.reset();  // this scan reaches the filter: the map is at it
  motion_to_skipped_.reset();

  std::vector<ObservedSegment> usable_observations;
  usable_observations.reserve(observations.size());
  for (const ObservedSegment& e : observations) {
    if (usable(e)) {
      usable_observations.push_back(e);
      // Step 2: the per-view model error on top of the fit's point noise.
      const double end_angle = config_.observation_end_noise_m / e.length_m;
      usable_observations.back().covariance +=
          Eigen::Vector2d(config_.observation_lateral_noise_m * config_.observation_lateral_noise_m,
                          config_.observation_angular_noise_rad * config_.observation_angular_noise_rad +
                              end_angle * end_angle)
              .asDiagonal();
    } else {
      ++report.observations_rejected;
    }
  }

  // Step 1: predict with the motion since the previous scan (the front end's:
  // the scan match, or the corrected odometry).
  if (motion) predict(motion->u, motion->Q);
  if (!first_utime_) first_utime_ = utime;
  last_utime_ = utime;

  // Step 3: individual pairing; steps 4–5: joint compatibility and one update.
  std::vector<Candidate> candidates = pair_observations(usable_observations, report);
  std::vector<bool> had_candidate(usable_observations.size(), false);
  for (const Candidate& c : candidates) had_candidate[c.pairing.observation] = true;
  const std::vector<Pairing> pairings = joint_update(std::move(candidates), report);

  geometric_update(usable_observations, pairings, report);                                        // step 6
  fuse_multiple_matches(pairings, report);                                                          // step 7
  const std::vector<EntityId> added = add_unpaired(usable_observations, had_candidate, pairings, report);  // step 8
  if (config_.constraints_enabled) apply_constraints(added, report);                               // step 9

  scan_poses_.push_back({utime, x_LR()});
  report.map_segments = static_cast<int>(num_segments());
  report.x_LR = x_LR();
  ++scans_;
  report.should_ship = should_ship();  // step 10: the caller ships and resets
  // Supervision: every covariance_check_interval scans, and always on the scan
  // that ships, so no map leaves unchecked (LocalMapConfig).
  const bool check_due =
      config_.covariance_check_interval > 0 && scans_ % config_.covariance_check_interval == 0;
  if (check_due || report.should_ship) {
    report.covariance_checked = true;
    report.covariance_health = check_covariance();
  }
  return report;
}

ScanReport LocalMap::process_scan(const LaserScan& scan) { return process(scan, false); }

std::optional<ScanReport> LocalMap::take_skipped_scan() {
  if (!last_scan_skipped_) return std::nullopt;
  const LaserScan scan = std::move(*last_scan_skipped_);  // update_with clears the skip state
  scan_poses_.pop_back();  // its dead-reckoned pose; the update gives it its own
  return process(scan, true);
}

ScanReport LocalMap::process(const LaserScan& scan, bool take) {
  require_finite_odometry(scan.utime, scan.odometry);
  const RegisteredScan registered = front_end_.register_scan(scan, take);  // step 1
  ScanReport report;
  if (registered.skipped) {
    // Not a new view (the front end's motion filter): the filter is not
    // touched; the scan's pose is dead-reckoned from the last scan taken.
    report.utime = scan.utime;
    report.scan_skipped = true;
    report.map_segments_before = report.map_segments = static_cast<int>(num_segments());
    motion_to_skipped_ = registered.motion;
    report.x_LR = x_LR_at_last_scan();
    scan_poses_.push_back({scan.utime, report.x_LR});
    last_scan_skipped_ = scan;
    return report;
  }
  report.scan_match_tried = registered.registration_tried;
  report.scan_match_escalated = registered.search_escalated;
  report.scan_match_from_escalation = registered.match_from_escalation;
  report.odometry_learning_weight = registered.odometry_learning_weight;
  if (const std::optional<ScanMatch>& match = registered.registration) {
    report.scan_matched = true;
    report.scan_match_points = match->correspondences;
    report.scan_match_increment = match->x_AB;
    report.scan_match_covariance = match->covariance;
    report.scan_match_objects_moving = match->objects_moving;
  }
  report = update_with(scan.utime, extract_segments(scan, config_.extraction), registered.motion, report);  // step 2
  if (config_.see_through.enabled) {
    report.segments_seen_through = remove_seen_through(scan);
    report.map_segments = static_cast<int>(num_segments());
  }
  return report;
}

// Free-space evidence: segments the scan sees through are removed (marginalised
// out of the map: deleting an entity's rows and columns of P is exact).
int LocalMap::remove_seen_through(const LaserScan& scan) {
  const std::vector<EntityId> ids = segment_ids();
  const Pose2 x_LR_hat = x_LR();
  std::vector<SensorSegment> in_sensor;
  in_sensor.reserve(ids.size());
  for (const EntityId id : ids) in_sensor.push_back({between(x_LR_hat, map_.root_location(id)), map_.entity(id).length_m});
  const std::vector<SeeThroughCount> counts =
      count_see_through(scan, in_sensor, config_.extraction.min_range_m, max_valid_range(scan, config_.extraction),
                        config_.see_through);
  int removed = 0;
  for (std::size_t i = 0; i < ids.size(); ++i) {
    if (!counts[i].seen_through(config_.see_through)) continue;
    map_.remove(ids[i]);
    ++removed;
  }
  return removed;
}

// ---------------------------------------------------------------------------
// Step 3: pair every observation with every map segment it may be (no
// nearest-neighbour rule: one observation may pair several segments).

std::vector<LocalMap::Candidate> LocalMap::pair_observations(const std::vector<ObservedSegment>& observations,
                                                             ScanReport& report) const {
  std::vector<Candidate> candidates;
  if (observations.empty()) return candidates;
  const local_map::RotatedPose x_LR_hat(x_LR());
  std::vector<local_map::RotatedPose> x_LE(observations.size());
  for (std::size_t i = 0; i < observations.size(); ++i) {
    x_LE[i] = local_map::RotatedPose(compose(x_LR_hat.x, observations[i].location));
  }

  // Most (observation, segment) combinations are far from compatible. The same
  // test is first evaluated in fixed-size form from the five entity blocks of P
  // (pairing_jacobians; S = H P Hᵀ + R with the spmap reference scale): when both
  // rows would certainly survive the careful inversion and d² is clearly above
  // the threshold, the pairing is rejected here, with the decision the full
  // spmap::individual_compatibility would take. Everything else goes through it.
  const auto P = map_.covariance();  // a view of P: no copy
  const Eigen::Index ro = map_.entity(robot_).offset;
  const Eigen::Matrix3d P_RR = P.block<3, 3>(ro, ro);
  const double tolerance = config_.careful_inverse_tolerance;
  for (const spmap::Entity& s : map_.entities()) {
    if (s.kind != EntityKind::kSegment) continue;
    const local_map::RotatedPose x_LS(s.location);
    const Eigen::Matrix2d P_SS = P.block<2, 2>(s.offset, s.offset);
    const Eigen::Matrix<double, 2, 3> P_SR = P.block<2, 3>(s.offset, ro);
    for (std::size_t i = 0; i < observations.size(); ++i) {
      ++report.pairings_tried;
      const local_map::PairingJacobians pj =
          local_map::pairing_jacobians(x_LS, x_LR_hat, observations[i].location, x_LE[i]);
      // Overlap of the extents (spmap::extent_overlap on E seen from S) first:
      // it is cheap and both tests must pass.
      const double half_s = 0.5 * s.length_m;
      const double half_e = 0.5 * std::abs(pj.cos_SE) * observations[i].length_m;
      const double overlap = std::min(half_s, pj.x_SE.x + half_e) - std::max(-half_s, pj.x_SE.x - half_e);
      if (overlap <= -config_.overlap_gap_tolerance_m) {
        ++report.pairings_rejected_overlap;
        continue;
      }
      const Eigen::Matrix2d R = pj.J_E * observations[i].covariance * pj.J_E.transpose();
      const Eigen::Matrix2d uncorrelated = pj.H_S * P_SS * pj.H_S.transpose() + pj.H_R * P_RR * pj.H_R.transpose() + R;
      const Eigen::Matrix2d cross = pj.H_S * P_SR * pj.H_R.transpose();
      const Eigen::Matrix2d S = uncorrelated + cross + cross.transpose();
      const double scale = std::max({std::abs(S(0, 0)), std::abs(S(1, 1)), uncorrelated.diagonal().maxCoeff()});
      const double first_pivot = std::max(S(0, 0), S(1, 1));
      const double second_pivot = first_pivot > 0.0 ? S.determinant() / first_pivot : 0.0;
      if (second_pivot > 1e3 * tolerance * scale &&
          pj.h.dot(S.inverse() * pj.h) > pairing_threshold_ * (1.0 + 1e-6)) {
        ++report.pairings_rejected_individual;
        continue;
      }
      // Individual compatibility, chi2(2) (paper eq. 8; docs/design.md §4.3).
      spmap::ImplicitMeasurement m = local_map::pairing_measurement(map_, s.id, robot_, observations[i]);
      const spmap::CompatibilityTest test = spmap::individual_compatibility(map_, m, careful_, pairing_chi2_);
      if (!test.passed) {
        ++report.pairings_rejected_individual;
        continue;
      }
      ++report.pairings_accepted_individual;
      candidates.push_back({{i, s.id, test.distance2}, std::move(m)});
    }
  }
  return candidates;
}

// ---------------------------------------------------------------------------
// Steps 4–5: incremental joint compatibility (best individual distance first),
// then one EKF update with all compatible pairings through the careful inversion.

std::vector<LocalMap::Pairing> LocalMap::joint_update(std::vector<Candidate> candidates, ScanReport& report) {
  std::vector<Pairing> pairings;
  if (candidates.empty()) return pairings;
  std::stable_sort(candidates.begin(), candidates.end(), [](const Candidate& a, const Candidate& b) {
    return a.pairing.distance2 < b.pairing.distance2;
  });
  std::vector<spmap::ImplicitMeasurement> measurements;
  measurements.reserve(candidates.size());
  for (Candidate& c : candidates) measurements.push_back(std::move(c.measurement));

  // One joint innovation of all candidates serves every visiting order.
  const spmap::StackedMeasurements stacked = spmap::stack(map_, measurements, "LocalMap::joint_update");
  const spmap::Innovation innovation = spmap::innovation(map_.lower_view(), stacked);
  std::vector<spmap::JointCompatibility::Rows> rows;
  rows.reserve(measurements.size());
  for (Eigen::Index first = 0; const spmap::ImplicitMeasurement& m : measurements) {
    rows.push_back({first, m.h.size()});
    first += m.h.size();
  }
  // The candidates of `order` visited in turn; those kept, in visiting order.
  const auto jointly_compatible = [&](const std::vector<std::size_t>& order) {
    spmap::JointCompatibility jc(innovation.S, innovation.row_scale, stacked.h, rows, careful_, joint_chi2_);
    std::vector<std::size_t> kept_in_order;
    for (const std::size_t k : order) {
      if (jc.try_add(k)) kept_in_order.push_back(k);
    }
    return kept_in_order;
  };
  std::vector<std::size_t> by_distance(candidates.size());
  std::iota(by_distance.begin(), by_distance.end(), std::size_t{0});
  std::vector<std::size_t> kept = jointly_compatible(by_distance);
  // The greedy visiting order lets one early spurious pairing (an accidental
  // match with a small distance) exclude the right set when the robot's
  // predicted pose is off. Restarts: the first rejected candidates, one at a
  // time, are visited first (then the rest by distance); the largest compatible
  // set wins, the first one found on ties.
  if (kept.size() < candidates.size() && config_.joint_compatibility_restarts > 0) {
    std::vector<bool> in_first(candidates.size(), false);
    for (std::size_t k : kept) in_first[k] = true;
    std::size_t restarts = 0;
    for (std::size_t seed = 0; seed < candidates.size() && restarts < config_.joint_compatibility_restarts;
         ++seed) {
      if (in_first[seed]) continue;
      ++restarts;
      std::vector<std::size_t> order = {seed};
      for (std::size_t k = 0; k < candidates.size(); ++k) {
        if (k != seed) order.push_back(k);
      }
      std::vector<std::size_t> kept_here = jointly_compatible(order);
      if (kept_here.size() <= kept.size()) continue;
      kept = std::move(kept_here);
    }
    report.joint_compatibility_restarts = static_cast<int>(restarts);
  }
  report.pairings_accepted_joint = static_cast<int>(kept.size());
  report.pairings_rejected_joint = static_cast<int>(candidates.size() - kept.size());
  if (kept.empty()) return pairings;

  std::vector<spmap::ImplicitMeasurement> compatible;
  compatible.reserve(kept.size());
  for (std::size_t k : kept) {
    compatible.push_back(std::move(measurements[k]));
    pairings.push_back(candidates[k].pairing);
  }
  // Eq. (9) with the reduced innovation (docs/design.md §6); folds p̂ into every location.
  const spmap::UpdateReport update = spmap::ekf_update(map_, compatible, careful_);
  report.update_rows = update.rows;
  report.update_rows_dropped = update.rows_dropped;
  return pairings;
}

// ---------------------------------------------------------------------------
// Step 6: geometric update. The EKF corrects only the lateral and angular
// errors; the end points come from projecting each paired observation on its
// (updated) map segment, moving the segment's frame with the dx rule (docs/design.md §3).

void LocalMap::geometric_update(const std::vector<ObservedSegment>& observations,
                                const std::vector<Pairing>& pairings, ScanReport& report) {
  std::set<EntityId> extended;
  for (const Pairing& p : pairings) {
    const ObservedSegment& e = observations[p.observation];
    const Pose2 x_SE = local_map::observation_in_segment(map_, p.segment, robot_, e);
    const spmap::Interval seen = spmap::project_extent(x_SE, e.length_m);
    const double half = 0.5 * map_.entity(p.segment).length_m;
    if (seen.min >= -half && seen.max <= half) continue;
    spmap::extend_segment(map_, p.segment, {std::min(seen.min, -half), std::max(seen.max, half)});
    extended.insert(p.segment);
  }
  report.segments_extended = static_cast<int>(extended.size());
}

// ---------------------------------------------------------------------------
// Step 7: map segments that matched one observation are one wall: fuse each
// into the oldest of them (ids grow with age).

void LocalMap::fuse_multiple_matches(const std::vector<Pairing>& pairings, ScanReport& report) {
  std::map<std::size_t, std::vector<EntityId>> by_observation;
  for (const Pairing& p : pairings) by_observation[p.observation].push_back(p.segment);

  std::unordered_map<EntityId, EntityId> fused_into;
  const auto resolve = [&fused_into](EntityId id) {
    for (auto it = fused_into.find(id); it != fused_into.end(); it = fused_into.find(id)) id = it->second;
    return id;
  };
  for (auto& [observation, segments] : by_observation) {
    if (segments.size() < 2) continue;
    std::vector<EntityId> live;
    for (EntityId s : segments) live.push_back(resolve(s));
    std::sort(live.begin(), live.end());
    live.erase(std::unique(live.begin(), live.end()), live.end());
    const EntityId keep = live.front();
    for (std::size_t k = 1; k < live.size(); ++k) {
      if (spmap::fuse_segments(map_, keep, live[k], config_.fusion_alpha)) {
        fused_into[live[k]] = keep;
        // The fusion's perfect constraint fixes their relative angle too.
        groups_.unite(keep, live[k]);
        ++report.segments_fused;
      } else {
        ++report.fusions_rejected;
      }
    }
  }
}

// ---------------------------------------------------------------------------
// Step 8: observations without any individually compatible pairing are new
// walls. Observations whose pairings were all rejected by the joint test are
// ambiguous (they fit the map somewhere, but not with the rest of the scan):
// they are dropped for this scan rather than duplicated as new segments.

std::vector<EntityId> LocalMap::add_unpaired(const std::vector<ObservedSegment>& observations,
                                             const std::vector<bool>& had_candidate,
                                             const std::vector<Pairing>& pairings, ScanReport& report) {
  std::vector<bool> paired(observations.size(), false);
  for (const Pairing& p : pairings) paired[p.observation] = true;
  std::vector<EntityId> added;
  for (std::size_t i = 0; i < observations.size(); ++i) {
    if (paired[i]) continue;
    if (had_candidate[i]) {
      ++report.observations_discarded;
      continue;
    }
    added.push_back(add_observation(observations[i]));
  }
  report.segments_added = static_cast<int>(added.size());
  return added;
}

EntityId LocalMap::add_observation(const ObservedSegment& observation) {
  const local_map::AdditionJacobians aj = local_map::addition_jacobians(x_LR(), observation.location);
  const EntityId id = map_.add(EntityKind::kSegment, aj.x_LS, std::nullopt, observation.length_m);
  // p_S = J_R p_R + J_E p_E (docs/design.md §4.8): the robot part carries the
  // correlations, the observation noise is independent of the state.
  map_.replace_perturbation(id, {{robot_, Eigen::MatrixXd(aj.J_R)}});
  const Eigen::Index off = map_.entity(id).offset;
  map_.mutable_covariance().block<2, 2>(off, off) += aj.J_E * observation.covariance * aj.J_E.transpose();
  groups_.find(id);  // a group of its own
  return id;
}

// ---------------------------------------------------------------------------
// Step 9: perfect angular constraints (paper §III.A; docs/design.md §4.9) between each
// new segment and the nearly parallel / perpendicular others, Mahalanobis-gated
// (chi2(1)), jointly checked, and applied in one update through the careful
// inversion (they make P singular).

void LocalMap::apply_constraints(const std::vector<EntityId>& added, ScanReport& report) {
  if (added.empty()) return;
  // One representative per group (the first member in state order): a segment's
  // angle relative to every member of a group is the same up to a known multiple
  // of pi/2, so one row per group carries all the information (the others would
  // be dropped by the careful inversion) and the gate gives the same distance.
  std::vector<EntityId> representatives;
  std::set<EntityId> groups_seen;
  for (const spmap::Entity& e : map_.entities()) {
    if (e.kind != EntityKind::kSegment) continue;
    if (groups_seen.insert(groups_.find(e.id)).second) representatives.push_back(e.id);
  }

  struct ConstraintCandidate {
    EntityId a;
    EntityId b;
    double distance2;
    spmap::ImplicitMeasurement measurement;
  };
  std::vector<ConstraintCandidate> candidates;
  for (EntityId n : added) {
    const double phi_n = map_.root_location(n).phi;
    // New segments are singleton groups appended in order, so "before n in state
    // order" visits the old groups and the earlier new segments: each pair once.
    for (EntityId r : representatives) {
      if (r >= n) break;
      if (groups_.find(r) == groups_.find(n)) continue;
      const double relative = wrap_angle(phi_n - map_.root_location(r).phi);
      const double target = local_map::nearest_right_angle(relative);
      if (std::abs(wrap_angle(relative - target)) > config_.constraint_max_angle_rad) continue;
      ++report.constraints_tried;
      spmap::ImplicitMeasurement m = local_map::angular_constraint(map_, r, n, target);
      const spmap::CompatibilityTest test = spmap::individual_compatibility(map_, m, careful_, constraint_chi2_);
      if (!test.passed) {
        ++report.constraints_rejected_individual;
        continue;
      }
      candidates.push_back({r, n, test.distance2, std::move(m)});
    }
  }
  if (candidates.empty()) return;

  std::stable_sort(candidates.begin(), candidates.end(), [](const ConstraintCandidate& x, const ConstraintCandidate& y) {
    return x.distance2 < y.distance2;
  });
  std::vector<spmap::ImplicitMeasurement> measurements;
  measurements.reserve(candidates.size());
  for (ConstraintCandidate& c : candidates) measurements.push_back(std::move(c.measurement));
  const std::vector<std::size_t> kept =
      spmap::incremental_joint_compatibility(map_, measurements, careful_, constraint_chi2_);
  report.constraints_rejected_joint = static_cast<int>(candidates.size() - kept.size());
  if (kept.empty()) return;

  std::vector<spmap::ImplicitMeasurement> applied;
  applied.reserve(kept.size());
  for (std::size_t k : kept) applied.push_back(std::move(measurements[k]));
  const spmap::UpdateReport update = spmap::ekf_update(map_, applied, careful_);
  report.constraints_applied = update.rows;
  report.constraint_rows_dropped = update.rows_dropped;
  for (std::size_t k : kept) groups_.unite(candidates[k].a, candidates[k].b);
}

spmap::CovarianceHealth LocalMap::check_covariance() const {
  return spmap::check_covariance(map_.covariance(), config_.covariance_tolerance);
}

// ---------------------------------------------------------------------------
// Step 10: ship policy.

bool LocalMap::should_ship() const {
  return span_m_ > config_.ship_distance_m || num_segments() > config_.max_segments;
}

LocalMapSnapshot LocalMap::snapshot() const {
  LocalMapSnapshot out;
  out.robot_id = robot_id_;
  out.seq = seq_;
  out.first_utime = first_utime_.value_or(last_utime_);
  out.last_utime = last_utime_;
  out.x_LR = x_LR();
  // Covariance of (p_R, p_S1, ..., p_Sk) with the robot first, whatever the state order.
  std::vector<Eigen::Index> rows;
  rows.reserve(static_cast<std::size_t>(map_.dimension()));
  const Eigen::Index robot_offset = map_.entity(robot_).offset;
  for (Eigen::Index k = 0; k < 3; ++k) rows.push_back(robot_offset + k);
  for (const spmap::Entity& e : map_.entities()) {
    if (e.kind != EntityKind::kSegment) continue;
    out.segments.push_back({e.location, e.length_m});
    rows.push_back(e.offset);
    rows.push_back(e.offset + 1);
  }
  const Eigen::Index n = static_cast<Eigen::Index>(rows.size());
  out.covariance.resize(n, n);
  const auto P = map_.covariance();  // a view of P: no copy
  for (std::size_t j = 0; j < rows.size(); ++j) {
    for (std::size_t i = 0; i < rows.size(); ++i) {
      out.covariance(static_cast<Eigen::Index>(i), static_cast<Eigen::Index>(j)) = P(rows[i], rows[j]);
    }
  }
  out.scan_poses = scan_poses_;
  return out;
}

void LocalMap::reset() {
  // Paper §II.C: the new local map starts at position 0 with covariance 0.
  const bool had_scans = first_utime_.has_value();
  map_.clear();
  robot_ = map_.add(EntityKind::kRobot, Pose2());
  groups_ = {};
  scan_poses_.clear();
  last_scan_skipped_.reset();
  motion_to_skipped_.reset();
  span_m_ = 0.0;
  ++seq_;
  first_utime_ = had_scans ? std::optional<int64_t>(last_utime_) : std::nullopt;
}

void LocalMap::resume(int64_t seq, int64_t origin_utime, const Pose2& origin_odometry) {
  if (seq < 0) throw std::invalid_argument("LocalMap::resume: seq must be >= 0, got " + std::to_string(seq));
  if (!finite(origin_odometry)) throw std::invalid_argument("LocalMap::resume: non-finite odometry pose");
  // What reset() leaves after that scan (paper §II.C: the new map starts at
  // position 0 with covariance 0) ...
  seq_ = seq - 1;
  reset();
  first_utime_ = origin_utime;
  last_utime_ = origin_utime;
  // ... with the odometry reference of that scan: update() predicts from it
  // (that scan's points are gone: no scan match for the first scan).
  front_end_.resume(origin_utime, origin_odometry);
}

}  // namespace lmf
