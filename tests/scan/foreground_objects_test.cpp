// Small foreground objects (people, other robots) told apart from walls, and
// the scan match that keeps a robot driving behind another one from learning
// that it stands still.
#include "lmf/scan/foreground_objects.hpp"

#include <cmath>
#include <optional>
#include <stdexcept>
#include <vector>

#include <Eigen/Core>
#include <gtest/gtest.h>

#include "lmf/scan/scan_matcher.hpp"
#include "scan/synthetic_scan.hpp"

namespace lmf {
namespace {

std::vector<bool> all_returns(const LaserScan& scan) {
  std::vector<bool> usable(scan.ranges_m.size());
  for (std::size_t i = 0; i < usable.size(); ++i) usable[i] = scan.ranges_m[i] < scan.max_range_m;
  return usable;
}

// A corridor 2 m wide along x, closed 20 m ahead.
testing::SyntheticWorld corridor() {
  testing::SyntheticWorld w;
  w.walls = {{{-30.0, -1.0}, {30.0, -1.0}}, {{-30.0, 1.0}, {30.0, 1.0}}, {{20.0, -1.0}, {20.0, 1.0}}};
  return w;
}

// Beams whose ray passes through the disc (robot at the origin, heading +x).
std::vector<bool> beams_on(const LaserScan& scan, const testing::Disc& disc) {
  std::vector<bool> on(scan.ranges_m.size());
  for (std::size_t i = 0; i < on.size(); ++i) {
    const Eigen::Vector2d u(std::cos(scan.beam_angle(i)), std::sin(scan.beam_angle(i)));
    on[i] = testing::ray_disc(Eigen::Vector2d::Zero(), u, disc).has_value();
  }
  return on;
}

TEST(SmallForegroundObjects, ARobotAheadInACorridorIsOneAndTheWallsAreNot) {
  testing::SyntheticWorld world = corridor();
  const testing::Disc body{{1.4, 0.1}, 0.25};
  world.discs = {body};
  const LaserScan scan = testing::make_scan(world);
  const std::vector<bool> object = small_foreground_objects(scan, all_returns(scan), 0.8, 0.3);
  const std::vector<bool> on_body = beams_on(scan, body);
  int marked = 0;
  for (std::size_t i = 0; i < object.size(); ++i) {
    EXPECT_EQ(object[i], on_body[i]) << "beam " << i;
    marked += object[i] ? 1 : 0;
  }
  EXPECT_GT(marked, 20);
}

TEST(SmallForegroundObjects, KeepsWideObjectsObjectsAgainstAWallAndGrazingWalls) {
  // A 1.5 m wide box ahead, a disc touching the left wall (no range jump on
  // the wall's side), and the corridor's walls seen down to grazing angles.
  testing::SyntheticWorld world = corridor();
  world.walls.push_back({{3.0, -0.75}, {3.0, 0.75}});
  world.discs = {{{1.5, 0.75}, 0.25}};
  const LaserScan scan = testing::make_scan(world);
  const std::vector<bool> object = small_foreground_objects(scan, all_returns(scan), 0.8, 0.3);
  for (std::size_t i = 0; i < object.size(); ++i) EXPECT_FALSE(object[i]) << "beam " << i;
}

TEST(SmallForegroundObjects, ZeroExtentMarksNothingAndBadInputThrows) {
  testing::SyntheticWorld world = corridor();
  world.discs = {{{1.4, 0.0}, 0.25}};
  const LaserScan scan = testing::make_scan(world);
  const std::vector<bool> object = small_foreground_objects(scan, all_returns(scan), 0.0, 0.3);
  for (const bool b : object) EXPECT_FALSE(b);
  EXPECT_THROW(small_foreground_objects(scan, std::vector<bool>(3, true), 0.8, 0.3), std::invalid_argument);
  EXPECT_THROW(small_foreground_objects(scan, all_returns(scan), 0.8, 0.0), std::invalid_argument);
}

TEST(ScanMatcherWithObjects, ABodyMovingWithTheRobotNeitherStopsItNorTeachesTheOdometry) {
  // Robot A then B, 0.3 m further down the corridor; the robot ahead keeps
  // its distance, so the laser sees it in the same place both times.
  testing::SyntheticWorld at_a = corridor();
  testing::SyntheticWorld at_b = corridor();
  const Pose2 x_WA(0.0, 0.0, 0.0);
  const Pose2 x_WB(0.3, 0.0, 0.0);
  at_a.discs = {{{1.2, 0.05}, 0.25}};
  at_b.discs = {{{1.5, 0.05}, 0.25}};
  ScanMatcherConfig config;
  const LaserScan A = testing::make_scan(at_a, x_WA);
  const LaserScan B = testing::make_scan(at_b, x_WB);
  const ReferenceScan reference = ReferenceScan::from(A, config);
  const Pose2 u_hat = between(x_WA, x_WB);  // the odometry is right
  const double s = 0.03;
  const Eigen::Matrix3d Q = Eigen::Vector3d(s * s, s * s, 0.01 * 0.01).asDiagonal();

  const ScanPoints points = scan_points_by_kind(B, config);
  ASSERT_LT(points.structure.size(), points.all.size());
  // Matched with the body, the robot seems to have barely moved ...
  const std::optional<ScanMatch> naive = match_scans(reference, points.all, u_hat, Q, config);
  ASSERT_TRUE(naive.has_value());
  EXPECT_LT(naive->x_AB.x, 0.2);
  // ... told apart, the body is seen to move and the increment is the odometry's.
  const std::optional<ScanMatch> m = match_scans(reference, points, u_hat, Q, config);
  ASSERT_TRUE(m.has_value());
  EXPECT_TRUE(m->objects_moving);
  EXPECT_NEAR(m->x_AB.x, 0.3, 0.03);
  EXPECT_NEAR(m->static_x_AB.x, 0.3, 0.03);
  // Along the corridor the walls alone say next to nothing.
  EXPECT_LT(m->static_laser_information(0, 0), 0.1 / Q(0, 0));
  // The search's findings stay the full scan's: its best pose, held back by
  // the body, lay on the window's edge, which the registration reads as a
  // motion the window may not have held (escalating_registration.hpp).
  EXPECT_TRUE(naive->search_at_window_edge);
  EXPECT_EQ(m->search_at_window_edge, naive->search_at_window_edge);
  EXPECT_EQ(m->search_score, naive->search_score);
}

TEST(ScanMatcherWithObjects, StaticObjectsAreKept) {
  // The same corridor with a pillar that stays put: kept in the match.
  testing::SyntheticWorld world = corridor();
  world.discs = {{{1.5, 0.05}, 0.25}};
  const Pose2 x_WA(0.0, 0.0, 0.0);
  const Pose2 x_WB(0.3, 0.0, 0.0);
  ScanMatcherConfig config;
  const LaserScan A = testing::make_scan(world, x_WA);
  const LaserScan B = testing::make_scan(world, x_WB);
  const Pose2 u_hat(0.33, 0.0, 0.0);  // the odometry 3 cm long
  const Eigen::Matrix3d Q = Eigen::Vector3d(0.03 * 0.03, 0.03 * 0.03, 0.01 * 0.01).asDiagonal();
  const std::optional<ScanMatch> m =
      match_scans(ReferenceScan::from(A, config), scan_points_by_kind(B, config), u_hat, Q, config);
  ASSERT_TRUE(m.has_value());
  EXPECT_FALSE(m->objects_moving);
  // The pillar corrects most of the odometry's error (the walls alone could not).
  EXPECT_LT(std::abs(m->x_AB.x - 0.3), 0.015);
}

}  // namespace
}  // namespace lmf
