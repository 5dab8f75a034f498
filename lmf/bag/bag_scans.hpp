// A robot's laser scans from a ROS bag, in the same form CARMEN logs give
// (LaserScan with its odometry pose x_OR, lmf's robot frame being the laser's),
// docs/bags.md:
//   * scans: a sensor_msgs/LaserScan topic, any angular range and direction
//     (a clockwise scan is reversed into lmf's counter-clockwise order; a laser
//     mounted upside down is mirrored); NaN, inf and readings outside
//     [range_min, range_max] are "no return" (counted), never an error. A scan
//     whose geometry is unusable (fewer than 2 beams, a zero or non-finite
//     angle_increment, a non-positive range_max) is rejected and counted.
//   * time: the header's stamp (the log time when the stamp is 0).
//   * odometry: the base's pose at each scan's stamp, interpolated between the
//     two odometry poses around it (linearly in x, y and along the shorter arc
//     in heading), from a nav_msgs/Odometry topic or from /tf
//     (odom_frame → base_frame). A scan outside the odometry's time span is
//     dropped (counted).
//   * the laser's mounting x_BL (base → the scan's frame_id) from /tf_static,
//     a chain of static transforms in either direction, projected to the plane;
//     or given. Each scan's odometry pose is then x_OB ⊕ x_BL.
// Without odometry (no_odometry), each scan's odometry pose is the identity and
// the scans say so (LaserScan carries no flag: the caller configures the local
// map for it).
//
// Pure, synchronous.
#pragma once

#include <cstddef>
#include <filesystem>
#include <optional>
#include <string>
#include <vector>

#include "lmf/geometry/pose2.hpp"
#include "lmf/scan/laser_scan.hpp"

namespace lmf::bag {

struct BagScanOptions {
  // A robot of several in one bag: its topics are those under this namespace
  // ("/robot1": /robot1/scan, /robot1/odom, ...; the topics below are then
  // relative to it), its /tf and /tf_static its own where it has them, else the
  // bag's, and its odometry frame "odom" or "robot1/odom". Empty: the whole bag.
  std::string robot_namespace;
  // Empty: the bag's only LaserScan topic (an error when there are several or none).
  std::string scan_topic;
  // The odometry: a nav_msgs/Odometry topic, or /tf from odom_frame to
  // base_frame. All empty: the bag's only Odometry topic, else /tf from "odom"
  // to its only child there.
  std::string odom_topic;
  std::string odom_frame;
  std::string base_frame;
  bool no_odometry = false;
  // The laser's mounting on the base (x_BL); unset: from /tf_static.
  std::optional<Pose2> laser_mounting;
};

struct BagScans {
  std::vector<LaserScan> scans;     // by stamp
  std::vector<std::string> notes;   // what was read from where, and what was not used
  std::size_t no_return_readings = 0;
  std::size_t rejected_scans = 0;   // unusable geometry
  std::size_t scans_outside_odometry = 0;
};

// Throws BagFormatError (bag_file.hpp) for a damaged bag or a message that does
// not decode (naming the topic and its index), and std::invalid_argument when
// the options name what the bag does not have (listing what it has).
BagScans read_bag_scans(const std::filesystem::path& file, const BagScanOptions& options = {});

}  // namespace lmf::bag
