// A robot's scans written as a ROS 1 bag (lmf-convert), the inverse of
// read_bag_scans: /scan (sensor_msgs/LaserScan in frame "laser"), the base's
// odometry at each scan's time (/odom nav_msgs/Odometry "odom" → "base_link",
// or the same as /tf), and the laser's mounting on /tf_static. Stamps and log
// times are the scans' times.
//
// Synchronous.
#pragma once

#include <filesystem>
#include <optional>
#include <vector>

#include "lmf/bag/ros1_bag_writer.hpp"
#include "lmf/geometry/pose2.hpp"
#include "lmf/scan/laser_scan.hpp"

namespace lmf::bag {

struct ScanBagExportOptions {
  Ros1BagWriter::Compression compression = Ros1BagWriter::Compression::none;
  bool odometry_as_tf = false;  // /tf instead of /odom
};

// `scans` carry the laser's odometry pose; `x_BL`, the laser on the base
// (identity when unset), gives the base's: x_OB = x_OL ⊕ ⊖x_BL. Throws
// BagFormatError when the file cannot be written.
void write_ros1_scan_bag(const std::filesystem::path& file, const std::vector<LaserScan>& scans,
                         const std::optional<Pose2>& x_BL, const ScanBagExportOptions& options = {});

}  // namespace lmf::bag
