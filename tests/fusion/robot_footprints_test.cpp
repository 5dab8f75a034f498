// RobotFootprints: a segment is covered only when one recorded position lies
// within the radius of both its ends, across grid cells and signs.
#include "lmf/fusion/robot_footprints.hpp"

#include <cmath>
#include <limits>
#include <stdexcept>

#include <gtest/gtest.h>

namespace lmf::fusion {
namespace {

TEST(RobotFootprintsTest, CoversASegmentInsideOneDisc) {
  RobotFootprints f(0.35);
  f.add({2.0, 1.0});
  EXPECT_TRUE(f.covers({1.8, 1.2}, {2.2, 1.2}));    // both ends 0.28 m away
  EXPECT_TRUE(f.covers({2.0, 1.0}, {2.0, 1.0}));    // a point on the position
  EXPECT_FALSE(f.covers({1.7, 1.2}, {2.3, 1.2}));   // ends 0.36 m away
  EXPECT_FALSE(f.covers({2.0, 1.5}, {2.1, 1.5}));   // beside it
  EXPECT_FALSE(f.covers({1.4, 1.0}, {2.0, 1.0}));   // one end outside
  EXPECT_EQ(f.size(), 1u);
}

TEST(RobotFootprintsTest, FindsPositionsInNeighbouringCellsAndAcrossZero) {
  RobotFootprints f(0.35);
  f.add({-0.01, -0.01});  // cell (-1, -1)
  EXPECT_TRUE(f.covers({0.2, 0.0}, {0.0, 0.2}));  // ends in cells (0, 0)
  EXPECT_TRUE(f.covers({-0.3, 0.1}, {0.1, -0.3}));
  f.add({10.69, -3.49});  // at the edge of a cell
  EXPECT_TRUE(f.covers({10.36, -3.49}, {10.69, -3.16}));
  EXPECT_FALSE(f.covers({10.3, -3.49}, {10.69, -3.16}));
}

TEST(RobotFootprintsTest, TwoDiscsTogetherDoNotCoverALongerSegment) {
  // One body is one disc: a wall 0.6 m long beside two poses 0.6 m apart is
  // within the radius of some pose at every point, but of no single one.
  RobotFootprints f(0.35);
  f.add({0.0, 0.0});
  f.add({0.6, 0.0});
  EXPECT_FALSE(f.covers({0.0, 0.2}, {0.6, 0.2}));
  EXPECT_TRUE(f.covers({0.0, 0.2}, {0.2, 0.2}));
  EXPECT_EQ(f.positions().size(), 2u);
  EXPECT_DOUBLE_EQ(f.positions()[1].x(), 0.6);
}

TEST(RobotFootprintsTest, AStandingRobotRecordsOnePosition) {
  RobotFootprints f(0.4);  // min_spacing 0.02 m
  EXPECT_DOUBLE_EQ(f.min_spacing(), 0.02);
  EXPECT_TRUE(f.add({1.0, 1.0}));
  for (int scan = 0; scan < 1000; ++scan) {
    // Pose jitter of a robot standing still, within 1.5 cm.
    EXPECT_FALSE(f.add({1.0 + 0.01 * std::sin(scan), 1.0 + 0.01 * std::cos(scan)}));
  }
  EXPECT_EQ(f.size(), 1u);
  EXPECT_TRUE(f.add({1.025, 1.0}));   // 2.5 cm away: a new position
  EXPECT_TRUE(f.add({0.399, 1.0}));   // another cell, far from both
  EXPECT_EQ(f.size(), 3u);
  EXPECT_FALSE(f.add({0.405, 1.0}));  // near the last one, across a cell boundary (0.4)
  EXPECT_TRUE(f.covers({0.9, 1.3}, {1.1, 1.3}));
}

TEST(RobotFootprintsTest, RejectsABadRadiusAndNonFinitePositions) {
  const double nan = std::numeric_limits<double>::quiet_NaN();
  EXPECT_THROW(RobotFootprints{0.0}, std::invalid_argument);
  EXPECT_THROW(RobotFootprints{-1.0}, std::invalid_argument);
  EXPECT_THROW(RobotFootprints{nan}, std::invalid_argument);
  RobotFootprints f(0.3);
  EXPECT_THROW(f.add({nan, 0.0}), std::invalid_argument);
  EXPECT_EQ(f.size(), 0u);
  f.add({0.0, 0.0});
  EXPECT_FALSE(f.covers({nan, 0.0}, {0.0, 0.0}));
}

}  // namespace
}  // namespace lmf::fusion
