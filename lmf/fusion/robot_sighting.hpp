// What a robot-robot sighting tells the fusion (light: the agents, the player
// and the wire conversions in runtime/ use it without the fusion core).
#pragma once

#include <cstdint>

#include <Eigen/Core>

#include "lmf/geometry/pose2.hpp"

namespace lmf::fusion {

// A robot-robot sighting (paper §IV, docs/design.md §5): observer A sees robot B.
// The sighting carries what the server cannot know by itself: where each robot
// was in its own local map at that moment. Its agent knows it (the current
// filtered pose and its marginal covariance); a player emulating robots from
// logs can take it from LocalMapSnapshot::scan_poses with zero covariance.
// The correlation of x_LA / x_LB with the rest of their local maps is not
// carried and therefore neglected (exact when B's pose is its local frame, i.e.
// x_LB = 0 with zero covariance).
struct RobotSighting {
  std::int64_t utime = 0;     // us, when A saw B
  int observer_id = 0;        // A (must have joined, or join later)
  int observed_id = 0;        // B
  std::int64_t observer_seq = 0;  // A's local map in progress at utime
  Pose2 x_LA;                     // A's pose in that local map
  Eigen::Matrix3d cov_LA = Eigen::Matrix3d::Zero();  // covariance of its perturbation
  Pose2 x_AB;                     // the measurement: B in A's robot frame
  Eigen::Matrix3d cov_AB = Eigen::Matrix3d::Zero();
  std::int64_t observed_seq = 0;  // B's local map in progress at utime
  Pose2 x_LB;                     // B's pose in that local map
  Eigen::Matrix3d cov_LB = Eigen::Matrix3d::Zero();
};

}  // namespace lmf::fusion
