// Plain values carried by the LCM messages that have no home in the core yet
// (no LCM inside: the core may take these by value). Frames and units as in
// docs/design.md §3: x_AB is frame B seen from frame A, metres and radians.
#pragma once

#include <cstdint>
#include <vector>

#include <Eigen/Core>

#include "lmf/geometry/pose2.hpp"
#include "lmf/scan/laser_scan.hpp"

namespace lmf::runtime {

// A scan as it travels: the core LaserScan plus who took it and its number.
struct RobotScan {
  int robot_id = 0;
  std::int64_t seq = 0;  // scan number of this robot, from 0, consecutive
  LaserScan scan;
};

// "Agent robot_id has processed scan seq" (lockstep replay), with the agent's
// state after that scan (and after shipping, if the scan made the map ship):
// what a sighting at that time needs from this robot (docs/design.md §5, joining).
struct ScanAck {
  std::int64_t utime = 0;
  int robot_id = 0;
  std::int64_t seq = 0;
  std::int64_t local_map_seq = 0;  // the local map in progress after the scan
  Pose2 x_LR;                      // the robot in that local map
  Eigen::Matrix3d covariance = Eigen::Matrix3d::Zero();  // Cov(p_R), symmetric PSD
};

// The replay is over: the listed robots' agents ship what they hold.
struct MissionEnd {
  std::int64_t utime = 0;
  std::vector<int> robot_ids;  // distinct, >= 0
};

// The server's answer to local map (robot_id, seq).
struct LocalMapAck {
  enum class Status : std::int8_t { kFused = 0, kDuplicate = 1, kQueued = 2, kReceived = 3 };  // = local_map_ack_t constants
  std::int64_t utime = 0;
  int robot_id = 0;
  std::int64_t seq = 0;
  Status status = Status::kFused;
};

// The server's answer to the sighting (utime, observer_id, observed_id).
struct SightingAck {
  enum class Status : std::int8_t { kApplied = 0, kDuplicate = 1, kRejected = 2, kReceived = 3 };  // = sighting_ack_t constants
  std::int64_t utime = 0;
  int observer_id = 0;
  int observed_id = 0;
  Status status = Status::kApplied;
};

// The corrected local-map frame L_r of one joined robot (docs/design.md §5 step 6).
struct CorrectedFrame {
  int robot_id = 0;
  std::int64_t last_applied_seq = -1;  // last local map fused for this robot, -1 if none
  Pose2 x_WL;                          // where robot r's current local map starts, in W
  Eigen::Matrix3d covariance = Eigen::Matrix3d::Zero();  // Cov(p_L), symmetric PSD
};

struct CorrectedFrames {
  std::int64_t utime = 0;
  std::int64_t fusion_count = 0;  // fusions applied so far
  std::vector<CorrectedFrame> frames;  // distinct robot ids
};

// Robot B (observed_id) seen from robot A (observer_id) at utime: lets B join
// (docs/design.md §5). Besides the measurement x_AB it carries where each robot was in
// its own local map at that moment, which the server cannot know by itself.
// Mirrors lmf::fusion::RobotSighting field by field.
struct Sighting {
  std::int64_t utime = 0;
  int observer_id = 0;
  int observed_id = 0;
  Pose2 x_AB;  // observed robot B in the observer's robot frame A
  Eigen::Matrix3d covariance = Eigen::Matrix3d::Zero();  // Cov of x_AB, symmetric PSD
  std::int64_t observer_seq = 0;  // A's local map in progress at utime
  Pose2 x_LA;                     // A's pose in that local map
  Eigen::Matrix3d cov_LA = Eigen::Matrix3d::Zero();
  std::int64_t observed_seq = 0;  // B's local map in progress at utime
  Pose2 x_LB;                     // B's pose in that local map
  Eigen::Matrix3d cov_LB = Eigen::Matrix3d::Zero();
};

}  // namespace lmf::runtime
