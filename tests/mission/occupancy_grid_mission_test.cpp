// lmf-grid on a short simulated mission (lmf-sim -> lmf-offline -> lmf-grid):
// the true walls the robots saw up close are occupied and the corridor
// centrelines they drove are free, within one cell, and map.yaml holds what
// lmf-grid wrote.
#include <sys/wait.h>
#include <unistd.h>

#include <cmath>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <map>
#include <set>
#include <sstream>
#include <string>
#include <utility>
#include <vector>

#include <gtest/gtest.h>

#include "lmf/mission/config_file.hpp"
#include "lmf/mission/mission_inputs.hpp"
#include "lmf/mission/mission_report.hpp"
#include "lmf/mission/offline_mission.hpp"
#include "lmf/sim/mission.hpp"
#include "lmf/sim/mission_writer.hpp"

namespace lmf {
namespace {

namespace fs = std::filesystem;
constexpr double kResolution = 0.05;

// map.yaml's `key: value` lines (the flat subset of YAML that map_server reads).
std::map<std::string, std::string> read_yaml(const fs::path& file) {
  std::map<std::string, std::string> values;
  std::ifstream in(file);
  for (std::string line; std::getline(in, line);) {
    const auto colon = line.find(':');
    if (colon == std::string::npos) continue;
    values[line.substr(0, colon)] = line.substr(line.find_first_not_of(' ', colon + 1));
  }
  return values;
}

struct Pgm {
  int width = 0;
  int height = 0;
  std::string pixels;  // top row first
  uint8_t at(int col, int row_from_bottom) const {
    return static_cast<uint8_t>(pixels[static_cast<std::size_t>(height - 1 - row_from_bottom) * width + col]);
  }
};

Pgm read_pgm(const fs::path& file) {
  std::ifstream in(file, std::ios::binary);
  std::string magic;
  in >> magic;
  EXPECT_EQ(magic, "P5");
  const auto skip_comments = [&] {
    in >> std::ws;
    while (in.peek() == '#') {
      std::string comment;
      std::getline(in, comment);
      in >> std::ws;
    }
  };
  Pgm pgm;
  int max_value = 0;
  skip_comments();
  in >> pgm.width;
  skip_comments();
  in >> pgm.height;
  skip_comments();
  in >> max_value;
  EXPECT_EQ(max_value, 255);
  in.get();  // the single whitespace before the pixels
  pgm.pixels.resize(static_cast<std::size_t>(pgm.width) * pgm.height);
  in.read(pgm.pixels.data(), static_cast<std::streamsize>(pgm.pixels.size()));
  EXPECT_EQ(in.gcount(), static_cast<std::streamsize>(pgm.pixels.size()));
  return pgm;
}

class OccupancyGridMission : public ::testing::Test {
 protected:
  static void SetUpTestSuite() {
    dir_ = new fs::path(fs::temp_directory_path() / ("lmf_grid_mission_" + std::to_string(::getpid())));
    sim::MissionConfig config;
    config.seed = 3;
    config.num_robots = 2;
    config.duration_s = 90.0;
    mission_ = new sim::Mission(sim::simulate_mission(config));
    sim::write_mission(*mission_, *dir_ / "sim");
    mission::MissionConfig mission_config = mission::load_mission_config(std::string(LMF_CONFIG_DIR) + "/sim.json");
    // This test is about the grid, so it maps with the odometry model the
    // simulator really has (the configured prior): the learned model still
    // costs the simulator accuracy (docs/results.md, "Accuracy").
    mission_config.local_map.odometry_learning.enabled = false;
    mission::OfflineMission offline(mission_config, mission::load_sim_folder(*dir_ / "sim", mission_config.sighting_noise));
    const mission::MissionResult result = offline.run();
    mission::write_mission_outputs(*dir_ / "out", offline, result,
                                   mission::score_mission(result, offline.inputs(), offline.global_map()));
    const std::string command = std::string(LMF_GRID_EXE) + " --map " + (*dir_ / "out/map.json").string() +
                                " --trajectory " + (*dir_ / "out/trajectories").string() + " --sim " +
                                (*dir_ / "sim").string() + " --resolution 0.05 --out " + (*dir_ / "grid").string();
    status_ = std::system(command.c_str());
  }
  static void TearDownTestSuite() {
    fs::remove_all(*dir_);
    delete dir_;
    delete mission_;
  }

