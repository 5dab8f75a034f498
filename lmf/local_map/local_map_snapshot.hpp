// What a robot ships to the fusion server: a finished local map (paper eq. 2).
#pragma once

#include <cstdint>
#include <vector>

#include <Eigen/Core>

#include "lmf/geometry/pose2.hpp"

namespace lmf {

struct SegmentEstimate {
  Pose2 location;       // x_LS: segment frame (midpoint, x along it) in the local frame L
  double length_m = 0.0;
};

struct ScanPose {
  int64_t utime = 0;
  Pose2 x_LR;           // the robot pose estimate for that scan, in L
};

struct LocalMapSnapshot {
  int robot_id = 0;
  int64_t seq = 0;                // local map number of this robot, from 0
  int64_t first_utime = 0;        // time L was set (robot pose then = L)
  int64_t last_utime = 0;         // time of the last scan folded in
  Pose2 x_LR;                     // final robot pose in L
  std::vector<SegmentEstimate> segments;
  // Covariance of (p_R, p_S1, ..., p_Sk): 3 + 2k square, symmetric PSD.
  Eigen::MatrixXd covariance;
  // Pose of every scan folded into this map (filtered estimate at that scan);
  // kept by the agent for trajectories, not needed by the fusion.
  std::vector<ScanPose> scan_poses;
};

}  // namespace lmf
