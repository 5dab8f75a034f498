// Serialising the ROS messages lmf writes (ros_messages.hpp), in either
// encoding (wire_decoder.hpp describes both): the inverse of decode_*, used by
// lmf-convert and by the readers' tests.
//
// Pure, thread-safe.
#pragma once

#include <cstdint>
#include <vector>

#include "lmf/bag/ros_messages.hpp"
#include "lmf/bag/wire_decoder.hpp"

namespace lmf::bag {

std::vector<std::uint8_t> encode_laser_scan(const RosLaserScan& scan, MessageEncoding encoding);
std::vector<std::uint8_t> encode_odometry(const RosOdometry& odometry, MessageEncoding encoding);
std::vector<std::uint8_t> encode_tf_message(const std::vector<RosTransform>& transforms, MessageEncoding encoding);

}  // namespace lmf::bag
