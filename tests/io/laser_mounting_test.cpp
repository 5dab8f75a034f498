#include "lmf/io/laser_mounting.hpp"

#include <cmath>
#include <cstdio>
#include <string>
#include <vector>

#include <gtest/gtest.h>

#include "lmf/io/carmen.hpp"

namespace lmf::io {
namespace {

// A robot driving a curve, its odometry poses x_OR.
std::vector<Pose2> robot_path(std::size_t n) {
  std::vector<Pose2> out;
  Pose2 x(1.0, -2.0, 0.3);
  for (std::size_t i = 0; i < n; ++i) {
    out.push_back(x);
    x = compose(x, Pose2(0.4, 0.0, 0.1 * std::sin(0.2 * static_cast<double>(i))));
  }
  return out;
}

std::vector<Pose2> laser_path(const std::vector<Pose2>& robot, const Pose2& x_RS) {
  std::vector<Pose2> out;
  for (const Pose2& x_OR : robot) out.push_back(compose(x_OR, x_RS));
  return out;
}

// A FLASER line with 3 beams, laser pose and odometry pose written at 3 decimals
// as many loggers do.
std::string flaser(const Pose2& laser, const Pose2& robot, int index) {
  char line[256];
  std::snprintf(line, sizeof line, "FLASER 3 1.0 1.0 1.0 %.3f %.3f %.3f %.3f %.3f %.3f %d.5 host %d.5", laser.x,
                laser.y, laser.phi, robot.x, robot.y, robot.phi, index, index);
  return line;
}

TEST(LaserMounting, ARigidMountIsFoundFromTheTwoPoses) {
  const Pose2 x_RS(0.12, -0.03, 0.05);
  const std::vector<Pose2> robot = robot_path(50);
  const LaserMounting m = estimate_laser_mounting(robot, laser_path(robot, x_RS));
  ASSERT_TRUE(m.x_RS.has_value()) << m.note;
  EXPECT_TRUE(is_near(*m.x_RS, x_RS, 1e-9, 1e-9));
  EXPECT_EQ(m.scans, 50u);
  EXPECT_EQ(m.scans_outside, 0u);
  EXPECT_NE(m.note.find("laser mounted at"), std::string::npos) << m.note;
}

TEST(LaserMounting, TheSamePoseTwiceIsNoMount) {
  const std::vector<Pose2> robot = robot_path(20);
  const LaserMounting m = estimate_laser_mounting(robot, robot);
  EXPECT_FALSE(m.x_RS.has_value());
  EXPECT_NE(m.note.find("no mounting offset"), std::string::npos) << m.note;
}

// A laser pose corrected by a localiser while the robot pose is raw odometry:
// the offset drifts, so the two poses are not a mount and nothing is used.
TEST(LaserMounting, PosesInDifferentFramesAreNotUsed) {
  const std::vector<Pose2> robot = robot_path(40);
  std::vector<Pose2> corrected;
  for (std::size_t i = 0; i < robot.size(); ++i) {
    corrected.push_back(compose(Pose2(0.02 * static_cast<double>(i), 0.0, 0.004 * static_cast<double>(i)), robot[i]));
  }
  const LaserMounting m = estimate_laser_mounting(robot, corrected);
  EXPECT_FALSE(m.x_RS.has_value());
  EXPECT_GT(m.scans_outside, 2u);
  EXPECT_NE(m.note.find("different frames"), std::string::npos) << m.note;
}

TEST(LaserMounting, AFewGlitchedPosesDoNotHideARigidMount) {
  const Pose2 x_RS(-0.2, 0.0, 3.1);  // mounted backwards, near the ±π cut
  const std::vector<Pose2> robot = robot_path(100);
  std::vector<Pose2> laser = laser_path(robot, x_RS);
  laser[10].x += 5.0;
  laser[60].phi += 1.0;
  const LaserMounting m = estimate_laser_mounting(robot, laser);
  ASSERT_TRUE(m.x_RS.has_value()) << m.note;
  EXPECT_TRUE(is_near(*m.x_RS, x_RS, 1e-9, 1e-9));
  EXPECT_EQ(m.scans_outside, 2u);
}

// Two frames that differ by a constant far away (a map frame and an odometry
// frame, say) are rigid too, but no laser sits 50 m from its robot.
TEST(LaserMounting, AConstantOffsetFarAwayIsNotAMount) {
  const std::vector<Pose2> robot = robot_path(20);
  const LaserMounting m = estimate_laser_mounting(robot, laser_path(robot, Pose2(50.0, 0.0, 0.0)));
  EXPECT_FALSE(m.x_RS.has_value());
  EXPECT_NE(m.note.find("not a mount"), std::string::npos) << m.note;
  std::vector<Pose2> huge = robot;
  for (Pose2& p : huge) p.x = 1e300;
  EXPECT_FALSE(estimate_laser_mounting(robot, huge).x_RS.has_value());
}

TEST(LaserMounting, MismatchedLengthsThrow) {
  EXPECT_THROW(estimate_laser_mounting(robot_path(3), robot_path(2)), std::invalid_argument);
  EXPECT_FALSE(estimate_laser_mounting({}, {}).x_RS.has_value());
}

// Through the CARMEN reader: each scan's odometry pose becomes the laser's,
// x_OR ⊕ x_RS, within the log's 3-decimal rounding.
TEST(LaserMounting, TheCarmenReaderMovesTheOdometryToTheLaser) {
  const Pose2 x_RS(0.15, 0.0, 0.0);
  const std::vector<Pose2> robot = robot_path(30);
  const std::vector<Pose2> laser = laser_path(robot, x_RS);
  CarmenLog log;
  for (std::size_t i = 0; i < robot.size(); ++i) {
    parse_carmen_line(flaser(laser[i], robot[i], static_cast<int>(i)), "mounted.log", i + 1, {}, log);
  }
  ASSERT_EQ(log.laser_poses.size(), 30u);
  apply_laser_mounting(log);
  ASSERT_TRUE(log.laser_mounting.x_RS.has_value()) << log.laser_mounting.note;
  EXPECT_TRUE(is_near(*log.laser_mounting.x_RS, x_RS, 2e-3, 2e-3));
  for (std::size_t i = 0; i < robot.size(); ++i) {
    EXPECT_TRUE(is_near(log.scans[i].odometry, laser[i], 3e-3, 3e-3)) << "scan " << i;
  }
}

}  // namespace
}  // namespace lmf::io
