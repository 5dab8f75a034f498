// The front end's stage 0 (docs/design.md §10, "The motion filter"): whether
// a scan is a new view.
//
// Consecutive scans of a fast laser see the same walls from nearly the same
// place, so their errors (the registration's against the same reference, each
// wall's model error per view) are nearly the same, and the EKF would count
// each as independent: at 10-20 scans per second the local map's covariance
// becomes several times too small. A scan is taken only once the motion since
// the last scan taken, as the motion prior predicts it, reaches the local
// submap's keyframe spacing (ScanMatcherConfig::keyframe_distance_m,
// keyframe_angle_rad: the spacing at which the submap takes a scan as a new
// view of its reference), to the nearest scan: a scan is taken when the next
// one, a step further at the same pace, would overshoot the keyframe by more
// than this one falls short of it (d + step / 2 >= keyframe, in distance or in
// angle). So a laser whose step is near the keyframe has every scan taken,
// not every other one. The scans between are dead-reckoned from the last one
// taken; the next one taken spans them. Odometry that stalls while the robot
// moves (a robot pushed) has every scan skipped until it moves again
// (docs/design.md §10, "The motion filter").
#pragma once

#include <cmath>

#include "lmf/geometry/pose2.hpp"
#include "lmf/scan/scan_matcher.hpp"

namespace lmf {

// Whether this scan is taken: `motion_since_taken` is x_{t,k}, from the last
// scan taken to this one, and `step` x_{k-1,k}, from the previous scan.
inline bool is_taken(const Pose2& motion_since_taken, const Pose2& step, const ScanMatcherConfig& config) {
  const double distance = std::hypot(motion_since_taken.x, motion_since_taken.y) + 0.5 * std::hypot(step.x, step.y);
  const double angle = std::abs(motion_since_taken.phi) + 0.5 * std::abs(step.phi);
  return distance >= config.keyframe_distance_m || angle >= config.keyframe_angle_rad;
}

}  // namespace lmf
