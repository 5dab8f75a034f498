// The robot's EKF local map (paper §II.B; docs/design.md §4): the robot R and the wall
// segments it has seen, all relative to the local frame L (the robot's pose when
// the map began), with their joint covariance.
//
// One call of update() runs the ten steps of docs/design.md §4 for one scan:
//   1 predict with odometry, (2 extraction: done by the caller or process_scan),
//   3 pair observations with map segments (individual chi2 + extent overlap),
//   4 incremental joint compatibility and one EKF update with all compatible
//     pairings, 5 through the careful inversion, 6 geometric update of the paired
//   segments' end points, 7 fusion of map segments that matched one observation,
//   8 addition of unpaired observations, 9 perfect angular constraints between
//   new segments and nearly parallel/perpendicular existing ones, and
//   10 the ship policy (should_ship / snapshot / reset).
//
// Choices beyond the bare steps (each documented where it is made):
//  * step 2: a per-view observation noise is added to the extraction's
//    covariance (LocalMapConfig::observation_*_noise);
//  * step 3: a fixed-size evaluation of the same individual test rejects the
//    clearly incompatible combinations before spmap::individual_compatibility;
//  * step 4: when the joint test rejects candidates it is rerun with a rejected
//    candidate first (LocalMapConfig::joint_compatibility_restarts) and the
//    largest compatible set is used;
//  * step 8: an observation whose individually compatible pairings were all
//    rejected by the joint test is dropped for this scan, not added;
//  * step 9: one representative per group of segments whose relative angles are
//    already perfectly known, and a joint test over the gated constraints.
//
// Units: metres, radians; time stamps in microseconds (from the data, never the
// wall clock). Not thread-safe; all methods are synchronous.
#pragma once

#include <cstdint>
#include <optional>
#include <unordered_map>
#include <vector>

#include <Eigen/Core>

#include "lmf/common/union_find.hpp"
#include "lmf/geometry/pose2.hpp"
#include "lmf/local_map/local_map_config.hpp"
#include "lmf/local_map/local_map_snapshot.hpp"
#include "lmf/front_end/front_end.hpp"
#include "lmf/front_end/odometry_model.hpp"
#include "lmf/scan/laser_scan.hpp"
#include "lmf/scan/observed_segment.hpp"
#include "lmf/spmap/covariance_check.hpp"
#include "lmf/spmap/ekf.hpp"
#include "lmf/spmap/estimator.hpp"
#include "lmf/spmap/stochastic_map.hpp"

namespace lmf {

// What one update() did, for status messages and tests (no timing: callers time it).
struct ScanReport {
  int64_t utime = 0;
  int observations = 0;           // observations given (after extraction)
  int observations_rejected = 0;  // skipped as malformed (non-finite, bad covariance, length <= 0)
  int map_segments_before = 0;

  // The front end's motion filter took the scan as no new view (process_scan
  // only; LocalMapConfig::motion_filter): the map is as it was, x_LR is the
  // scan's dead-reckoned pose, and nothing else below is filled.
  bool scan_skipped = false;

  // Step 1 (LocalMapConfig::scan_matching, process_scan only): whether the scan
  // was matched against the recent ones and the prediction used the match.
  bool scan_match_tried = false;
  bool scan_matched = false;
  // The search escalated to its wider window (escalating_registration.hpp) ...
  bool scan_match_escalated = false;
  // ... and the match is the wider window's.
  bool scan_match_from_escalation = false;
  int scan_match_points = 0;  // points matched (when scan_matched)
  // The matched motion from the previous scan, x_AB, and its covariance (when scan_matched).
  Pose2 scan_match_increment;
  Eigen::Matrix3d scan_match_covariance = Eigen::Matrix3d::Zero();
  // The match left out small foreground objects that moved (ScanMatch::objects_moving).
  bool scan_match_objects_moving = false;
  // Its robust weight in the odometry model learner (LocalMapConfig::odometry_learning;
  // 0 when not learned from; below 1/2: the odometry disagreed like a glitch).
  double odometry_learning_weight = 0.0;

  // Step 3: every (observation, map segment) combination is a tried pairing; the
  // overlap test runs first, then the individual chi2(2) test on those that overlap.
  int pairings_tried = 0;
  int pairings_rejected_overlap = 0;
  int pairings_rejected_individual = 0;
  int pairings_accepted_individual = 0;
  // Step 4: incremental joint compatibility over the individually accepted ones.
  int pairings_rejected_joint = 0;
  int pairings_accepted_joint = 0;
  int joint_compatibility_restarts = 0;  // extra JC runs with another first candidate
  // Step 5: rows of the stacked update and those the careful inversion dropped.
  int update_rows = 0;
  int update_rows_dropped = 0;

