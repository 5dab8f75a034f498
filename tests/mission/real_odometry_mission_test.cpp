// A 3-robot simulated mission whose odometry behaves like a real robot's (lmf/sim/odometry.hpp,
// RealOdometry: per-robot scale errors, heading bias, slip, heading noise, glitches), mapped in
// process by OfflineMission with the built-in default configuration.
#include <algorithm>
#include <cmath>
#include <filesystem>
#include <limits>
#include <numbers>
#include <string>

#include <gtest/gtest.h>
#include <unistd.h>

#include "lmf/geometry/pose2.hpp"
#include "lmf/local_map/local_map_config.hpp"
#include "lmf/mission/mission_inputs.hpp"
#include "lmf/mission/mission_report.hpp"
#include "lmf/mission/offline_mission.hpp"
#include "lmf/sim/mission.hpp"
#include "lmf/sim/mission_writer.hpp"

namespace lmf::mission {
namespace {

// The mission lmf-sim would write for `config`, read back as lmf-offline --sim reads it.
MissionInputs simulated_inputs(const sim::MissionConfig& config, const std::string& name) {
  const std::filesystem::path dir =
      std::filesystem::temp_directory_path() / ("lmf_" + name + "_" + std::to_string(::getpid()));
  sim::write_mission(sim::simulate_mission(config), dir);
  MissionInputs inputs = load_sim_folder(dir, SightingNoise{});
  std::filesystem::remove_all(dir);
  return inputs;
}

// One robot for 600 s (~300 m) with real-like odometry whose heading glitches,
// one per 20 m, are of [min_rad, max_rad].
sim::MissionConfig one_robot_with_heading_glitches(int seed, double min_rad, double max_rad) {
  sim::MissionConfig config;
  config.num_robots = 1;
  config.seed = seed;
  config.duration_s = 600.0;
  config.odometry_model = sim::OdometryModel::kReal;
  config.real_odometry.heading_glitch_rate_per_m = 0.05;
  config.real_odometry.heading_glitch_min_rad = min_rad;
  config.real_odometry.heading_glitch_max_rad = max_rad;
  return config;
}

// One robot's mission mapped with the built-in defaults: its result, its
// local maps' worst end errors and the ATE, after the checks every such run
// passes (one robot, covariance always fine, more than 20 local maps).
struct OneRobotRun {
  RobotResult robot;
  double worst_local_map_m = 0.0;
  double worst_local_map_rad = 0.0;
  double ate_m = 0.0;
};

OneRobotRun run_one_robot(const MissionInputs& inputs) {
  OneRobotRun run;
  OfflineMission mission(MissionConfig{}, inputs);
  const MissionResult result = mission.run();
  EXPECT_EQ(result.robots.size(), 1u);
  if (result.robots.size() != 1u) return run;
  run.robot = result.robots[0];
  EXPECT_TRUE(run.robot.covariance_always_ok) << run.robot.first_covariance_problem;
  EXPECT_GT(run.robot.local_map_consistency.size(), 20u);
  for (const LocalMapConsistency& c : run.robot.local_map_consistency) {
    run.worst_local_map_m = std::max(run.worst_local_map_m, c.error_m);
    run.worst_local_map_rad = std::max(run.worst_local_map_rad, c.error_rad);
  }
  const auto score = score_mission(result, mission.inputs(), mission.global_map());
  EXPECT_TRUE(score.has_value());
  run.ate_m = score ? score->ate.position_rmse_m : std::numeric_limits<double>::infinity();
  return run;
}

TEST(RealOdometryMission, ThreeRobotsJoinFuseEveryLocalMapAndStayNearTheTruth) {
  sim::MissionConfig sim_config;
  sim_config.num_robots = 3;
  sim_config.seed = 2;
  sim_config.duration_s = 240.0;  // 4 minutes, ~110 m per robot
  sim_config.odometry_model = sim::OdometryModel::kReal;
  const MissionInputs inputs = simulated_inputs(sim_config, "real_odometry_mission");
  ASSERT_EQ(inputs.robots.size(), 3u);

  OfflineMission mission(MissionConfig{}, inputs);  // the built-in defaults, no config file
  const MissionResult result = mission.run();
  for (const RobotResult& r : result.robots) {
    SCOPED_TRACE(r.name);
    EXPECT_TRUE(r.joined);
    EXPECT_EQ(r.trajectory.size(), r.scans);
    EXPECT_GT(r.local_maps_shipped, 0u);
    EXPECT_EQ(r.local_maps_fused, r.local_maps_shipped);
    EXPECT_TRUE(r.covariance_always_ok) << r.first_covariance_problem;
  }
  EXPECT_TRUE(result.global_covariance_always_ok);

  const auto score = score_mission(result, mission.inputs(), mission.global_map());
  ASSERT_TRUE(score.has_value());
  ASSERT_EQ(score->robots.size(), 3u);
  // Odometry alone: RMS over the robots of each robot's odometry ATE, each aligned on its own
  // (kinder to the odometry than the map's one alignment for all robots).
  double odometry2 = 0.0;
  for (const RobotScore& s : score->robots) odometry2 += s.odometry_ate.position_rmse_m * s.odometry_ate.position_rmse_m;
  const double odometry_ate = std::sqrt(odometry2 / 3.0);
  // Measured at the commit that added this test: map ATE 0.755 m over the 3 robots in one
  // alignment; odometry alone 2.40 m (0.65, 4.01 and 0.86 m per robot). The bounds pass with
  // ~60 % margin and still fail for a broken map (one robot's frame off by metres, or the map no
  // better than half the odometry's error). They are loose on purpose while the real-odometry
  // accuracy is being worked on: tighten them as it improves.
  EXPECT_LT(score->ate.position_rmse_m, 1.25);
  EXPECT_LT(score->ate.position_rmse_m, 0.5 * odometry_ate);
  EXPECT_GT(odometry_ate, 1.5);  // the odometry really is bad here (the test means something)
  ASSERT_TRUE(score->map.has_value());
  EXPECT_GT(score->map->segments, 20u);
}

// The learner and the matcher in closed loop through glitches larger than the
// search window (heading glitches of 16-26° against its ± 14°, wheel spins of
// 35-50 cm against ± 0.3 m; five times as frequent as RealOdometryConfig's):
// no local map ends bent by one, and none teaches the odometry model a
// runaway heading bias.
TEST(RealOdometryMission, GlitchesLargerThanTheSearchWindowBendNoLocalMap) {
  sim::MissionConfig sim_config = one_robot_with_heading_glitches(3, 0.28, 0.45);
  sim_config.real_odometry.translation_glitch_rate_per_m = 0.03;
  sim_config.real_odometry.translation_glitch_min_m = 0.35;
  sim_config.real_odometry.translation_glitch_max_m = 0.5;
  const MissionInputs inputs = simulated_inputs(sim_config, "glitch_mission");
  ASSERT_EQ(inputs.robots.size(), 1u);

  // The test means something: increments whose odometry error lies outside the window.
  const LocalMapConfig defaults;
  const std::vector<LaserScan>& scans = inputs.robots[0].scans;
  const std::vector<StampedPose>& truth = inputs.reference.at(inputs.robots[0].robot_id);
  ASSERT_EQ(truth.size(), scans.size());
  int beyond_window = 0;
  for (std::size_t k = 1; k < scans.size(); ++k) {
    const Pose2 e = between(between(truth[k - 1].pose, truth[k].pose), between(scans[k - 1].odometry, scans[k].odometry));
    beyond_window += std::abs(wrap_angle(e.phi)) > defaults.scan_matching.search_window_rad ||
                     std::max(std::abs(e.x), std::abs(e.y)) > defaults.scan_matching.search_window_m;
  }
  EXPECT_GE(beyond_window, 10);

  const OneRobotRun run = run_one_robot(inputs);
  // Measured at the commit that added this test: 26 increments beyond the window,
  // worst local map 1.6°, learned heading bias -0.005 rad/m (the simulated
  // robots' bias has a std of 0.005 rad/m), ATE 0.08 m.
  EXPECT_LT(run.worst_local_map_rad, 4.0 * std::numbers::pi / 180.0);
  EXPECT_LE(std::abs(run.robot.odometry_model.heading_bias_rad_per_m), 0.01);
  EXPECT_LT(run.ate_m, 0.2);
}

// Heading glitches of 26-34°, beyond the search window (± 14°) by more than
// the refinement's basin reaches back: a wrong pose near the glitched prior
// still explains part of the scan there. The escalated search
// (escalating_registration.hpp) finds the turn; no local map ends bent.
TEST(RealOdometryMission, GlitchesBeyondTheRefinementsReachBendNoLocalMap) {
  const sim::MissionConfig sim_config = one_robot_with_heading_glitches(1, 0.45, 0.6);
  const MissionInputs inputs = simulated_inputs(sim_config, "large_glitch_mission");
  ASSERT_EQ(inputs.robots.size(), 1u);

  const OneRobotRun run = run_one_robot(inputs);
  EXPECT_GT(run.robot.matches_from_escalation, 0u);  // the wider search found what the first could not
  // docs/results.md, "The search escalates", has this mission's figures.
  EXPECT_LT(run.worst_local_map_rad, 4.0 * std::numbers::pi / 180.0);
  EXPECT_LT(run.ate_m, 0.2);
}

// A short-range laser (8 m, as many indoor lasers) writes its range for a beam
// with no return, in a log format that does not state it (FLASER). Read as
// returns, those readings draw an arc around the robot that moves with it and
// holds the matches back along a corridor; the learned odometry scale then
// runs to its bound and local maps end metres short. The reader finds the
// no-return reading (no_return_reading.hpp), and no local map ends far off.
TEST(RealOdometryMission, AShortRangeLasersNoReturnReadingsHoldNoLocalMapBack) {
  sim::MissionConfig sim_config;
  sim_config.num_robots = 1;
  sim_config.seed = 3;
  sim_config.duration_s = 600.0;
  sim_config.odometry_model = sim::OdometryModel::kReal;
  sim_config.laser.max_range_m = 8.0;
  const MissionInputs inputs = simulated_inputs(sim_config, "short_range_mission");
  ASSERT_EQ(inputs.robots.size(), 1u);
  ASSERT_FALSE(inputs.robots[0].scans.empty());
  EXPECT_DOUBLE_EQ(inputs.robots[0].scans[0].max_range_m, 8.0);

  const OneRobotRun run = run_one_robot(inputs);
  // Measured at the commit that added this test (docs/results.md, "A short-range
  // laser's no-return reading"): worst local map 0.16 m, learned translation
  // scale 0.993, ATE 0.07 m; with the no-return readings read as returns, 11.2 m,
  // 0.7 (the bound) and 8.3 m.
  EXPECT_LT(run.worst_local_map_m, 0.5);
  EXPECT_NEAR(run.robot.odometry_model.translation_scale, 1.0, 0.05);
  EXPECT_LT(run.ate_m, 0.2);
}

}  // namespace
}  // namespace lmf::mission
