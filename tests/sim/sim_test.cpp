// Tests of the simulator: random streams, world layout, ray casting, scans, routes,
// odometry noise, sightings and determinism.
#include <algorithm>
#include <cmath>
#include <limits>
#include <numbers>
#include <optional>
#include <queue>
#include <vector>

#include <gtest/gtest.h>

#include "lmf/sim/laser.hpp"
#include "lmf/sim/mission.hpp"
#include "lmf/sim/odometry.hpp"
#include "lmf/sim/random.hpp"
#include "lmf/sim/ray_cast.hpp"
#include "lmf/sim/route.hpp"
#include "lmf/sim/world.hpp"

namespace lmf::sim {
namespace {

// Brute force: the nearest wall along a ray (no grid).
std::optional<double> brute_force_ray(const std::vector<Wall>& walls, const Eigen::Vector2d& origin, double angle) {
  const Eigen::Vector2d dir(std::cos(angle), std::sin(angle));
  std::optional<double> best;
  for (const auto& w : walls) {
    const auto t = ray_segment_distance(origin, dir, w);
    if (t && (!best || *t < *best)) best = t;
  }
  return best;
}

bool segment_crosses_wall(const std::vector<Wall>& walls, const Eigen::Vector2d& a, const Eigen::Vector2d& b) {
  const Eigen::Vector2d d = b - a;
  const double len = d.norm();
  const auto t = brute_force_ray(walls, a, std::atan2(d.y(), d.x()));
  return t && *t < len;
}

double brute_force_clearance(const std::vector<Wall>& walls, const Eigen::Vector2d& p) {
  double best = std::numeric_limits<double>::infinity();
  for (const auto& w : walls) best = std::min(best, point_segment_distance(p, w.a, w.b));
  return best;
}

// Random free points at least `clearance` from every wall.
std::vector<Eigen::Vector2d> free_points(const World& world, std::size_t count, double clearance, uint64_t seed) {
  Rng rng(seed);
  std::vector<Eigen::Vector2d> points;
  while (points.size() < count) {
    const Eigen::Vector2d p(rng.uniform(world.bounds.min.x(), world.bounds.max.x()),
                            rng.uniform(world.bounds.min.y(), world.bounds.max.y()));
    if (world.is_free(p) && brute_force_clearance(world.walls, p) >= clearance) points.push_back(p);
  }
  return points;
}

TEST(Random, SameSeedSameNumbersAndPortableDistributions) {
  Rng a(42);
  Rng b(42);
  for (int i = 0; i < 100; ++i) ASSERT_EQ(a.normal(), b.normal());
  // Moments of the Box–Muller normals and the uniform integers.
  Rng r(7);
  const int n = 200000;
  double sum = 0.0, sum2 = 0.0;
  for (int i = 0; i < n; ++i) {
    const double x = r.normal();
    sum += x;
    sum2 += x * x;
  }
  EXPECT_NEAR(sum / n, 0.0, 0.01);
  EXPECT_NEAR(sum2 / n, 1.0, 0.01);
  std::vector<int> counts(5, 0);
  for (int i = 0; i < 50000; ++i) {
    const int v = r.uniform_int(3, 7);
    ASSERT_GE(v, 3);
    ASSERT_LE(v, 7);
    ++counts[static_cast<std::size_t>(v - 3)];
  }
  for (int c : counts) EXPECT_NEAR(c, 10000, 400);
  EXPECT_NE(derive_seed(1, 0), derive_seed(1, 1));
  EXPECT_NE(derive_seed(1, 0), derive_seed(2, 0));
  EXPECT_THROW(r.uniform_index(0), std::invalid_argument);
}

TEST(RayCast, HitsAKnownWallAtTheRightRange) {
  // A wall at x = 5 from y = -2 to y = 2 (facing -x: free space on its left walking down).
  const WallIndex index({Wall{{5.0, 2.0}, {5.0, -2.0}}}, 0.7);
  const Eigen::Vector2d origin(0.3, 0.1);
  EXPECT_NEAR(*index.cast_ray(origin, 0.0, 30.0), 4.7, 1e-12);
  const double a = 0.3;
  EXPECT_NEAR(*index.cast_ray(origin, a, 30.0), 4.7 / std::cos(a), 1e-12);
  EXPECT_FALSE(index.cast_ray(origin, std::numbers::pi, 30.0).has_value());  // behind
  EXPECT_FALSE(index.cast_ray(origin, 1.2, 30.0).has_value());               // passes above the wall
  EXPECT_FALSE(index.cast_ray(origin, 0.0, 4.0).has_value());                // beyond max range
  EXPECT_TRUE(index.blocks({0.0, 0.0}, {6.0, 0.0}));
  EXPECT_FALSE(index.blocks({0.0, 0.0}, {4.9, 0.0}));
  EXPECT_NEAR(*index.distance_to_nearest({4.0, 3.0}, 2.0), std::sqrt(2.0), 1e-12);
  EXPECT_FALSE(index.distance_to_nearest({1.0, 0.0}, 2.0).has_value());
}

TEST(RayCast, GridAgreesWithBruteForceInTheGeneratedWorld) {
  const World world = generate_world({}, 3);
  const WallIndex index(world.walls);
  Rng rng(11);
  int hits = 0;
  for (const auto& p : free_points(world, 200, 0.05, 5)) {
    for (int k = 0; k < 20; ++k) {
      const double angle = rng.uniform(-std::numbers::pi, std::numbers::pi);
      const auto grid = index.cast_ray(p, angle, 30.0);
      auto brute = brute_force_ray(world.walls, p, angle);
      if (brute && *brute > 30.0) brute.reset();
      ASSERT_EQ(grid.has_value(), brute.has_value()) << "at " << p.transpose() << " angle " << angle;
      if (grid) {
        ASSERT_NEAR(*grid, *brute, 1e-9);
        ++hits;
      }
    }
  }
  EXPECT_GT(hits, 3000);
}

TEST(World, HasALoopOfAtLeast100mThatIsDrivable) {
  for (uint64_t seed : {1u, 2u, 3u}) {
    const World world = generate_world({}, seed);
    EXPECT_GE(world.loop_length_m, 100.0);
    ASSERT_EQ(world.loop.size(), 4u);
    double length = 0.0;
    for (std::size_t i = 0; i < world.loop.size(); ++i) {
      const Eigen::Vector2d a = world.loop[i];
      const Eigen::Vector2d b = world.loop[(i + 1) % world.loop.size()];
      length += (b - a).norm();
      EXPECT_FALSE(segment_crosses_wall(world.walls, a, b)) << "loop leg " << i << " crosses a wall";
      for (double s = 0.0; s <= 1.0; s += 0.01) {
        const Eigen::Vector2d p = a + s * (b - a);
        ASSERT_TRUE(world.is_free(p));
        ASSERT_GE(brute_force_clearance(world.walls, p), 0.5 * world.config.corridor_width_m - 1e-9);
      }
    }
    EXPECT_NEAR(length, world.loop_length_m, 1e-9);
  }
}

TEST(World, WallsAreOrientedFacesAndTheRoadGraphIsConnected) {
  const World world = generate_world({}, 1);
  EXPECT_GT(world.walls.size(), 100u);
  EXPECT_GT(world.rooms.size(), 10u);
  for (const auto& w : world.walls) {
    ASSERT_GT(w.length(), 0.05);
    const Eigen::Vector2d mid = 0.5 * (w.a + w.b);
    const Eigen::Vector2d e = (w.b - w.a).normalized();
    const Eigen::Vector2d left(-e.y(), e.x());
    EXPECT_TRUE(world.is_free(mid + 0.05 * left));
    EXPECT_FALSE(world.is_free(mid - 0.05 * left));
  }
  // Thin walls have two faces: the corridor side and the room side of a door's wall.
  const Room& room = world.rooms.front();
  int faces_near_door = 0;
  for (const auto& w : world.walls) {
    if (point_segment_distance(room.door_center, w.a, w.b) < 0.5 * world.config.door_width_m + 0.2) ++faces_near_door;
  }
  EXPECT_GE(faces_near_door, 4);  // two jambs, each side of the wall
  // Every road node is reachable from node 0.
  const RoadGraph& g = world.graph;
  std::vector<bool> seen(g.nodes.size(), false);
  std::queue<int> todo;
  todo.push(0);
  seen[0] = true;
  while (!todo.empty()) {
    const int n = todo.front();
    todo.pop();
    for (int m : g.neighbours[static_cast<std::size_t>(n)]) {
      if (!seen[static_cast<std::size_t>(m)]) {
        seen[static_cast<std::size_t>(m)] = true;
        todo.push(m);
      }
    }
  }
  EXPECT_TRUE(std::all_of(seen.begin(), seen.end(), [](bool b) { return b; }));
  for (const auto& n : g.nodes) EXPECT_TRUE(world.is_free(n.p));
}

TEST(World, SeedChangesTheLayoutAndBadConfigThrows) {
  const World a = generate_world({}, 1);
  const World b = generate_world({}, 1);
  const World c = generate_world({}, 2);
  ASSERT_EQ(a.walls.size(), b.walls.size());
  for (std::size_t i = 0; i < a.walls.size(); ++i) {
    EXPECT_EQ(a.walls[i].a, b.walls[i].a);
    EXPECT_EQ(a.walls[i].b, b.walls[i].b);
  }
  bool differ = a.walls.size() != c.walls.size();
  for (std::size_t i = 0; !differ && i < a.walls.size(); ++i) differ = a.walls[i].a != c.walls[i].a;
  EXPECT_TRUE(differ);
  WorldConfig bad;
  bad.corridor_width_m = 0.5;
  EXPECT_THROW(generate_world(bad, 1), std::invalid_argument);
}

TEST(Laser, NoReturnsThroughWalls) {
  const World world = generate_world({}, 4);
  const WallIndex index(world.walls);
  LaserConfig config;
  config.range_noise_sigma_m = 0.0;
  Rng rng(1);
  Rng angles(2);
  int returns = 0;
  for (const auto& p : free_points(world, 60, 0.3, 9)) {
    const Pose2 x_WR(p.x(), p.y(), angles.uniform(-std::numbers::pi, std::numbers::pi));
    const LaserScan scan = simulate_scan(index, x_WR, config, {}, rng);
    ASSERT_EQ(scan.ranges_m.size(), 361u);
    EXPECT_DOUBLE_EQ(scan.angle_min_rad, -std::numbers::pi / 2.0);
    EXPECT_DOUBLE_EQ(scan.angle_increment_rad, std::numbers::pi / 360.0);
    for (std::size_t i = 0; i < scan.ranges_m.size(); ++i) {
      const double r = scan.ranges_m[i];
      const double angle = x_WR.phi + scan.beam_angle(i);
      const Eigen::Vector2d dir(std::cos(angle), std::sin(angle));
      if (r >= config.max_range_m) {
        const auto t = brute_force_ray(world.walls, p, angle);
        EXPECT_TRUE(!t || *t >= config.max_range_m);
        continue;
      }
      ++returns;
      // The beam travels through free space only and ends on a wall.
      ASSERT_FALSE(segment_crosses_wall(world.walls, p, p + (r - 1e-6) * dir));
      ASSERT_TRUE(world.is_free(p + (r - 0.01) * dir));
      ASSERT_NEAR(*brute_force_ray(world.walls, p, angle), r, 1e-9);
    }
  }
  EXPECT_GT(returns, 15000);
}

TEST(Laser, NoiseHasTheConfiguredSpreadAndDiscsOcclude) {
  const WallIndex index({Wall{{5.0, 20.0}, {5.0, -20.0}}});
  LaserConfig config;
  Rng rng(3);
  const Pose2 x_WR(0.0, 0.0, 0.0);
  double sum = 0.0, sum2 = 0.0;
  int n = 0;
  for (int k = 0; k < 50; ++k) {
    const LaserScan scan = simulate_scan(index, x_WR, config, {}, rng);
    const std::size_t mid = 180;  // straight ahead
    for (std::size_t i = mid - 20; i <= mid + 20; ++i) {
      const double err = scan.ranges_m[i] - 5.0 / std::cos(scan.beam_angle(i));
      sum += err;
      sum2 += err * err;
      ++n;
    }
  }
  EXPECT_NEAR(sum / n, 0.0, 0.005);
  EXPECT_NEAR(std::sqrt(sum2 / n), 0.05, 0.005);
  config.range_noise_sigma_m = 0.0;
  const LaserScan scan = simulate_scan(index, x_WR, config, {Circle{{2.0, 0.0}, 0.25}}, rng);
  EXPECT_NEAR(scan.ranges_m[180], 1.75, 1e-12);
  EXPECT_EQ(scan.ranges_m[0], config.max_range_m);  // straight right: no wall, no return
}

// range_noise_per_m adds a part proportional to the range, in quadrature:
// σ(r)² = range_noise_sigma_m² + (range_noise_per_m r)².
TEST(Laser, NoiseGrowsWithTheRangeWhenConfigured) {
  LaserConfig config;
  config.range_noise_sigma_m = 0.01;
  config.range_noise_per_m = 0.01;
  Rng rng(4);
  for (const double wall_m : {2.0, 20.0}) {
    const WallIndex index({Wall{{wall_m, 40.0}, {wall_m, -40.0}}});
    double sum2 = 0.0;
    int n = 0;
    for (int k = 0; k < 50; ++k) {
      const LaserScan scan = simulate_scan(index, Pose2(), config, {}, rng);
      for (std::size_t i = 170; i <= 190; ++i) {
        const double range = wall_m / std::cos(scan.beam_angle(i));
        const double err = scan.ranges_m[i] - range;
        sum2 += err * err / (1e-4 + 1e-4 * range * range);  // in units of σ(r)²
        ++n;
      }
    }
    EXPECT_NEAR(std::sqrt(sum2 / n), 1.0, 0.1) << wall_m;
  }
  LaserConfig bad;
  bad.range_noise_per_m = -0.01;
  EXPECT_THROW(bad.validate(), std::invalid_argument);
  bad.range_noise_per_m = 0.2;
  EXPECT_THROW(bad.validate(), std::invalid_argument);
}

TEST(Route, PathsStayAwayFromWallsNeverCrossThemAndTurnSmoothly) {
  MotionConfig motion;
  for (uint64_t seed : {1u, 2u, 5u}) {
    const World world = generate_world({}, seed);
    const WallIndex index(world.walls);
    for (std::size_t r = 0; r < 3; ++r) {
      Rng rng(derive_seed(seed, 100 + r));
      const Trajectory traj = plan_route(world, world.start_spots[r], motion, 400.0, rng);
      ASSERT_GE(traj.duration_s(), 400.0);
      const double dt = 0.05;
      Pose2 prev = traj.pose_at(0.0);
      EXPECT_NEAR(prev.x, world.start_spots[r].p.x(), 1e-12);
      EXPECT_NEAR(prev.phi, wrap_angle(world.start_spots[r].heading_rad), 1e-12);
      for (double t = dt; t <= traj.duration_s(); t += dt) {
        const Pose2 x = traj.pose_at(t);
        const Eigen::Vector2d p(x.x, x.y);
        const Eigen::Vector2d q(prev.x, prev.y);
        ASSERT_TRUE(world.is_free(p)) << "seed " << seed << " robot " << r << " t " << t;
        ASSERT_GE(brute_force_clearance(world.walls, p), motion.wall_margin_m - 1e-9)
            << "seed " << seed << " robot " << r << " t " << t << " at " << p.transpose();
        if ((p - q).norm() > 0.0) {
          ASSERT_FALSE(index.blocks(q, p));
        }
        // Bounded speed and yaw rate: no jumps in position or heading.
        ASSERT_LE((p - q).norm(), motion.speed_mps * dt + 1e-9);
        const double max_rate = std::max(motion.speed_mps / 0.4, motion.rotation_speed_radps);
        ASSERT_LE(std::abs(wrap_angle(x.phi - prev.phi)), max_rate * dt + 1e-9);
        prev = x;
      }
      EXPECT_NEAR(traj.distance_at(traj.duration_s()), traj.length_m(), 1e-12);
    }
  }
}

TEST(Route, SmoothPolylineFilletsCornersAndRotatesAtReversals) {
  MotionConfig motion;
  const Trajectory traj = smooth_polyline({{0.0, 0.0}, {5.0, 0.0}, {5.0, 5.0}, {5.0, 2.0}}, motion);
  // Corner: a quarter circle of turn_radius_m replaces 2 r of the polyline.
  const double r = motion.turn_radius_m;
  EXPECT_NEAR(traj.length_m(), 5.0 + 5.0 + 3.0 - 2.0 * r + 0.5 * std::numbers::pi * r, 1e-9);
  const Pose2 end = traj.pose_at(traj.duration_s());
  EXPECT_NEAR(end.x, 5.0, 1e-9);
  EXPECT_NEAR(end.y, 2.0, 1e-9);
  EXPECT_NEAR(end.phi, -std::numbers::pi / 2.0, 1e-9);
  // The reversal is a rotation in place of pi at rotation_speed_radps.
  EXPECT_NEAR(traj.duration_s(), traj.length_m() / motion.speed_mps + std::numbers::pi / motion.rotation_speed_radps,
              1e-9);
}

TEST(Odometry, NoiseIsProportionalToTheMotion) {
  OdometryNoiseConfig config;
  Rng rng(5);
  for (const Pose2 u : {Pose2(0.1, 0.0, 0.05), Pose2(0.5, 0.02, -0.2), Pose2(0.0, 0.0, 0.3)}) {
    const int n = 40000;
    Eigen::Vector3d sum2 = Eigen::Vector3d::Zero();
    for (int i = 0; i < n; ++i) {
      const Pose2 v = noisy_increment(u, config, rng);
      const Eigen::Vector3d e(v.x - u.x, v.y - u.y, wrap_angle(v.phi - u.phi));
      sum2 += e.cwiseProduct(e);
    }
    const Eigen::Vector3d expected = odometry_noise_covariance(u, config).diagonal();
    for (int k = 0; k < 3; ++k) EXPECT_NEAR(sum2(k) / n, expected(k), 0.03 * expected(k) + 1e-15) << k;
    const double d = std::hypot(u.x, u.y);
    EXPECT_NEAR(std::sqrt(expected(0)), 0.08 * d, 1e-12);
    EXPECT_NEAR(std::sqrt(expected(2)), 0.08 * std::abs(u.phi) + 0.01 * d, 1e-12);
  }
  // No motion, no error.
  const Pose2 still = noisy_increment(Pose2(), config, rng);
  EXPECT_EQ(still.x, 0.0);
  EXPECT_EQ(still.phi, 0.0);
}

MissionConfig short_mission(uint64_t seed, double duration_s, int robots) {
  MissionConfig config;
  config.seed = seed;
  config.duration_s = duration_s;
  config.num_robots = robots;
  return config;
}

TEST(Mission, OdometryDriftsInProportionToTheDistance) {
  MissionConfig config = short_mission(1, 400.0, 1);
  const Mission mission = simulate_mission(config);
  const RobotRun& run = mission.robots[0];
  ASSERT_EQ(run.scans.size(), 2001u);
  EXPECT_NEAR(run.distance_m, 0.5 * 400.0, 25.0);  // corners and rotations slow it a little
  // Per-step errors of the odometry increments match the model (in units of the motion).
  double ratio2 = 0.0;
  int steps = 0;
  for (std::size_t k = 1; k < run.scans.size(); ++k) {
    const Pose2 u_true = between(run.true_poses[k - 1], run.true_poses[k]);
    const Pose2 u_odo = between(run.scans[k - 1].odometry, run.scans[k].odometry);
    const double d = std::hypot(u_true.x, u_true.y);
    if (d < 0.05) continue;
    const double e = std::hypot(u_odo.x - u_true.x, u_odo.y - u_true.y);
    ratio2 += (e * e) / (d * d);
    ++steps;
  }
  // E|e|^2 = 2 (0.08 d)^2 for the two translation components.
  EXPECT_NEAR(std::sqrt(ratio2 / steps / 2.0), 0.08, 0.006);
  // Travelled distance: the odometry's relative error stays within a few percent...
  const double rel = std::abs(run.odometry_distance_m - run.distance_m) / run.distance_m;
  EXPECT_LT(rel, 0.03);
  // ... while the pose drifts visibly (heading noise integrates).
  const Pose2 err = between(run.true_poses.back(), run.scans.back().odometry);
  EXPECT_GT(std::hypot(err.x, err.y), 0.05);
  // Without noise the odometry is the true motion.
  config.odometry = {0.0, 0.0, 0.0};
  config.duration_s = 60.0;
  const Mission exact = simulate_mission(config);
  for (std::size_t k = 0; k < exact.robots[0].scans.size(); ++k) {
    ASSERT_TRUE(is_near(exact.robots[0].scans[k].odometry, exact.robots[0].true_poses[k], 1e-9, 1e-9));
  }
}

TEST(Mission, SameSeedSameMissionDifferentSeedDifferent) {
  const Mission a = simulate_mission(short_mission(9, 30.0, 2));
  const Mission b = simulate_mission(short_mission(9, 30.0, 2));
  const Mission c = simulate_mission(short_mission(10, 30.0, 2));
  ASSERT_EQ(a.robots.size(), 2u);
  for (std::size_t r = 0; r < 2; ++r) {
    ASSERT_EQ(a.robots[r].scans.size(), 151u);
    for (std::size_t k = 0; k < a.robots[r].scans.size(); ++k) {
      ASSERT_EQ(a.robots[r].scans[k].ranges_m, b.robots[r].scans[k].ranges_m);
      ASSERT_EQ(a.robots[r].scans[k].utime, b.robots[r].scans[k].utime);
      ASSERT_EQ(a.robots[r].scans[k].odometry.x, b.robots[r].scans[k].odometry.x);
    }
  }
  EXPECT_NE(a.robots[0].scans[10].ranges_m, c.robots[0].scans[10].ranges_m);
  // Every robot scans at the same times, 5 Hz.
  EXPECT_EQ(a.robots[0].scans[1].utime - a.robots[0].scans[0].utime, 200000);
  EXPECT_EQ(a.robots[1].scans[7].utime, a.robots[0].scans[7].utime);
}

TEST(Mission, SightingsOnlyWhenVisibleAndThinned) {
  const Mission mission = simulate_mission(short_mission(1, 600.0, 3));
  ASSERT_FALSE(mission.sightings.empty());
  // Robot 0 starts with robot 1 five metres ahead.
  EXPECT_EQ(mission.sightings.front().utime, 0);
  EXPECT_EQ(mission.sightings.front().observer, 0);
  EXPECT_EQ(mission.sightings.front().observed, 1);
  EXPECT_NEAR(mission.sightings.front().x_AB.x, 5.0, 1e-9);
  const auto& walls = mission.world.walls;
  for (const auto& s : mission.sightings) {
    const RobotRun& a = mission.robots[static_cast<std::size_t>(s.observer)];
    const RobotRun& b = mission.robots[static_cast<std::size_t>(s.observed)];
    const Pose2& x_WA = a.true_poses[s.observer_scan];
    ASSERT_EQ(s.observed_scan, s.observer_scan);
    ASSERT_EQ(b.scans[s.observed_scan].utime, s.utime);
    const Pose2& x_WB = b.true_poses[s.observed_scan];
    EXPECT_TRUE(is_near(s.x_AB, between(x_WA, x_WB), 1e-12, 1e-12));
    EXPECT_LE(s.range_m, 8.0);
    EXPECT_LE(std::abs(std::atan2(s.x_AB.y, s.x_AB.x)), std::numbers::pi / 2.0);
    EXPECT_FALSE(segment_crosses_wall(walls, {x_WA.x, x_WA.y}, {x_WB.x, x_WB.y}));
  }
  for (std::size_t i = 0; i < mission.sightings.size(); ++i) {
    for (std::size_t j = i + 1; j < mission.sightings.size(); ++j) {
      const auto& p = mission.sightings[i];
      const auto& q = mission.sightings[j];
      if (p.observer == q.observer && p.observed == q.observed) {
        EXPECT_GE(q.utime - p.utime, 10000000);
      }
    }
  }
  // A wall between two robots hides them; behind the observer is out of view.
  const WallIndex wall({Wall{{2.0, -1.0}, {2.0, 1.0}}});
  const SightingConfig config;
  EXPECT_FALSE(robot_visible(wall, Pose2(0, 0, 0), Pose2(4, 0, 0), config));
  EXPECT_TRUE(robot_visible(wall, Pose2(0, 0, 0), Pose2(1.5, 0, 0), config));
  EXPECT_FALSE(robot_visible(wall, Pose2(0, 0, 0), Pose2(-1.5, 0, 0), config));
  EXPECT_FALSE(robot_visible(wall, Pose2(0, 0, 0), Pose2(0, 9, 0), config));
}

TEST(Mission, PeopleAndRobotsShowUpAsClutter) {
  MissionConfig config = short_mission(2, 20.0, 2);
  config.laser.range_noise_sigma_m = 0.0;
  const Mission empty = simulate_mission(config);
  config.people.count = 30;
  const Mission busy = simulate_mission(config);
  ASSERT_EQ(busy.people.size(), 30u);
  // Same routes (independent streams), shorter ranges somewhere.
  int shorter = 0;
  for (std::size_t k = 0; k < empty.robots[0].scans.size(); ++k) {
    ASSERT_TRUE(is_near(empty.robots[0].true_poses[k], busy.robots[0].true_poses[k], 0.0, 0.0));
    for (std::size_t i = 0; i < 361; ++i) {
      ASSERT_LE(busy.robots[0].scans[k].ranges_m[i], empty.robots[0].scans[k].ranges_m[i] + 1e-12);
      if (busy.robots[0].scans[k].ranges_m[i] < empty.robots[0].scans[k].ranges_m[i] - 1e-9) ++shorter;
    }
  }
  EXPECT_GT(shorter, 0);
  for (const auto& person : busy.people) {
    for (double t = 0.0; t < 20.0; t += 1.0) EXPECT_TRUE(busy.world.is_free(person.position_at(t)));
  }
  // Robot 0 sees robot 1 ahead at t = 0: a disc of radius 0.25 m at 5 m.
  EXPECT_NEAR(empty.robots[0].scans[0].ranges_m[180], 5.0 - config.robot_radius_m, 1e-9);
}

// Scan steps at which two robots' bodies overlap, and at which one heading
// the same way as another (within 45°: following it) closes in on it within
// the gap.
struct Encounters {
  int overlapping = 0;
  int following_closer_than_gap = 0;
};

Encounters encounters(const Mission& m) {
  Encounters e;
  const double r = m.config.robot_radius_m;
  for (std::size_t i = 0; i < m.robots.size(); ++i) {
    for (std::size_t j = i + 1; j < m.robots.size(); ++j) {
      for (std::size_t k = 1; k < m.robots[i].true_poses.size(); ++k) {
        const Pose2& a = m.robots[i].true_poses[k];
        const Pose2& b = m.robots[j].true_poses[k];
        const Pose2& a0 = m.robots[i].true_poses[k - 1];
        const Pose2& b0 = m.robots[j].true_poses[k - 1];
        const double d = std::hypot(a.x - b.x, a.y - b.y);
        const double d0 = std::hypot(a0.x - b0.x, a0.y - b0.y);
        if (d < 2.0 * r) ++e.overlapping;
        if (d < 2.0 * r + m.config.robot_gap_m - 1e-9 && d < d0 - 1e-9 &&
            std::cos(wrap_angle(a.phi - b.phi)) > std::cos(M_PI / 4)) {
          ++e.following_closer_than_gap;
        }
      }
    }
  }
  return e;
}

TEST(Mission, RobotsWaitRatherThanDriveIntoEachOther) {
  MissionConfig config = short_mission(4, 900.0, 8);
  config.robot_gap_m = 0.0;
  const Mission through = simulate_mission(config);
  const Encounters before = encounters(through);
  ASSERT_GT(before.overlapping, 0) << "precondition: on the clock, some robots drive through each other";
  ASSERT_GT(before.following_closer_than_gap, 0) << "precondition: ... and into the one ahead";
  config.robot_gap_m = MissionConfig{}.robot_gap_m;
  const Mission careful = simulate_mission(config);
  const Encounters after = encounters(careful);
  // Robots following each other always keep the gap; what overlaps is left
  // to robots meeting head-on, which wait max_wait_s and then pass.
  EXPECT_EQ(after.following_closer_than_gap, 0);
  EXPECT_LT(after.overlapping, before.overlapping);
  // A waiting robot stands still on its route: same pose, same route time.
  int waits = 0;
  for (const RobotRun& run : careful.robots) {
    ASSERT_EQ(run.route_times.size(), run.true_poses.size());
    for (std::size_t k = 1; k < run.route_times.size(); ++k) {
      ASSERT_GE(run.route_times[k], run.route_times[k - 1]);
      if (run.route_times[k] == run.route_times[k - 1]) {
        ++waits;
        EXPECT_TRUE(is_near(run.true_poses[k], run.true_poses[k - 1], 0.0, 0.0));
      } else {
        EXPECT_TRUE(is_near(run.true_poses[k], run.trajectory.pose_at(run.route_times[k]), 0.0, 0.0));
      }
    }
  }
  EXPECT_GT(waits, 0);
}

TEST(Mission, BadConfigThrows) {
  MissionConfig config;
  config.num_robots = 0;
  EXPECT_THROW(simulate_mission(config), std::invalid_argument);
  config = MissionConfig{};
  config.laser.num_beams = 1;
  EXPECT_THROW(simulate_mission(config), std::invalid_argument);
  config = MissionConfig{};
  config.motion.wall_margin_m = 0.5;
  config.world.door_width_m = 0.8;
  EXPECT_THROW(simulate_mission(config), std::invalid_argument);
  config = MissionConfig{};
  config.robot_gap_m = -0.1;
  EXPECT_THROW(simulate_mission(config), std::invalid_argument);
  config = MissionConfig{};
  config.max_wait_s = std::nan("");
  EXPECT_THROW(simulate_mission(config), std::invalid_argument);
}

}  // namespace
}  // namespace lmf::sim
