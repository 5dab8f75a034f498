// Plain values carried by the LCM messages that have no home in the core yet
// (no LCM inside: the core may take these by value). Those with a home there
// travel as the core's own types: LocalMapSnapshot, fusion::CorrectedFrame,
// fusion::RobotSighting. Frames and units as in
// docs/design.md §3: x_AB is frame B seen from frame A, metres and radians.
#pragma once

#include <array>
#include <cstdint>
#include <string>
#include <utility>
#include <vector>

#include <Eigen/Core>

#include "lmf/fusion/corrected_frame.hpp"
#include "lmf/fusion/robot_sighting.hpp"
#include "lmf/geometry/pose2.hpp"
#include "lmf/front_end/odometry_model.hpp"
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

struct CorrectedFrames {
  std::int64_t utime = 0;
  std::int64_t fusion_count = 0;  // fusions applied so far
  std::vector<fusion::CorrectedFrame> frames;  // distinct robot ids
};

// Incoming messages refused, by reason name (runtime/rejection.hpp), as the
// status messages carry them: each count > 0 where a process sends them.
using RejectCounts = std::vector<std::pair<std::string, std::int64_t>>;

// The odometry error model an agent predicts with, and how much it has learned
// from (lmf/front_end/odometry_model.hpp; the prior until the first increment).
struct OdometryModelReport {
  OdometryErrorModel model;
  std::int64_t increments_learned = 0;
  std::int64_t increments_downweighted = 0;  // of those, taken as glitches
};

// One agent's periodic status (agent -> monitors and the player). Scan times
// are order statistics over the window since the previous status.
struct AgentStatus {
  std::int64_t utime = 0;  // wall clock of the agent
  int robot_id = 0;
  bool joined = false;  // the agent has received its corrected frame
  std::int64_t scans = 0;  // scans processed
  int local_map_segments = 0;
  std::int64_t maps_shipped = 0;
  std::int64_t maps_acknowledged = 0;
  double scan_time_p50_ms = 0.0;
  double scan_time_p99_ms = 0.0;
  double scan_time_max_ms = 0.0;
  int window_scans = 0;
  bool covariance_ok = true;  // symmetric and PSD within tolerance over the window
  Pose2 x_WR;                 // best global estimate of the robot (identity while not joined)
  OdometryModelReport odometry;
  bool mission_done = false;  // mission end received and every local map acknowledged
  RejectCounts rejects;
};

// The server's periodic status (server -> monitors).
struct ServerStatus {
  std::int64_t utime = 0;  // wall clock of the server
  int robots_joined = 0;
  int segments = 0;
  int submaps = 0;
  int graph_edges = 0;
  std::int64_t fusions = 0;
  double last_fusion_ms = 0.0;
  double mean_fusion_ms = 0.0;
  int queue_length = 0;  // local maps received and not yet fused
  bool covariance_ok = true;  // the last fusion's health check of P
  double min_eigenvalue = 0.0;  // smallest eigenvalue (or LDLT pivot) of P; 0 before the first fusion
  RejectCounts rejects;
};

// What monitors draw of the global map (server -> anyone): its segments' end points.
struct GlobalMapSummary {
  std::int64_t utime = 0;  // newest local map fused (data time)
  std::int64_t fusion_count = 0;
  int submaps = 0;
  int graph_edges = 0;
  std::vector<std::array<double, 4>> endpoints;  // x1 y1 x2 y2 in W, m
};

}  // namespace lmf::runtime
