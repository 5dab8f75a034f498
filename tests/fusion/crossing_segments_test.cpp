// segments_cross: proper crossings only, within the angle, away from every end.
#include "lmf/fusion/crossing_segments.hpp"

#include <cmath>
#include <numbers>

#include <gtest/gtest.h>

namespace lmf::fusion {
namespace {

EndPoints from(double x0, double y0, double x1, double y1) { return {{x0, y0}, {x1, y1}}; }

// A 0.4 m piece at `degrees` to the x axis, centred at (cx, 0).
EndPoints piece(double cx, double degrees) {
  const double a = degrees * std::numbers::pi / 180.0;
  const Eigen::Vector2d h(0.2 * std::cos(a), 0.2 * std::sin(a));
  return {Eigen::Vector2d(cx, 0.0) - h, Eigen::Vector2d(cx, 0.0) + h};
}

TEST(CrossingSegmentsTest, AShortPieceAtAnAngleAcrossAWallCrosses) {
  const EndPoints wall = from(0.0, 0.0, 4.0, 0.0);
  const CrossingRule rule;  // 0.1 m, 60°
  for (const double degrees : {10.0, 25.0, 40.0, 59.0, -30.0, 150.0}) {
    EXPECT_TRUE(segments_cross(wall, piece(2.0, degrees), rule)) << degrees;
    EXPECT_TRUE(segments_cross(piece(2.0, degrees), wall, rule)) << degrees;  // symmetric
  }
}

TEST(CrossingSegmentsTest, NearPerpendicularCrossingsAreLeftToTheWallsBeyondTheAngle) {
  const EndPoints wall = from(0.0, 0.0, 4.0, 0.0);
  EXPECT_FALSE(segments_cross(wall, piece(2.0, 61.0), {}));
  EXPECT_FALSE(segments_cross(wall, piece(2.0, 90.0), {}));
  EXPECT_TRUE(segments_cross(wall, piece(2.0, 90.0), {0.1, std::numbers::pi / 2}));
}

TEST(CrossingSegmentsTest, CornersJunctionsAndParallelsDoNotCross) {
  const EndPoints wall = from(0.0, 0.0, 4.0, 0.0);
  const CrossingRule rule{0.1, std::numbers::pi / 2};  // every angle
  EXPECT_FALSE(segments_cross(wall, from(4.0, 0.0, 4.0, 3.0), rule));     // L corner
  EXPECT_FALSE(segments_cross(wall, from(3.95, -0.05, 3.95, 3.0), rule)); // corner overshooting by 5 cm
  EXPECT_FALSE(segments_cross(wall, from(2.0, -0.08, 2.0, 3.0), rule));   // T junction, stem 8 cm through
  EXPECT_TRUE(segments_cross(wall, from(2.0, -0.3, 2.0, 3.0), rule));     // 30 cm through: a crossing
  EXPECT_FALSE(segments_cross(wall, from(0.0, 0.2, 4.0, 0.2), rule));     // the wall's other face
  EXPECT_FALSE(segments_cross(wall, from(1.0, 0.0, 3.0, 0.0), rule));     // collinear, overlapping
  EXPECT_FALSE(segments_cross(wall, from(5.0, -1.0, 6.0, 1.0), rule));    // apart
}

TEST(CrossingSegmentsTest, TheMarginHoldsOnBothSegments) {
  const EndPoints wall = from(0.0, 0.0, 4.0, 0.0);
  const CrossingRule rule{0.1, std::numbers::pi / 3};
  // Crossing 0.139 m from the piece's end: inside a margin of 0.15, outside one of 0.1.
  const EndPoints near_end = from(1.88, -0.06928, 2.22641, 0.13072);  // 0.4 m at 30°, crossing 0.1386 m from its start
  EXPECT_TRUE(segments_cross(wall, near_end, rule));
  EXPECT_FALSE(segments_cross(wall, near_end, {0.15, std::numbers::pi / 3}));
  // Crossing 0.05 m from the wall's end.
  EXPECT_FALSE(segments_cross(wall, piece(3.95, 30.0), rule));
  // Pieces shorter than twice the margin never cross.
  EXPECT_FALSE(segments_cross(wall, piece(2.0, 30.0), {0.25, std::numbers::pi / 3}));
}

}  // namespace
}  // namespace lmf::fusion
