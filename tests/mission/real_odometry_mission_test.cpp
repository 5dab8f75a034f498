// A 3-robot simulated mission whose odometry behaves like a real robot's (lmf/sim/odometry.hpp,
// RealOdometry: per-robot scale errors, heading bias, slip, heading noise, glitches), mapped in
// process by OfflineMission with the built-in default configuration.
#include <cmath>
#include <filesystem>
#include <string>

#include <gtest/gtest.h>
#include <unistd.h>

#include "lmf/mission/mission_inputs.hpp"
#include "lmf/mission/mission_report.hpp"
#include "lmf/mission/offline_mission.hpp"
#include "lmf/sim/mission.hpp"
#include "lmf/sim/mission_writer.hpp"

namespace lmf::mission {
namespace {

TEST(RealOdometryMission, ThreeRobotsJoinFuseEveryLocalMapAndStayNearTheTruth) {
  sim::MissionConfig sim_config;
  sim_config.num_robots = 3;
  sim_config.seed = 2;
  sim_config.duration_s = 240.0;  // 4 minutes, ~110 m per robot
  sim_config.odometry_model = sim::OdometryModel::kReal;
  const std::filesystem::path dir =
      std::filesystem::temp_directory_path() / ("lmf_real_odometry_mission_" + std::to_string(::getpid()));
  sim::write_mission(sim::simulate_mission(sim_config), dir);
  const MissionInputs inputs = load_sim_folder(dir, SightingNoise{});
  std::filesystem::remove_all(dir);
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

}  // namespace
}  // namespace lmf::mission