  // The map frame W is robot 0's pose at its first scan: x_sim_W.
  static Pose2 x_sim_W() { return mission_->robots.front().true_poses.front(); }

  static fs::path* dir_;
  static sim::Mission* mission_;
  static int status_;
};
fs::path* OccupancyGridMission::dir_ = nullptr;
sim::Mission* OccupancyGridMission::mission_ = nullptr;
int OccupancyGridMission::status_ = -1;

TEST_F(OccupancyGridMission, YamlHoldsTheRosMapServerKeys) {
  ASSERT_EQ(status_, 0);
  const auto yaml = read_yaml(*dir_ / "grid/map.yaml");
  EXPECT_EQ(yaml.at("image"), "map.pgm");
  EXPECT_DOUBLE_EQ(std::stod(yaml.at("resolution")), kResolution);
  EXPECT_EQ(yaml.at("negate"), "0");
  EXPECT_DOUBLE_EQ(std::stod(yaml.at("occupied_thresh")), 0.65);
  EXPECT_DOUBLE_EQ(std::stod(yaml.at("free_thresh")), 0.196);
  EXPECT_EQ(yaml.at("mode"), "trinary");
  double x = 0, y = 0, yaw = 1;
  ASSERT_EQ(std::sscanf(yaml.at("origin").c_str(), "[%lf, %lf, %lf]", &x, &y, &yaw), 3) << yaml.at("origin");
  EXPECT_EQ(yaw, 0.0);
  // The origin is the lower-left corner: it lies below and left of robot 0's start (W's origin).
  EXPECT_LT(x, 0.0);
  EXPECT_LT(y, 0.0);
}

TEST_F(OccupancyGridMission, TrueWallsAreOccupiedAndCorridorCentresFree) {
  ASSERT_EQ(status_, 0);
  const auto yaml = read_yaml(*dir_ / "grid/map.yaml");
  double ox = 0, oy = 0, yaw = 0;
  ASSERT_EQ(std::sscanf(yaml.at("origin").c_str(), "[%lf, %lf, %lf]", &ox, &oy, &yaw), 3);
  const Pgm pgm = read_pgm(*dir_ / "grid/map.pgm");
  ASSERT_GT(pgm.width, 0);
  const Pose2 to_W = inverse(x_sim_W());
  // Whether any cell within one cell of a sim-frame point has the pixel value.
  const auto near_value = [&](const Eigen::Vector2d& p_sim, uint8_t value) {
    const Eigen::Vector2d p = to_W.transform_point(p_sim);
    const int col = static_cast<int>(std::floor((p.x() - ox) / kResolution));
    const int row = static_cast<int>(std::floor((p.y() - oy) / kResolution));
    for (int dr = -1; dr <= 1; ++dr) {
      for (int dc = -1; dc <= 1; ++dc) {
        const int c = col + dc, r = row + dr;
        if (c >= 0 && r >= 0 && c < pgm.width && r < pgm.height && pgm.at(c, r) == value) return true;
      }
    }
    return false;
  };

  // What the robots saw up close: their beams' end points from the true poses,
  // per sim-frame cell, within kCloseRange_m (where the 0.5 degree beams put a
  // point every 4.4 cm, less than a cell, so a wall seen there is a dense line
  // that the extraction maps; farther walls seen at grazing angles may not be mapped).
  constexpr double kCloseRange_m = 5.0;
  std::map<std::pair<int, int>, int> returns;
  const auto key = [](const Eigen::Vector2d& p) {
    return std::pair<int, int>(static_cast<int>(std::floor(p.x() / kResolution)),
                               static_cast<int>(std::floor(p.y() / kResolution)));
  };
  std::vector<Eigen::Vector2d> driven;
  for (const sim::RobotRun& robot : mission_->robots) {
    for (std::size_t k = 0; k < robot.scans.size(); ++k) {
      driven.emplace_back(robot.true_poses[k].x, robot.true_poses[k].y);
      for (std::size_t i = 0; i < robot.scans[k].ranges_m.size(); ++i) {
        if (robot.scans[k].ranges_m[i] > kCloseRange_m) continue;
        ++returns[key(robot.true_poses[k].transform_point(robot.scans[k].beam_point(i)))];
      }
    }
  }
  const auto seen = [&](const Eigen::Vector2d& p) {
    const auto [c, r] = key(p);
    int n = 0;
    for (int dr = -1; dr <= 1; ++dr) {
      for (int dc = -1; dc <= 1; ++dc) {
        const auto it = returns.find({c + dc, r + dr});
        if (it != returns.end()) n += it->second;
      }
    }
    return n >= 5;
  };

  int wall_samples = 0, wall_occupied = 0;  // 5 cm samples of the true wall faces seen up close
  for (const sim::Wall& wall : mission_->world.walls) {
    const int n = static_cast<int>(wall.length() / kResolution);
    for (int i = 0; i <= n; ++i) {
      const Eigen::Vector2d p = wall.a + (wall.b - wall.a) * (n > 0 ? static_cast<double>(i) / n : 0.0);
      if (!seen(p)) continue;
      ++wall_samples;
      wall_occupied += near_value(p, 0) ? 1 : 0;
    }
  }
  int centre_samples = 0, centre_free = 0, centre_occupied = 0;
  for (const sim::Wall& run : mission_->world.corridor_runs) {
    const int n = static_cast<int>(run.length() / kResolution);
    for (int i = 0; i <= n; ++i) {
      const Eigen::Vector2d p = run.a + (run.b - run.a) * (n > 0 ? static_cast<double>(i) / n : 0.0);
      bool passed = false;  // a robot drove within 1 m
      for (const Eigen::Vector2d& q : driven) passed = passed || (q - p).norm() < 1.0;
      if (!passed) continue;
      ++centre_samples;
      centre_free += near_value(p, 254) ? 1 : 0;
      centre_occupied += near_value(p, 0) ? 1 : 0;
    }
  }
  std::cout << "seen true wall samples: " << wall_samples << ", occupied within one cell: " << wall_occupied
            << "; driven corridor centre samples: " << centre_samples << ", free: " << centre_free
            << ", occupied within one cell: " << centre_occupied << "\n";
  ASSERT_GT(wall_samples, 500);
  ASSERT_GT(centre_samples, 200);
  // The map's walls lie where the mission put them, a few centimetres off
  // the truth along the corridors (their open direction): 84 % of the samples
  // are within one 5 cm cell (the vertical walls 2.2 cm off on average).
  EXPECT_GE(wall_occupied, 0.8 * wall_samples);
  EXPECT_EQ(centre_free, centre_samples);
  EXPECT_LE(centre_occupied, 0.01 * centre_samples);
}

TEST_F(OccupancyGridMission, OneTrajectoryFileForTwoRobotsIsRefused) {
  // trajectory.txt holds both robots in time order: which pose is whose is not known.
  const std::string command = std::string(LMF_GRID_EXE) + " --map " + (*dir_ / "out/map.json").string() +
                              " --trajectory " + (*dir_ / "out/trajectory.txt").string() + " --sim " +
                              (*dir_ / "sim").string() + " --out " + (*dir_ / "grid2").string() + " 2>/dev/null";
  const int status = std::system(command.c_str());
  ASSERT_TRUE(WIFEXITED(status));
  EXPECT_EQ(WEXITSTATUS(status), 1);
  EXPECT_FALSE(fs::exists(*dir_ / "grid2/map.pgm"));
}

}  // namespace
}  // namespace lmf
