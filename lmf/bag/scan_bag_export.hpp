// A robot's scans written as a bag (lmf-convert), the inverse of
// read_bag_scans: /scan (sensor_msgs/LaserScan in frame "laser"), the base's
// odometry at each scan's time (/odom nav_msgs/Odometry "odom" → "base_link",
// or the same as /tf), and the laser's mounting on /tf_static. Stamps and log
// times are the scans' times. A ROS 1 bag (through librosbag-storage, ROS 1
// serialisation) or an MCAP file (ROS 2 profile, CDR).
//
// Synchronous.
#pragma once

#include <filesystem>
#include <optional>
#include <string>
#include <utility>
#include <vector>

#include "lmf/bag/bag_file.hpp"
#include "lmf/geometry/pose2.hpp"
#include "lmf/scan/laser_scan.hpp"

namespace lmf::bag {

struct ScanBagExportOptions {
  BagFormat format = BagFormat::ros1;  // ros1 or mcap
  std::string compression = "none";    // ros1: none, bz2, lz4; mcap: none, zstd
  bool odometry_as_tf = false;         // /tf instead of /odom
};

// One robot's recording. `scans` carry the laser's odometry pose; `x_BL`, the
// laser on the base (identity when unset), gives the base's: x_OB = x_OL ⊕ ⊖x_BL.
// With a namespace ("/robot1") its topics are under it (/robot1/scan,
// /robot1/odom) and its frames prefixed ("robot1/odom", "robot1/base_link",
// "robot1/laser", on the bag's /tf and /tf_static), as multi-robot setups name
// them.
struct RobotScans {
  std::string robot_namespace;
  std::vector<LaserScan> scans;
  std::optional<Pose2> x_BL;
};

// Throws std::invalid_argument for a format or compression it cannot write and
// BagFormatError when the file cannot be written.
void write_scan_bag(const std::filesystem::path& file, const std::vector<RobotScans>& robots,
                    const ScanBagExportOptions& options = {});
// One robot, no namespace.
void write_scan_bag(const std::filesystem::path& file, const std::vector<LaserScan>& scans,
                    const std::optional<Pose2>& x_BL, const ScanBagExportOptions& options = {});

}  // namespace lmf::bag