  int segments_extended = 0;       // step 6: paired map segments whose extent grew
  int segments_fused = 0;          // step 7: map segments removed by fusion into another
  int fusions_rejected = 0;        // step 7: fusion candidates whose constraint failed chi2(2)
  int segments_added = 0;          // step 8
  int observations_discarded = 0;  // step 8: all their pairings were rejected by JC: neither paired nor added

  // Step 9.
  int constraints_tried = 0;          // candidate pairs within constraint_max_angle_rad
  int constraints_rejected_individual = 0;
  int constraints_rejected_joint = 0;
  int constraints_applied = 0;        // rows given to the update
  int constraint_rows_dropped = 0;    // of those, dropped by the careful inversion (redundant)

  int segments_seen_through = 0;  // removed after the scan: most beams crossing them passed through (see_through)

  int map_segments = 0;  // after the scan
  Pose2 x_LR;            // robot pose estimate after the scan
  bool covariance_checked = false;  // covariance_health is filled (LocalMapConfig::covariance_check_interval)
  spmap::CovarianceHealth covariance_health;
  bool should_ship = false;
};

class LocalMap {
 public:
  // Throws std::invalid_argument if the config is invalid.
  explicit LocalMap(const LocalMapConfig& config = {}, int robot_id = 0);

  // One scan with already extracted observations (x_RE in the robot frame).
  // `odometry` is x_OR, the robot pose in the odometry frame read with the scan;
  // the first call only sets the odometry reference (no prediction). Malformed
  // observations are skipped and counted. Throws std::invalid_argument (state
  // unchanged) for a non-finite odometry pose.
  ScanReport update(int64_t utime, const Pose2& odometry, const std::vector<ObservedSegment>& observations);

  // The whole step for a scan: the front end (front_end.hpp) gives the motion
  // since the previous scan, segments are extracted with config().extraction,
  // and the filter predicts with that motion and updates. Throws
  // std::invalid_argument (state unchanged) for a non-finite odometry pose.
  ScanReport process_scan(const LaserScan& scan);
  // When the last scan was skipped by the motion filter (ScanReport::scan_skipped),
  // takes it now, as process_scan would a new view, so the map ends at it (a
  // map shipped before the robot moved on: the mission's end); nullopt, and
  // nothing done, otherwise.
  std::optional<ScanReport> take_skipped_scan();

  // Step 1 alone, with the odometry increment u = between(odom_prev, odom_now)
  // (m, rad) and the current odometry model (odometry_model(): the learned one,
  // or the configured prior): the increment corrected for its systematic error
  // and its covariance. update() calls it; public for tests and experiments.
  void predict(const Pose2& u);
  // The same with an increment known better than the odometry's (a scan match):
  // Q is the covariance of its perturbation p_u (u_true = u ⊕ p_u).
  void predict(const Pose2& u, const Eigen::Matrix3d& Q);

  // Step 10: true when span_m() > ship_distance_m or the map holds more than max_segments.
  bool should_ship() const;
  // Robot path length since the map began (m): the sum of the odometry step lengths.
  double span_m() const { return span_m_; }

  // The finished map: robot pose, segments in state order, covariance of
  // (p_R, p_S1, ..., p_Sk), scan poses.
  LocalMapSnapshot snapshot() const;
  // Starts a new local map at the robot's current pose: pose 0, covariance 0, no
  // segments, seq + 1, first_utime = the last scan's time. The odometry reference
  // is kept, so the next prediction uses the motion since the last scan.
  void reset();
  // Continues a chain of local maps in a new LocalMap (a robot agent restarted
  // from its persisted state): as if reset() had just started local map `seq`
  // after a scan at `origin_utime` with odometry reading `origin_odometry` (x_OR).
  // The next update() predicts with the motion since that reading (step 1), so
  // the robot starts that map NOT at the origin but at the odometric
  // displacement, with the odometry noise model's covariance for it: whatever
  // was observed in between is lost, the motion is bridged by odometry. Throws
  // std::invalid_argument (state unchanged) for seq < 0 or a non-finite pose.
  void resume(int64_t seq, int64_t origin_utime, const Pose2& origin_odometry);

  // Symmetry and positive semidefiniteness of P (LocalMapConfig::covariance_tolerance).
  spmap::CovarianceHealth check_covariance() const;

