// The plane's part of a ROS pose, and a ROS pose for a planar one.
//
// A heading written as a quaternion and read back through atan2 does not
// always return the same double. `ros_pose` picks, among the quaternions
// within a few units in the last place of the exact one, one that
// `planar_pose` reads back to the very heading written, so a log converted to
// a bag maps exactly as the log does (docs/bags.md).
//
// Pure, thread-safe.
#pragma once

#include <Eigen/Geometry>

#include "lmf/bag/ros_messages.hpp"
#include "lmf/geometry/pose2.hpp"

namespace lmf::bag {

// The pose as a rigid transform (the quaternion normalised).
Eigen::Isometry3d isometry(const RosPose3& p);

// x, y and the heading of the rotated x axis.
Pose2 planar_pose(const Eigen::Isometry3d& T);
Pose2 planar_pose(const RosPose3& p);

// A rotation about z by x.phi at (x.x, x.y, 0), with planar_pose(ros_pose(x)) == x
// bit for bit wherever a quaternion within kHeadingSearchUlps of the exact one
// achieves it (all of 10⁵ random headings in the tests); otherwise the exact one.
RosPose3 ros_pose(const Pose2& x);
inline constexpr int kHeadingSearchUlps = 8;

}  // namespace lmf::bag
