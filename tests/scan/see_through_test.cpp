// count_see_through: free-space evidence of a scan against segments.
#include "lmf/scan/see_through.hpp"

#include <cmath>
#include <numbers>
#include <stdexcept>

#include <gtest/gtest.h>

#include "scan/synthetic_scan.hpp"

namespace lmf {
namespace {

constexpr double kMinRange = 0.05;
constexpr double kMaxValid = 30.0;

// A wall across the view 6 m ahead, and a 0.8 m box face 2 m ahead.
const testing::Wall kFarWall{{6.0, -5.0}, {6.0, 5.0}};
const testing::Wall kBoxFace{{2.0, -0.4}, {2.0, 0.4}};
// The box face as the map holds it (sensor frame): midpoint, direction, length.
const SensorSegment kBoxSegment{Pose2(2.0, 0.0, std::numbers::pi / 2), 0.8};

SeeThroughCount count_one(const testing::SyntheticWorld& world, const SensorSegment& segment,
                          const SeeThroughConfig& config = {}) {
  const LaserScan scan = testing::make_scan(world);
  const std::vector<SeeThroughCount> counts = count_see_through(scan, {segment}, kMinRange, kMaxValid, config);
  EXPECT_EQ(counts.size(), 1u);
  return counts.front();
}

TEST(SeeThrough, AnObjectStillThereIsSupported) {
  testing::SyntheticWorld world;
  world.walls = {kFarWall, kBoxFace};
  const SeeThroughCount c = count_one(world, kBoxSegment);
  EXPECT_EQ(c.through, 0);
  EXPECT_GT(c.support, 20);  // 0.6 m checked at 2 m: ~17°, two beams per degree
  EXPECT_FALSE(c.seen_through({}));
}

TEST(SeeThrough, AnObjectGoneIsSeenThroughOverItsLength) {
  testing::SyntheticWorld world;
  world.walls = {kFarWall};
  const SeeThroughCount c = count_one(world, kBoxSegment);
  EXPECT_GT(c.through, 20);
  EXPECT_EQ(c.support, 0);
  EXPECT_NEAR(c.checked_length_m, 0.6, 1e-12);
  EXPECT_GT(c.through_extent_m, 0.55);
  EXPECT_TRUE(c.seen_through({}));
}

TEST(SeeThrough, OneSupportingBeamVetoesByDefault) {
  // Half the face is still there (a wall the map extended across an opening).
  testing::SyntheticWorld world;
  world.walls = {kFarWall, {{2.0, 0.0}, {2.0, 0.4}}};
  const SeeThroughCount c = count_one(world, kBoxSegment);
  EXPECT_GT(c.through, 5);
  EXPECT_GT(c.support, 5);
  EXPECT_FALSE(c.seen_through({}));
  SeeThroughConfig lenient;
  lenient.min_fraction = 0.3;
  lenient.min_coverage = 0.3;
  EXPECT_TRUE(c.seen_through(lenient));
}

TEST(SeeThroughCoverage, SeenThroughAtOneEndOnlyIsKept) {
  // Behind the right end there is a wall; elsewhere no return (no evidence).
  testing::SyntheticWorld world;
  world.walls = {{{6.0, -5.0}, {6.0, -0.6}}};
  const SeeThroughCount c = count_one(world, kBoxSegment);
  EXPECT_GE(c.through, 5);
  EXPECT_EQ(c.support, 0);
  EXPECT_LT(c.through_extent_m, 0.7 * c.checked_length_m);
  EXPECT_FALSE(c.seen_through({}));
}

TEST(SeeThrough, NoReturnGrazingAndOutOfViewSayNothing) {
  testing::SyntheticWorld empty;  // every beam reads max range: no return
  SeeThroughCount c = count_one(empty, kBoxSegment);
  EXPECT_EQ(c.through + c.support, 0);

  testing::SyntheticWorld world;
  world.walls = {kFarWall};
  // Along the beams (incidence ~0): every crossing is grazing.
  c = count_one(world, {Pose2(2.0, 0.02, 0.0), 2.0});
  EXPECT_EQ(c.through + c.support, 0);
  // Behind the sensor (the scan covers -90°..90°).
  c = count_one(world, {Pose2(-2.0, 0.0, std::numbers::pi / 2), 0.8});
  EXPECT_EQ(c.through + c.support, 0);
  // An object nearer than the box hides it: occlusion is no evidence.
  world.walls = {kFarWall, {{1.0, -1.0}, {1.0, 1.0}}};
  c = count_one(world, kBoxSegment);
  EXPECT_EQ(c.through + c.support, 0);
}

TEST(SeeThrough, ASegmentAcrossTheScanStartIsFound) {
  // Bearings -100°..-80° straddle the first beam (-90°): beams from index 0.
  testing::SyntheticWorld world;
  world.walls = {{{-5.0, -6.0}, {5.0, -6.0}}};
  const SensorSegment below{Pose2(0.0, -2.0, 0.0), 0.8};
  const SeeThroughCount c = count_one(world, below);
  EXPECT_GT(c.through, 5);
}

TEST(SeeThroughConfig, ValidateNamesTheField) {
  SeeThroughConfig c;
  EXPECT_NO_THROW(c.validate());
  c.margin_m = 0.0;
  EXPECT_THROW(c.validate(), std::invalid_argument);
  c = {};
  c.min_incidence_rad = std::numbers::pi / 2;
  EXPECT_THROW(c.validate(), std::invalid_argument);
  c = {};
  c.min_beams = 0;
  EXPECT_THROW(c.validate(), std::invalid_argument);
  c = {};
  c.min_fraction = 0.0;
  try {
    c.validate();
    FAIL() << "min_fraction 0 accepted";
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find("min_fraction"), std::string::npos);
  }
  c = {};
  c.min_coverage = 1.5;
  EXPECT_THROW(c.validate(), std::invalid_argument);
}

}  // namespace
}  // namespace lmf