  // The odometry error model the prediction uses: learned from the scan matches
  // (LocalMapConfig::odometry_learning) since construction; kept across reset().
  const OdometryErrorModel& odometry_model() const { return front_end_.odometry_model(); }
  const OdometryLearningStats& odometry_learning_stats() const {
    return front_end_.motion_prior().odometry_learning_stats();
  }
  // The front end that gives process_scan its motion; it goes on across reset().
  const FrontEnd& front_end() const { return front_end_; }

  const LocalMapConfig& config() const { return config_; }
  int robot_id() const { return robot_id_; }
  int64_t seq() const { return seq_; }
  const spmap::StochasticMap& map() const { return map_; }
  spmap::EntityId robot() const { return robot_; }
  // The robot in the filter: at the last scan taken (process_scan's motion
  // filter leaves the filter there).
  Pose2 x_LR() const;
  Eigen::Matrix3d robot_covariance() const;
  // The robot at the last scan given: x_LR() after a scan taken; after a
  // skipped one, x_LR ⊕ u with u the motion since the last scan taken, and
  // the covariance the prediction with it would give (J_R P_RR J_Rᵀ + J_u Q
  // J_uᵀ). The agent's global pose reports it; acks and sightings report the
  // robot in the filter (docs/design.md §10, "The motion filter").
  Pose2 x_LR_at_last_scan() const;
  Eigen::Matrix3d robot_covariance_at_last_scan() const;
  std::size_t num_segments() const;
  std::vector<spmap::EntityId> segment_ids() const;  // state order

  // For tests and tools that build maps directly: adds a segment with the given
  // location in L, length and covariance of its perturbation (uncorrelated with
  // the rest). Throws std::invalid_argument for a bad length or covariance size.
  spmap::EntityId add_segment_for_test(const Pose2& x_LS, double length_m, const Eigen::Matrix2d& covariance);

 private:
  // An observation paired with a map segment (steps 3–7).
  struct Pairing {
    std::size_t observation = 0;
    spmap::EntityId segment = 0;
    double distance2 = 0.0;  // individual Mahalanobis distance (squared)
  };
  struct Candidate {
    Pairing pairing;
    spmap::ImplicitMeasurement measurement;
  };

  // process_scan; `take`: whatever the motion filter says.
  ScanReport process(const LaserScan& scan, bool take);
  // Steps 1-10 with the front end's motion (none for the first scan).
  ScanReport update_with(int64_t utime, const std::vector<ObservedSegment>& observations,
                         const std::optional<MotionIncrement>& motion, ScanReport report);

  std::vector<Candidate> pair_observations(const std::vector<ObservedSegment>& observations,
                                           ScanReport& report) const;
  std::vector<Pairing> joint_update(std::vector<Candidate> candidates, ScanReport& report);
  void geometric_update(const std::vector<ObservedSegment>& observations, const std::vector<Pairing>& pairings,
                        ScanReport& report);
  void fuse_multiple_matches(const std::vector<Pairing>& pairings, ScanReport& report);
  std::vector<spmap::EntityId> add_unpaired(const std::vector<ObservedSegment>& observations,
                                            const std::vector<bool>& had_candidate,
                                            const std::vector<Pairing>& pairings, ScanReport& report);
  void apply_constraints(const std::vector<spmap::EntityId>& added, ScanReport& report);
  int remove_seen_through(const LaserScan& scan);
  spmap::EntityId add_observation(const ObservedSegment& observation);

  LocalMapConfig config_;
  double pairing_threshold_ = 0.0;  // chi2inv(1 - pairing_alpha, 2)
  int robot_id_;
  int64_t seq_ = 0;
  spmap::StochasticMap map_;
  spmap::EntityId robot_ = 0;
  FrontEnd front_end_;
  // The estimator's settings (spmap/estimator.hpp): the careful inversion's
  // relative tolerance, and chi2 quantiles at each test's significance (caches).
  spmap::CarefulTolerance careful_;
  mutable spmap::Chi2Table pairing_chi2_;
  spmap::Chi2Table joint_chi2_;
  spmap::Chi2Table constraint_chi2_;
  std::optional<int64_t> first_utime_;
  int64_t last_utime_ = 0;
  double span_m_ = 0.0;
  std::size_t scans_ = 0;  // scans folded in since construction
  std::vector<ScanPose> scan_poses_;
  std::optional<LaserScan> last_scan_skipped_;  // the last scan, when the motion filter skipped it ...
  std::optional<MotionIncrement> motion_to_skipped_;  // ... and the motion to it from the last scan taken
  // Groups of segments whose relative angles are perfectly known (joined by
  // applied constraints or fusions): one member of a group stands for all in
  // step 9, because a constraint to another member would repeat the same row.
  UnionFind<spmap::EntityId> groups_;
};

}  // namespace lmf
