// The motion prior of scans that come without odometry
// (LocalMapConfig::scans_have_odometry false; a bag mapped with --no-odometry):
// the robot is predicted to go on as it went, û = v Δt with v the last
// increment per second (KISS-ICP's constant-velocity model), and the prior's
// covariance is as wide as the scan matcher's search window, σ = window / 3 in
// x, y and heading: the window is sized to hold what the motion can do between
// two scans (ScanMatcherConfig), so the prior claims nothing more. The scan
// match then carries the motion; where it fails, the prediction and this
// covariance are the increment.
//
// Pure and deterministic; not thread-safe.
#pragma once

#include <cstdint>

#include <Eigen/Core>

#include "lmf/geometry/pose2.hpp"
#include "lmf/scan/scan_matcher.hpp"

namespace lmf {

class ConstantVelocityPrior {
 public:
  explicit ConstantVelocityPrior(const ScanMatcherConfig& matching);

  // The increment expected over dt_us (µs) from the last one observed (none: zero motion).
  Pose2 predict(int64_t dt_us) const;
  const Eigen::Matrix3d& covariance() const { return covariance_; }
  // The increment u that took dt_us (the match, or the prediction where it failed).
  void observe(const Pose2& u, int64_t dt_us);

 private:
  Eigen::Matrix3d covariance_;
  Eigen::Vector3d velocity_ = Eigen::Vector3d::Zero();  // (x, y, φ) per second
};

}  // namespace lmf
