// The ROS messages lmf maps from, decoded from either encoding (wire_decoder.hpp).
// Field layouts follow the message definitions (sensor_msgs/LaserScan,
// nav_msgs/Odometry, geometry_msgs/TransformStamped in tf/tfMessage and
// tf2_msgs/TFMessage); ROS 1's std_msgs/Header has a uint32 seq that ROS 2's
// lacks. Only the fields lmf uses are kept; the rest are read past.
//
// Pure, thread-safe.
#pragma once

#include <cstdint>
#include <span>
#include <string>
#include <vector>

#include <Eigen/Core>
#include <Eigen/Geometry>

#include "lmf/bag/wire_decoder.hpp"

namespace lmf::bag {

struct RosHeader {
  std::int64_t stamp_ns = 0;
  std::string frame_id;
};

struct RosLaserScan {
  RosHeader header;
  float angle_min = 0, angle_max = 0, angle_increment = 0;
  float range_min = 0, range_max = 0;
  std::vector<float> ranges;
};

struct RosPose3 {
  Eigen::Vector3d translation = Eigen::Vector3d::Zero();
  Eigen::Quaterniond rotation = Eigen::Quaterniond::Identity();
};

struct RosOdometry {
  RosHeader header;          // frame_id: the odometry frame
  std::string child_frame_id;  // the robot's base frame
  RosPose3 pose;             // the base in the odometry frame
};

struct RosTransform {
  RosHeader header;            // frame_id: the parent
  std::string child_frame_id;  // the child
  RosPose3 transform;          // the child in the parent's frame
};

// The types each decoder accepts, as bags name them.
bool is_laser_scan_type(const std::string& type);  // sensor_msgs/LaserScan, sensor_msgs/msg/LaserScan
bool is_odometry_type(const std::string& type);    // nav_msgs/Odometry, nav_msgs/msg/Odometry
bool is_tf_type(const std::string& type);          // tf/tfMessage, tf2_msgs/TFMessage, tf2_msgs/msg/TFMessage

// Throw WireDecodeError on a short or malformed message.
RosLaserScan decode_laser_scan(std::span<const std::uint8_t> bytes, MessageEncoding encoding);
RosOdometry decode_odometry(std::span<const std::uint8_t> bytes, MessageEncoding encoding);
std::vector<RosTransform> decode_tf_message(std::span<const std::uint8_t> bytes, MessageEncoding encoding);

}  // namespace lmf::bag
