#include "lmf/mission/offline_mission.hpp"

#include <algorithm>
#include <cstdint>
#include <deque>
#include <filesystem>
#include <string>
#include <system_error>
#include <utility>

#include <gtest/gtest.h>

#include "lmf/mission/config_file.hpp"
#include "lmf/mission/mission_inputs.hpp"
#include "lmf/mission/mission_report.hpp"
#include "lmf/sim/mission.hpp"
#include "lmf/sim/mission_writer.hpp"
#include "test_support.hpp"

namespace lmf::mission {
namespace {

// A short two-robot simulated mission written to a temporary folder once.
// A 2-robot, 150 s simulator mission, written once per seed and process.
// The folder is removed when the process ends; one left behind by an earlier
// process with the same id is removed before writing, so nothing stale is read.
struct SimulatedFolder {
  explicit SimulatedFolder(std::filesystem::path p) : path(std::move(p)) {}
  SimulatedFolder(const SimulatedFolder&) = delete;
  SimulatedFolder& operator=(const SimulatedFolder&) = delete;
  std::filesystem::path path;
  ~SimulatedFolder() {
    std::error_code ec;
    std::filesystem::remove_all(path, ec);
  }
};

std::filesystem::path write_simulated_folder(std::uint64_t seed) {
  sim::MissionConfig config;
  config.num_robots = 2;
  config.duration_s = 150.0;
  config.seed = seed;
  static std::deque<SimulatedFolder> written;  // deque: push_back moves none of them
  const std::filesystem::path out = std::filesystem::temp_directory_path() /
                                    ("lmf_mission_test_" + std::to_string(::getpid()) + "_" + std::to_string(seed));
  std::filesystem::remove_all(out);
  sim::write_mission(sim::simulate_mission(config), out);
  written.emplace_back(out);
  return out;
}

const std::filesystem::path& simulated_folder() {
  static const std::filesystem::path dir = write_simulated_folder(3);
  return dir;
}

MissionResult run(const MissionInputs& inputs, MissionConfig config = {}) {
  OfflineMission mission(config, inputs);
  return mission.run();
}

TEST(OfflineMission, SimulatedTwoRobotMissionJoinsBySightingAndMaps) {
  const MissionInputs inputs = load_sim_folder(simulated_folder(), SightingNoise{});
  ASSERT_EQ(inputs.robots.size(), 2u);
  ASSERT_FALSE(inputs.sightings.empty());
  // The configuration shipped for the simulator's laser (config/sim.json).
  OfflineMission mission(load_mission_config(std::string(LMF_CONFIG_DIR) + "/sim.json"), inputs);
  const MissionResult result = mission.run();
  for (const RobotResult& r : result.robots) {
    SCOPED_TRACE(r.name);
    EXPECT_TRUE(r.joined);
    EXPECT_EQ(r.trajectory.size(), r.scans);  // every scan has a final pose
    EXPECT_EQ(r.local_maps_fused, r.local_maps_shipped);
    EXPECT_TRUE(r.covariance_always_ok) << r.first_covariance_problem;
    // The simulator's laser has the same noise at every range. The estimator
    // reads it as 0 to 0.0018 (seeds 1-4, scans 0.2 m apart), below the 0.0023
    // it reads for noise of 0.5 % of the range (docs/results.md).
    EXPECT_GT(r.range_noise_matches, 0U);
    EXPECT_LT(r.range_noise_per_m, 0.0022);
    EXPECT_GT(r.point_sigma_m, 0.0);
  }
  EXPECT_TRUE(result.global_covariance_always_ok);
  const auto score = score_mission(result, mission.inputs(), mission.global_map());
  ASSERT_TRUE(score.has_value());
  // Odometry alone drifts by metres over this mission; the map keeps the robots
  // within a decimetre of the truth in one common frame.
  EXPECT_LT(score->ate.position_rmse_m, 0.1);
  for (const RobotScore& s : score->robots) EXPECT_LT(s.ate.position_rmse_m, s.odometry_ate.position_rmse_m);
  EXPECT_GT(mission.global_map().counts().segments, 20);
}

// Every fusion of the simulator's mission (which has a reference for every
// scan) is checked against it; the first robot's first frame defines W, so its
// predicted error is zero, and no frame is far from the truth on a mission whose
// ATE is centimetres.
TEST(OfflineMission, FusionFrameChecksFollowTheReference) {
  const MissionInputs inputs = load_sim_folder(simulated_folder(), SightingNoise{});
  OfflineMission mission(load_mission_config(std::string(LMF_CONFIG_DIR) + "/sim.json"), inputs);
  const MissionResult result = mission.run();
  ASSERT_EQ(result.fusion_frame_checks.size(), result.fusions.size());
  const auto first = std::find_if(result.fusion_frame_checks.begin(), result.fusion_frame_checks.end(),
                                  [&](const FusionFrameCheck& c) { return c.robot_id == inputs.robots.front().robot_id && c.seq == 0; });
  ASSERT_NE(first, result.fusion_frame_checks.end());
  EXPECT_LT(first->before_m, 1e-6);
  EXPECT_LT(first->before_rad, 1e-6);
  for (const FusionFrameCheck& c : result.fusion_frame_checks) {
    SCOPED_TRACE("robot " + std::to_string(c.robot_id) + " map " + std::to_string(c.seq));
    EXPECT_LT(c.before_m, 0.3);
    EXPECT_LT(c.after_m, 0.3);
    EXPECT_LT(c.after_rad, 0.05);
  }
}

// --no-sightings: the first robot defines W; without a sighting the second
// joins where one of its local maps is recognised in the global map
// (place_recognition.hpp, turned on), and with place recognition off (the
// default) it never joins: its local maps wait in the server's queue, not lost.
TEST(OfflineMission, WithoutSightingsTheOtherRobotJoinsByPlaceOrWaits) {
  MissionInputs inputs = load_sim_folder(simulated_folder(), SightingNoise{});
  ASSERT_FALSE(inputs.sightings.empty());
  drop_sightings(inputs);
  EXPECT_TRUE(inputs.sightings.empty());
  ASSERT_FALSE(inputs.notes.empty());
  EXPECT_NE(inputs.notes.back().find("no sightings"), std::string::npos) << inputs.notes.back();
  const MissionConfig config = load_mission_config(std::string(LMF_CONFIG_DIR) + "/sim.json");
  ASSERT_FALSE(config.global_map.place_recognition.enabled);
  {
    MissionConfig on = config;
    on.global_map.place_recognition.enabled = true;
    OfflineMission mission(on, inputs);
    const MissionResult result = mission.run();
    ASSERT_EQ(result.robots.size(), 2U);
    EXPECT_TRUE(result.robots[0].joined);
    ASSERT_TRUE(result.robots[1].joined);
    ASSERT_TRUE(result.robots[1].join.has_value());
    EXPECT_EQ(result.robots[1].join->how, fusion::JoinKind::kPlace);
    EXPECT_EQ(result.robots[1].local_maps_fused, result.robots[1].local_maps_shipped);
    EXPECT_EQ(mission.global_map().queued_count(), 0);
    EXPECT_EQ(mission.global_map().place_recognition_counts().placed, 1);
  }
  OfflineMission mission(config, inputs);
  const MissionResult result = mission.run();
  EXPECT_TRUE(result.robots[0].joined);
  EXPECT_GT(result.robots[0].local_maps_fused, 0U);
  EXPECT_FALSE(result.robots[1].joined);
  EXPECT_EQ(result.robots[1].local_maps_fused, 0U);
  EXPECT_GT(result.robots[1].local_maps_shipped, 0U);
  EXPECT_EQ(static_cast<std::size_t>(mission.global_map().queued_count()), result.robots[1].local_maps_shipped);
}

TEST(OfflineMission, FusionFrameChecksCountNoticeableMoves) {
  const std::vector<FusionFrameCheck> checks = {
      {0, 1, 0.30, 0.00, 0.10, 0.00},  // 0.2 m closer
      {0, 2, 0.10, 0.00, 0.15, 0.00},  // 5 cm farther: not noticeable
      {1, 3, 0.28, 0.01, 1.18, 0.01},  // 0.9 m farther: the farthest
      {1, 4, 0.20, 0.00, 0.20, 0.03},  // 1.7 deg farther
  };
  const std::string line = describe_fusion_frame_checks(checks);
  EXPECT_NE(line.find("each of 4): 1 moved it 0.1 m or 1 deg closer, 2 farther"), std::string::npos) << line;
  EXPECT_NE(line.find("robot 1 map 3, 0.28 m"), std::string::npos) << line;
}

// Robot footprints on the simulator (its robots see each other as discs): the
// segments they remove were no walls. With and without them, the same segments
// match a wall; those that do not are fewer by exactly the number removed.
TEST(OfflineMission, RobotFootprintsRemoveBodiesAndNoWall) {
  // Seed 1: one robot's body ends up in the other's local maps (seed 3's no
  // longer does since the scan match tells small moving objects apart).
  static const std::filesystem::path folder = write_simulated_folder(1);
  const MissionInputs inputs = load_sim_folder(folder, SightingNoise{});
  MissionConfig with = load_mission_config(std::string(LMF_CONFIG_DIR) + "/sim.json");
  ASSERT_GT(with.global_map.footprint_radius_m, 0.0);
  MissionConfig without = with;
  without.global_map.footprint_radius_m = 0.0;
  OfflineMission a(with, inputs);
  OfflineMission b(without, inputs);
  const MissionResult ra = a.run();
  const MissionResult rb = b.run();
  int removed = 0;
  for (const fusion::FusionReport& f : ra.fusions) removed += f.footprint_segments_removed;
  for (const fusion::FusionReport& f : rb.fusions) EXPECT_EQ(f.footprint_segments_removed, 0);
  EXPECT_GE(removed, 1);  // one robot seen standing by the other
  const auto sa = score_mission(ra, a.inputs(), a.global_map());
  const auto sb = score_mission(rb, b.inputs(), b.global_map());
  ASSERT_TRUE(sa && sa->map && sb && sb->map);
  EXPECT_EQ(a.global_map().counts().segments + removed, b.global_map().counts().segments);
  EXPECT_EQ(sa->map->segments + static_cast<std::size_t>(removed), sb->map->segments);
  EXPECT_EQ(sa->map->segments - sa->map->unmatched_segments, sb->map->segments - sb->map->unmatched_segments);
  EXPECT_EQ(sa->map->unmatched_segments + static_cast<std::size_t>(removed), sb->map->unmatched_segments);
  EXPECT_NEAR(sa->ate.position_rmse_m, sb->ate.position_rmse_m, 1e-3);
}

// Crossing segments on the simulator: what they remove is, nearly all, segments
// that match no wall (bad fits of noisy walls), and the trajectory does not suffer.
TEST(OfflineMission, CrossingSegmentsRemoveBadFitsNotWalls) {
  const MissionInputs inputs = load_sim_folder(simulated_folder(), SightingNoise{});
  MissionConfig with = load_mission_config(std::string(LMF_CONFIG_DIR) + "/sim.json");
  ASSERT_GT(with.global_map.crossing_margin_m, 0.0);
  MissionConfig without = with;
  without.global_map.crossing_margin_m = 0.0;
  OfflineMission a(with, inputs);
  OfflineMission b(without, inputs);
  const MissionResult ra = a.run();
  const MissionResult rb = b.run();
  int removed = 0;
  for (const fusion::FusionReport& f : ra.fusions) removed += f.crossing_segments_removed;
  for (const fusion::FusionReport& f : rb.fusions) EXPECT_EQ(f.crossing_segments_removed, 0);
  const auto sa = score_mission(ra, a.inputs(), a.global_map());
  const auto sb = score_mission(rb, b.inputs(), b.global_map());
  ASSERT_TRUE(sa && sa->map && sb && sb->map);
  const std::size_t matched_a = sa->map->segments - sa->map->unmatched_segments;
  const std::size_t matched_b = sb->map->segments - sb->map->unmatched_segments;
  // Seed 3, 2 robots: 6 removed; 7 -> 3 match no wall (the scorer accepts fits
  // up to 0.3 rad off, so some bad fits count as matched: the RMS goes down,
  // not up); the same ATE. At least two thirds of what goes matched no wall.
  EXPECT_GE(removed, 4);
  EXPECT_LE(3 * (sa->map->unmatched_segments) + 2 * static_cast<std::size_t>(removed), 3 * sb->map->unmatched_segments);
  EXPECT_GE(matched_a + 5, matched_b);
  EXPECT_LE(sa->map->rms_m, sb->map->rms_m + 1e-4);
  EXPECT_NEAR(sa->ate.position_rmse_m, sb->ate.position_rmse_m, 2e-3);
}

TEST(OfflineMission, RepeatedRunsAreIdentical) {
  const MissionInputs inputs = load_sim_folder(simulated_folder(), SightingNoise{});
  const MissionResult a = run(inputs);
  const MissionResult b = run(inputs);
  ASSERT_EQ(a.robots.size(), b.robots.size());
  for (std::size_t i = 0; i < a.robots.size(); ++i) {
    ASSERT_EQ(a.robots[i].trajectory.size(), b.robots[i].trajectory.size());
    for (std::size_t k = 0; k < a.robots[i].trajectory.size(); ++k) {
      EXPECT_EQ(a.robots[i].trajectory[k].pose.x, b.robots[i].trajectory[k].pose.x);
      EXPECT_EQ(a.robots[i].trajectory[k].pose.phi, b.robots[i].trajectory[k].pose.phi);
    }
  }
}

// Files of an earlier, larger mission left in the folder are not replayed:
// mission.json says how many robots there are.
TEST(OfflineMission, SimFolderReadsTheRobotsItsMissionLists) {
  const std::filesystem::path dir =
      std::filesystem::temp_directory_path() / ("lmf_mission_stale_" + std::to_string(::getpid()));
  std::filesystem::remove_all(dir);
  std::filesystem::create_directories(dir);
  for (const char* name : {"mission.json", "robot0.log", "robot0.gt", "robot1.log", "robot1.gt", "sightings.json",
                           "walls.json"}) {
    std::filesystem::copy_file(simulated_folder() / name, dir / name);
  }
  std::filesystem::copy_file(dir / "robot1.log", dir / "robot2.log");  // stale
  EXPECT_EQ(load_sim_folder(dir, SightingNoise{}).robots.size(), 2u);
  std::filesystem::remove(dir / "robot1.log");
  try {
    load_sim_folder(dir, SightingNoise{});
    ADD_FAILURE() << "a robot the mission lists is missing";
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find("robot1.log is missing"), std::string::npos) << e.what();
  }
  std::filesystem::remove_all(dir);
}

TEST(OfflineMission, RejectsDuplicateRobotIds) {
  MissionInputs inputs;
  inputs.robots.resize(2);
  EXPECT_THROW(OfflineMission(MissionConfig{}, inputs), std::invalid_argument);
  EXPECT_THROW(OfflineMission(MissionConfig{}, MissionInputs{}), std::invalid_argument);
}

TEST(OfflineMission, TimingStatsUseNearestRank) {
  std::vector<double> d;
  for (int i = 1; i <= 200; ++i) d.push_back(i);
  const TimingStats s = timing_stats(d);
  EXPECT_EQ(s.count, 200u);
  EXPECT_DOUBLE_EQ(s.p50_ms, 100.0);
  EXPECT_DOUBLE_EQ(s.p99_ms, 198.0);
  EXPECT_DOUBLE_EQ(s.max_ms, 200.0);
  EXPECT_DOUBLE_EQ(s.mean_ms, 100.5);
}

// The acceptance figure on the real log with one robot: ATE <= 0.25 m
// (odometry alone: about 4 m). The split runs are reported in the README; they
// do not meet that figure yet.
TEST(Belgioioso, OneRobotAteWithinQuarterMetre) {
  LMF_REQUIRE_DATASETS(dir);
  const MissionInputs inputs =
      load_logs({dir / "belgioioso-noisy.log.gz"}, 1, dir / "belgioioso-noisy.gt", SightingNoise{});
  OfflineMission mission(MissionConfig{}, inputs);
  const MissionResult result = mission.run();
  const auto score = score_mission(result, mission.inputs(), mission.global_map());
  ASSERT_TRUE(score.has_value());
  EXPECT_EQ(score->ate.count, 395u);
  EXPECT_LT(score->ate.position_rmse_m, 0.25);
  EXPECT_TRUE(result.global_covariance_always_ok);
}

}  // namespace
}  // namespace lmf::mission
