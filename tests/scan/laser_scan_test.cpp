#include <gtest/gtest.h>

#include "lmf/scan/laser_scan.hpp"

namespace lmf {
namespace {

TEST(LaserScan, AtMessagePrecisionRoundsEveryFloatField) {
  LaserScan scan;
  scan.utime = 123;
  scan.odometry = Pose2(0.1, 0.2, 0.3);
  scan.angle_min_rad = -1.5707963267948966;
  scan.angle_increment_rad = 0.1;
  scan.max_range_m = 0.1;
  scan.ranges_m = {0.1, 2.0 / 3.0};
  const LaserScan out = at_message_precision(scan);
  const auto as_float = [](double v) { return static_cast<double>(static_cast<float>(v)); };
  EXPECT_EQ(out.angle_min_rad, as_float(scan.angle_min_rad));
  EXPECT_NE(out.angle_min_rad, scan.angle_min_rad);
  EXPECT_EQ(out.angle_increment_rad, as_float(scan.angle_increment_rad));
  EXPECT_EQ(out.max_range_m, as_float(scan.max_range_m));
  EXPECT_EQ(out.ranges_m, (std::vector<double>{as_float(0.1), as_float(2.0 / 3.0)}));
  // Time and odometry travel as int64 and double: unchanged.
  EXPECT_EQ(out.utime, 123);
  EXPECT_EQ(out.odometry.phi, 0.3);
}

}  // namespace
}  // namespace lmf
