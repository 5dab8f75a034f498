// The scan history (scan_history.hpp): poses re-expressed in the newest
// scan's frame exactly, the keyframe rules, and the union reference.
#include "lmf/front_end/scan_history.hpp"

#include <cmath>
#include <vector>

#include <Eigen/Geometry>
#include <gtest/gtest.h>

namespace lmf {
namespace {

OrientedPoints one_point(double x, double y) {
  OrientedPoints p;
  p.points.emplace_back(x, y);
  p.normals.emplace_back(-1.0, 0.0);
  return p;
}

TEST(ScanHistory, PosesAreReExpressedInTheNewestFrameExactly) {
  ScanMatcherConfig config;
  config.history_scans = 4;
  ScanHistory history(config);
  const std::vector<Pose2> x_W = {Pose2(0.0, 0.0, 0.0),  Pose2(0.5, 0.1, 0.3),   Pose2(0.9, 0.5, 1.2),
                                  Pose2(0.7, 1.1, 2.9),  Pose2(0.2, 1.0, -2.8),  Pose2(-0.4, 0.6, -1.9)};
  for (std::size_t k = 0; k < x_W.size(); ++k) {
    const Pose2 increment = k == 0 ? Pose2() : between(x_W[k - 1], x_W[k]);
    history.add(one_point(2.0 + static_cast<double>(k), 0.5), increment, k > 0);
    ASSERT_EQ(history.size(), std::min<std::size_t>(k + 1, 4));
    for (std::size_t i = 0; i < history.size(); ++i) {
      // Keyframe i is scan k - i.
      const Pose2 expected = between(x_W[k], x_W[k - i]);
      const Pose2& got = history.keyframes()[i].x_NK;
      EXPECT_NEAR(got.x, expected.x, 1e-12) << k << " " << i;
      EXPECT_NEAR(got.y, expected.y, 1e-12) << k << " " << i;
      EXPECT_NEAR(wrap_angle(got.phi - expected.phi), 0.0, 1e-12) << k << " " << i;
    }
    // The reference holds each keyframe's point in the newest frame.
    ASSERT_EQ(history.reference().size(), history.size());
    for (std::size_t i = 0; i < history.size(); ++i) {
      const std::size_t scan = k - i;
      const Eigen::Vector2d world = x_W[scan].transform_point(Eigen::Vector2d(2.0 + static_cast<double>(scan), 0.5));
      const Eigen::Vector2d in_newest = inverse(x_W[k]).transform_point(world);
      EXPECT_TRUE(history.reference().points()[i].isApprox(in_newest, 1e-12));
      const Eigen::Vector2d normal = Eigen::Rotation2Dd(x_W[scan].phi - x_W[k].phi) * Eigen::Vector2d(-1.0, 0.0);
      EXPECT_TRUE(history.reference().normals()[i].isApprox(normal, 1e-12));
    }
  }
}

TEST(ScanHistory, KeyframesNeedMotionAndAFailedMatchRestartsTheHistory) {
  ScanMatcherConfig config;
  ScanHistory history(config);
  history.add(one_point(2.0, 0.0), Pose2(), false);
  history.add(one_point(2.0, 1.0), Pose2(0.5, 0.0, 0.0), true);
  EXPECT_EQ(history.size(), 2u);
  // Standing still: the previous scan adds nothing next to this one.
  history.add(one_point(2.0, 2.0), Pose2(0.01, 0.0, 0.01), true);
  EXPECT_EQ(history.size(), 2u);
  EXPECT_TRUE(history.keyframes()[1].points.points.front().isApprox(Eigen::Vector2d(2.0, 0.0)));
  // Turning on the spot is motion.
  history.add(one_point(2.0, 3.0), Pose2(0.0, 0.0, 0.3), true);
  EXPECT_EQ(history.size(), 3u);
  // Not connected (odometry only): only the new scan.
  history.add(one_point(2.0, 4.0), Pose2(0.5, 0.0, 0.0), false);
  EXPECT_EQ(history.size(), 1u);
  EXPECT_EQ(history.reference().size(), 1u);
  history.clear();
  EXPECT_TRUE(history.empty());
  EXPECT_EQ(history.reference().size(), 0u);
}

}  // namespace
}  // namespace lmf
