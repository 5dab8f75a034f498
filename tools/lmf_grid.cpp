// lmf-grid: the occupancy grid of a finished mission (lmf/io/occupancy_grid.hpp)
// as ROS map_server reads it: free space from the scans cast from their
// corrected poses, occupied cells from the map's wall segments. See --help.
#include <filesystem>
#include <iostream>
#include <map>
#include <string>
#include <vector>

#include <boost/program_options.hpp>

#include "lmf/io/config.hpp"
#include "lmf/io/occupancy_grid.hpp"
#include "lmf/io/trajectory.hpp"
#include "lmf/mission/mission_inputs.hpp"
#include "tools/tool_support.hpp"

namespace po = boost::program_options;

namespace {

struct Options {
  std::string map_file;
  std::string trajectory;
  std::vector<std::string> logs;
  int split = 1;
  std::string sim_dir;
  double resolution_m = 0.05;
  std::string out_dir;
  std::string name = "map";
};

// map.json's segments (lmf/fusion/map_export.hpp, format "lmf-map").
std::vector<lmf::io::WallSegment> read_map_walls(const std::filesystem::path& file) {
  const nlohmann::json doc = lmf::io::read_json_file(file);
  if (doc.value("format", "") != "lmf-map" || !doc.contains("segments") || !doc["segments"].is_array()) {
    throw std::runtime_error(file.string() + ": not an lmf map.json (format \"lmf-map\" with \"segments\")");
  }
  std::vector<lmf::io::WallSegment> walls;
  for (const auto& s : doc["segments"]) {
    const auto point = [&](const char* key) {
      const auto& p = s.at(key);
      return Eigen::Vector2d(p.at(0).get<double>(), p.at(1).get<double>());
    };
    walls.push_back({point("start"), point("end")});
  }
  return walls;
}

// Each robot's corrected poses by scan time: --trajectory is lmf-offline's (or
// lmf-server's) trajectories/ folder (NAME.txt per robot), or one file when
// there is one robot.
std::map<std::string, std::map<int64_t, lmf::Pose2>> read_corrected_poses(
    const std::filesystem::path& path, const std::vector<lmf::mission::RobotLog>& robots) {
  std::map<std::string, std::map<int64_t, lmf::Pose2>> poses;
  const auto read = [&](const std::filesystem::path& file, const std::string& name) {
    for (const lmf::StampedPose& p : lmf::io::read_trajectory(file)) poses[name][p.utime] = p.pose;
  };
  if (std::filesystem::is_directory(path)) {
    for (const auto& robot : robots) {
      const auto file = path / (robot.name + ".txt");
      if (std::filesystem::exists(file)) {
        read(file, robot.name);
      } else {
        std::cerr << "lmf-grid: no " << file.string() << ": " << robot.name << "'s scans are left out\n";
      }
    }
  } else if (robots.size() == 1) {
    read(path, robots.front().name);
  } else {
    throw std::runtime_error(std::to_string(robots.size()) + " robots but --trajectory " + path.string() +
                             " is one file: give the trajectories/ folder (one NAME.txt per robot)");
  }
  return poses;
}

int run(const Options& o) {
  const lmf::mission::MissionInputs inputs = o.sim_dir.empty()
                                                 ? lmf::mission::load_logs({o.logs.begin(), o.logs.end()}, o.split, "", {})
                                                 : lmf::mission::load_sim_folder(o.sim_dir, {});
  const auto poses = read_corrected_poses(o.trajectory, inputs.robots);
  std::vector<lmf::io::PosedScan> scans;
  std::size_t without_pose = 0;
  for (const auto& robot : inputs.robots) {
    const auto it = poses.find(robot.name);
    for (const lmf::LaserScan& scan : robot.scans) {
      const lmf::Pose2* pose = nullptr;
      if (it != poses.end()) {
        const auto p = it->second.find(scan.utime);
        if (p != it->second.end()) pose = &p->second;
      }
      if (pose == nullptr) {
        ++without_pose;
        continue;
      }
      scans.push_back({*pose, &scan});
    }
  }
  if (scans.empty()) throw std::runtime_error("no scan has a pose in " + o.trajectory + " (wrong folder or log?)");

  lmf::io::OccupancyGridConfig config;
  config.resolution_m = o.resolution_m;
  const auto walls = read_map_walls(o.map_file);
  const lmf::io::OccupancyGrid grid = lmf::io::make_occupancy_grid(scans, walls, config);
  lmf::io::write_ros_map(grid, o.out_dir, o.name);
  std::cout << "lmf-grid: " << scans.size() << " scans (" << without_pose << " without a corrected pose, left out), "
            << walls.size() << " wall segments -> " << grid.width << " x " << grid.height << " cells of "
            << grid.resolution_m << " m: " << grid.count(lmf::io::GridCell::kFree) << " free, "
            << grid.count(lmf::io::GridCell::kOccupied) << " occupied; wrote " << o.out_dir << "/" << o.name
            << ".{pgm,yaml}\n";
  return 0;
}

}  // namespace

int main(int argc, char** argv) {
  Options o;
  po::options_description options(
      "lmf-grid: the occupancy grid of a finished mission for ROS map_server (NAME.pgm + NAME.yaml, trinary):\n"
      "free space from the scans cast from their corrected poses, occupied cells from the map's walls.\n\n"
      "Usage: lmf-grid --map OUT/map.json --trajectory OUT/trajectories (--log FILE... [--split N] | --sim DIR)\n"
      "                [--resolution 0.05] --out DIR\n\n"
      "Options");
  options.add_options()("help,h", "print this help")(
      "map", po::value(&o.map_file)->required(), "map.json of lmf-offline or lmf-server")(
      "trajectory", po::value(&o.trajectory)->required(),
      "corrected poses: the trajectories/ folder (one NAME.txt per robot), or one trajectory file for one robot")(
      "log", po::value(&o.logs), "the mission's CARMEN log(s), as given to lmf-offline")(
      "split", po::value(&o.split)->default_value(1), "as given to lmf-offline")(
      "sim", po::value(&o.sim_dir), "the mission's lmf-sim folder, as given to lmf-offline")(
      "resolution", po::value(&o.resolution_m)->default_value(0.05), "cell size (m)")(
      "name", po::value(&o.name)->default_value("map"), "file names: NAME.pgm, NAME.yaml")(
      "out", po::value(&o.out_dir)->required(), "output folder (created)");
  const auto check = [&] {
    if (o.logs.empty() == o.sim_dir.empty()) throw po::error("give exactly one of --log or --sim");
    if (!(o.resolution_m > 0.0)) throw po::error("--resolution must be > 0");
  };
  if (const auto exit_code = lmf::tools::parse_command_line(argc, argv, options, "lmf-grid", check)) return *exit_code;
  return lmf::tools::run_reporting_errors("lmf-grid", [&] { return run(o); });
}
