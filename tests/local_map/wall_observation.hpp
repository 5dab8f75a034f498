// Constructed observations for the local map tests: a wall given by its end
// points in L, seen from a robot pose x_LR, as an ObservedSegment with the scan
// module's conventions (midpoint frame, sensor on the left).
#pragma once

#include <cmath>

#include <Eigen/Core>

#include "lmf/geometry/pose2.hpp"
#include "lmf/scan/observed_segment.hpp"

namespace lmf::testing {

inline ObservedSegment observe_wall(const Pose2& x_LR, const Eigen::Vector2d& a_L, const Eigen::Vector2d& b_L,
                                    double sigma_lateral_m = 0.01, double sigma_angle_rad = 0.005) {
  const Pose2 x_RL = inverse(x_LR);
  Eigen::Vector2d a = x_RL.transform_point(a_L);
  Eigen::Vector2d b = x_RL.transform_point(b_L);
  const Eigen::Vector2d mid = 0.5 * (a + b);
  Eigen::Vector2d d = (b - a).normalized();
  const Eigen::Vector2d left(-d.y(), d.x());
  // The sensor (origin of R) must be on the segment's left (+y).
  if (left.dot(-mid) < 0.0) {
    d = -d;
    std::swap(a, b);
  }
  ObservedSegment e;
  e.location = Pose2(mid.x(), mid.y(), std::atan2(d.y(), d.x()));
  e.length_m = (b - a).norm();
  e.covariance << sigma_lateral_m * sigma_lateral_m, 0.0, 0.0, sigma_angle_rad * sigma_angle_rad;
  e.first_point = a;
  e.last_point = b;
  e.num_points = 50;
  return e;
}

// The same observation with its frame perturbed by (0, dy, dphi): a noisy fit.
inline ObservedSegment perturbed(ObservedSegment e, double dy_m, double dphi_rad) {
  e.location = compose(e.location, Pose2(0.0, dy_m, dphi_rad));
  return e;
}

}  // namespace lmf::testing
