// Uses an installed lmf: composes two Pose2 (lmf::geometry), builds a LocalMap
// from two scans' observations of one wall (lmf::local_map), and encodes a
// generated LCM message (lmf::lcmtypes). Prints what it got; exits non-zero on
// a wrong value.
#include <cmath>
#include <cstdio>
#include <vector>

#include "lmf/geometry/pose2.hpp"
#include "lmf/local_map/local_map.hpp"
#include "lmf/pose2_t.hpp"

int main() {
  const lmf::Pose2 a(1.0, 0.0, M_PI / 2.0);
  const lmf::Pose2 b(2.0, 0.0, 0.0);
  const lmf::Pose2 c = lmf::compose(a, b);  // 2 m along a's heading (+y)
  std::printf("compose: %.3f %.3f %.3f\n", c.x, c.y, c.phi);
  if (std::abs(c.x - 1.0) > 1e-12 || std::abs(c.y - 2.0) > 1e-12 || std::abs(c.phi - M_PI / 2.0) > 1e-12) return 1;

  // A wall 3 m ahead of the robot, seen from the start and after 0.1 m forward.
  lmf::LocalMap map;
  auto wall_seen_from = [](double robot_x) {
    lmf::ObservedSegment wall;
    wall.location = lmf::Pose2(3.0 - robot_x, 0.0, M_PI / 2.0);
    wall.length_m = 2.0;
    wall.covariance = Eigen::Vector2d(1e-4, 1e-4).asDiagonal();
    wall.first_point = Eigen::Vector2d(3.0 - robot_x, -1.0);
    wall.last_point = Eigen::Vector2d(3.0 - robot_x, 1.0);
    wall.num_points = 40;
    return std::vector<lmf::ObservedSegment>{wall};
  };
  map.update(0, lmf::Pose2(), wall_seen_from(0.0));
  map.update(100000, lmf::Pose2(0.1, 0.0, 0.0), wall_seen_from(0.1));
  std::printf("local map: %zu segments, robot x %.3f\n", map.num_segments(), map.x_LR().x);
  if (map.num_segments() != 1) return 1;

  lmf::pose2_t message;
  message.x = c.x;
  message.y = c.y;
  message.phi = c.phi;
  std::vector<char> buffer(static_cast<std::size_t>(message.getEncodedSize()));
  if (message.encode(buffer.data(), 0, static_cast<int>(buffer.size())) != static_cast<int>(buffer.size())) return 1;
  std::printf("pose2_t: %zu bytes\n", buffer.size());
  return 0;
}
