// Tests of the simulator's output folder: byte-identical files for one seed, readable
// CARMEN logs and trajectories that match the mission in memory.
#include <cmath>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <string>

#include <unistd.h>

#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include "lmf/io/carmen.hpp"
#include "lmf/io/trajectory.hpp"
#include "lmf/sim/mission.hpp"
#include "lmf/sim/mission_writer.hpp"

namespace lmf::sim {
namespace {

namespace fs = std::filesystem;

std::string slurp(const fs::path& file) {
  std::ifstream in(file, std::ios::binary);
  return {std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>()};
}

class TempDir {
 public:
  explicit TempDir(const std::string& name)
      : path_(fs::temp_directory_path() / ("lmf_sim_test_" + name + "_" + std::to_string(::getpid()))) {
    fs::remove_all(path_);
  }
  ~TempDir() { fs::remove_all(path_); }
  const fs::path& path() const { return path_; }

 private:
  fs::path path_;
};

MissionConfig short_mission(uint64_t seed) {
  MissionConfig config;
  config.seed = seed;
  config.duration_s = 20.0;
  config.num_robots = 2;
  config.people.count = 3;
  return config;
}

const char* const kFiles[] = {"robot0.log", "robot0.gt", "robot1.log", "robot1.gt", "walls.json",
                              "sightings.json", "world.svg", "mission.json"};

TEST(MissionWriter, SameSeedGivesIdenticalFilesDifferentSeedDifferentFiles) {
  TempDir a("a"), b("b"), c("c");
  write_mission(simulate_mission(short_mission(4)), a.path());
  write_mission(simulate_mission(short_mission(4)), b.path());
  write_mission(simulate_mission(short_mission(5)), c.path());
  for (const char* name : kFiles) {
    ASSERT_TRUE(fs::exists(a.path() / name)) << name;
    const std::string text = slurp(a.path() / name);
    EXPECT_FALSE(text.empty()) << name;
    EXPECT_EQ(text, slurp(b.path() / name)) << name << " differs for the same seed";
  }
  for (const char* name : {"robot0.log", "robot1.log", "walls.json", "world.svg", "mission.json"}) {
    EXPECT_NE(slurp(a.path() / name), slurp(c.path() / name)) << name << " is the same for another seed";
  }
}

TEST(MissionWriter, LogsAndGroundTruthReadBackAsTheMission) {
  TempDir dir("read");
  const Mission mission = simulate_mission(short_mission(6));
  write_mission(mission, dir.path());
  io::CarmenReadOptions options;
  options.flaser_max_range_m = mission.config.laser.max_range_m;
  for (const auto& run : mission.robots) {
    const std::string name = "robot" + std::to_string(run.id);
    const io::CarmenLog log = io::read_carmen_log(dir.path() / (name + ".log"), options);
    ASSERT_EQ(log.scans.size(), run.scans.size());
    const auto truth = io::read_trajectory(dir.path() / (name + ".gt"));
    ASSERT_EQ(truth.size(), run.true_poses.size());
    for (std::size_t k = 0; k < run.scans.size(); ++k) {
      const LaserScan& got = log.scans[k];
      const LaserScan& want = run.scans[k];
      ASSERT_EQ(got.utime, want.utime);
      ASSERT_EQ(truth[k].utime, want.utime);
      ASSERT_TRUE(is_near(got.odometry, want.odometry, 1e-6, 1e-6));
      ASSERT_TRUE(is_near(truth[k].pose, run.true_poses[k], 1e-6, 1e-6));
      ASSERT_EQ(got.ranges_m.size(), want.ranges_m.size());
      ASSERT_NEAR(got.angle_increment_rad, want.angle_increment_rad, 1e-12);
      for (std::size_t i = 0; i < want.ranges_m.size(); ++i) ASSERT_NEAR(got.ranges_m[i], want.ranges_m[i], 5e-4);
    }
  }
  // walls.json holds every wall face and the loop; sightings.json every sighting.
  const auto walls = nlohmann::json::parse(slurp(dir.path() / "walls.json"));
  ASSERT_EQ(walls.at("walls").size(), mission.world.walls.size());
  EXPECT_EQ(walls.at("seed").get<uint64_t>(), 6u);
  EXPECT_GE(walls.at("loop_length_m").get<double>(), 100.0);
  const auto& w0 = walls.at("walls")[0];
  EXPECT_NEAR(w0[0].get<double>(), mission.world.walls[0].a.x(), 1e-6);
  EXPECT_NEAR(w0[3].get<double>(), mission.world.walls[0].b.y(), 1e-6);
  const auto sightings = nlohmann::json::parse(slurp(dir.path() / "sightings.json"));
  ASSERT_EQ(sightings.at("sightings").size(), mission.sightings.size());
  ASSERT_FALSE(mission.sightings.empty());
  const auto& s0 = sightings.at("sightings")[0];
  EXPECT_EQ(s0.at("observer").get<int>(), mission.sightings[0].observer);
  EXPECT_NEAR(s0.at("x_AB")[0].get<double>(), mission.sightings[0].x_AB.x, 1e-6);
  const auto params = nlohmann::json::parse(slurp(dir.path() / "mission.json"));
  EXPECT_EQ(params.at("config").at("num_robots").get<int>(), 2);
  EXPECT_EQ(params.at("config").at("laser").at("num_beams").get<int>(), 361);
  EXPECT_EQ(params.at("robots").size(), 2u);
}

}  // namespace
}  // namespace lmf::sim
