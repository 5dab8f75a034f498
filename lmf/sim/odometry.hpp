// Simulated wheel odometry: true motion increments plus noise proportional to the motion.
//
// Between consecutive scans the true increment is u = between(x_WR(k-1), x_WR(k)) =
// (dx, dy, dphi) in the robot frame at k-1, with d = |(dx, dy)|. The odometry reports
//   u_odo = (dx + n_x, dy + n_y, dphi + n_phi),
//   n_x, n_y ~ N(0, (translation_fraction * d)^2),
//   n_phi   ~ N(0, (rotation_fraction * |dphi| + heading_drift_rad_per_m * d)^2),
// all independent, independent between increments (datasets/README.md: 8 %, 8 %, 0.01 rad/m;
// the paper: odometry error proportional to the motion, 6-8 %). The odometry pose is
// x_OR(k) = x_OR(k-1) ⊕ u_odo(k), starting at the true start pose. A filter predicting with the
// same increments should use exactly this covariance (DESIGN §4 step 1).
#pragma once

#include <Eigen/Core>

#include "lmf/geometry/pose2.hpp"
#include "lmf/sim/random.hpp"

namespace lmf::sim {

struct OdometryNoiseConfig {
  double translation_fraction = 0.08;     // standard deviation per metre of translation, in [0, 1]
  double rotation_fraction = 0.08;        // standard deviation per radian of rotation, in [0, 1]
  double heading_drift_rad_per_m = 0.01;  // extra heading standard deviation per metre, in [0, 1]
  // Throws std::invalid_argument when out of range.
  void validate() const;
};

// The covariance of the increment noise for a true increment u (diagonal, see above).
Eigen::Matrix3d odometry_noise_covariance(const Pose2& u, const OdometryNoiseConfig& config);

// The increment as the odometry reports it (3 normals are drawn from rng, always).
Pose2 noisy_increment(const Pose2& u, const OdometryNoiseConfig& config, Rng& rng);

}  // namespace lmf::sim
