// Configuration of the robot local map (docs/design.md §4; paper §II.B), with units and
// documented defaults. validate() throws std::invalid_argument naming the field.
#pragma once

#include <cstddef>

#include "lmf/front_end/odometry_model.hpp"
#include "lmf/scan/scan_matcher.hpp"
#include "lmf/scan/see_through.hpp"
#include "lmf/scan/segment_extraction.hpp"

namespace lmf {

struct LocalMapConfig {
  // --- Step 1: odometry noise: the PRIOR of the learned odometry model
  // (odometry_learning below; with learning off, the model used). The increment u = between(odom_prev, odom_now)
  // has its perturbation p_u (in the frame of the new pose, u_true = û ⊕ p_u)
  // Gaussian with independent standard deviations proportional to the motion
  // of that step (paper §IV: 6–8 % error; datasets/README.md: 8 % of translation,
  // 8 % of rotation, 0.01 rad per metre):
  //   sigma_x = sigma_y = translation_ratio · d            (d = |(û.x, û.y)|, m)
  //   sigma_phi = rotation_ratio · |û.phi| + drift · d
  // each then combined in quadrature with a floor so a standing robot's
  // covariance stays well defined: sigma² ← sigma² + floor².
  double odom_translation_noise_ratio = 0.08;  // m of std per m travelled (>= 0)
  double odom_rotation_noise_ratio = 0.08;     // rad of std per rad turned (>= 0)
  double odom_drift_rad_per_m = 0.01;          // rad of heading std per m travelled (>= 0)
  double odom_noise_floor_m = 0.001;           // std added to x and y of every step (m, >= 0)
  double odom_noise_floor_rad = 0.0005;        // std added to the heading of every step (rad, >= 0)

  // --- Step 2: observation noise. The extraction's covariance of p_E models the
  // independent range noise of the points only; a real wall is not a perfect
  // line and each view fits it a little differently (partial views, clutter at
  // the ends), an error shared by all points of one view that the fit cannot
  // see. The filter adds it as independent noise per observation:
  // Cov(p_E) += diag(lateral², angular²). Without it the map grows overconfident
  // on real logs (robot NEES against the belgioioso reference ~50-200 instead of
  // ~3) and good pairings start failing the tests. Set both to 0 for data whose
  // walls are perfect lines (the simulator).
  double observation_lateral_noise_m = 0.03;    // std added to the lateral error (m, >= 0)
  double observation_angular_noise_rad = 0.02;  // std added to the angular error (rad, >= 0)
  // A stray point or a clipped end moves a segment's end sideways; the angle
  // error it causes shrinks with the length: angular std² += (end_noise / length)².
  double observation_end_noise_m = 0.0;  // (m, >= 0)

  // --- Step 3: pairing an observation E with a map segment S.
  // Individual Mahalanobis test: d² < chi2inv(1 - pairing_alpha, 2). Loose on
  // purpose: a large odometry heading error (turning on the spot) moves every
  // observation together, so each one alone looks unlikely while the joint test
  // (step 4) still tells right from wrong.
  double pairing_alpha = 0.001;
  // Overlap test: E's extent projected on S's axis must overlap S's extent or
  // leave a gap shorter than this (m). Larger than the laser's point spacing,
  // smaller than a door.
  double overlap_gap_tolerance_m = 0.3;

  // --- Step 4: incremental joint compatibility, chi2 at the joint dof.
  double joint_alpha = 0.01;
  // When the joint test rejects some candidates, rerun it up to this many times,
  // each time visiting one of the rejected candidates first; keep the largest
  // compatible set (0: one greedy pass in order of individual distance).
  std::size_t joint_compatibility_restarts = 3;

  // --- Step 5 (and every inversion of an innovation covariance): careful
  // inversion stops when the best pivot < tolerance · largest pivot (docs/design.md §6).
  double careful_inverse_tolerance = 1e-9;

  // --- Step 7: two map segments that matched the same observation are fused
  // when their perfect collinearity constraint passes chi2(2) at this alpha.
  double fusion_alpha = 0.01;

  // --- Step 9: perfect angular constraints between each new segment and the
  // existing ones that are nearly parallel (0, pi) or perpendicular (±pi/2).
  bool constraints_enabled = true;
  // A candidate's estimated angle must be within this of a multiple of pi/2 (rad)...
  double constraint_max_angle_rad = 0.2;
  // ... and pass the Mahalanobis test d² < chi2inv(1 - constraint_alpha, 1).
  double constraint_alpha = 0.01;

  // --- Step 10: ship policy. The local map's span is the robot's path length
  // since the map began (sum of the odometry step lengths, m): the quantity the
  // odometry error — and so the linearisation error — grows with.
  double ship_distance_m = 10.0;   // should_ship() when span > this (m, > 0)
  std::size_t max_segments = 100;  // ... or when the map holds more segments than this (> 0)

  // --- Covariance supervision: symmetric and PSD within this tolerance
  // (relative to max(1, max |P_ii|)), checked on the scan that makes the map
  // ship (always: no map leaves unchecked) and after every
  // `covariance_check_interval` scans in between (1: every scan; 0: only at the
  // ship and through LocalMap::check_covariance()). The check is a Cholesky of
  // P shifted by the tolerance (spmap::check_covariance), O(n³/3): with 170
  // segments it costs about four times the rest of the scan update
  // (lmf_bench_local_map). One scan in 10 bounds its amortised share to about
  // 0.4 update, and still finds a loss within 10 scans, well inside one local
  // map (ship_distance_m of travel is 10–20 scans at the 0.5–1 m scan spacing
  // of a mapping robot).
  double covariance_tolerance = 1e-9;
  std::size_t covariance_check_interval = 10;

  // Step 1 learned (beyond the paper; on by default): the agent estimates its
  // own odometry error model (systematic scales and heading bias, noise per step,
  // per metre and per radian) from the disagreement between the odometry and the
  // scan matches, starting from the prior above, and predicts with it
  // (odometry_model.hpp).
  OdometryLearningConfig odometry_learning;

  // Segment extraction used by LocalMap::process_scan (step 2).
  ExtractionConfig extraction;

  // Step 1 refined (beyond the paper; on by default): LocalMap::process_scan
  // matches each scan against the previous one with the odometry increment as
  // prior (scan_matcher.hpp) and predicts with the match and its covariance;
  // when the match fails it predicts with the odometry as usual.
  ScanMatcherConfig scan_matching;

  // What the scans carry, not a tuning: false for scans without odometry (a
  // recording of a laser alone; lmf-offline --bag --no-odometry). Each increment
  // is then predicted at constant velocity with a covariance as wide as the
  // scan matcher's window (constant_velocity_prior.hpp), the scan match carries
  // the motion, and there is no odometry model to learn. Needs scan_matching.
  bool scans_have_odometry = true;

  // The motion filter (beyond the paper; on by default; front_end/motion_filter.hpp):
  // LocalMap::process_scan takes a scan with odometry only once the robot moved
  // a keyframe (scan_matching.keyframe_distance_m or keyframe_angle_rad) from
  // the last scan taken; the scans between get dead-reckoned poses.
  bool motion_filter = true;

  // Free-space evidence (beyond the paper; on by default): after each scan,
  // LocalMap::process_scan removes the map segments that most beams crossing
  // them pass through (see_through.hpp): other robots, people, false extractions.
  SeeThroughConfig see_through;

  // Throws std::invalid_argument naming the first invalid field and its value.
  void validate() const;
};

}  // namespace lmf
