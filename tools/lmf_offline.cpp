// lmf-offline: the whole multi-robot mapping mission in one deterministic
// process, without LCM (lockstep: each shipped local map is fused before the
// next scan). See --help.
#include <exception>
#include <filesystem>
#include <iostream>
#include <sstream>
#include <stdexcept>
#include <string>
#include <vector>

#include <boost/program_options.hpp>

#include "lmf/bag/bag_scans.hpp"
#include "lmf/mission/config_file.hpp"
#include "lmf/mission/mission_inputs.hpp"
#include "lmf/mission/mission_report.hpp"
#include "lmf/mission/offline_mission.hpp"

namespace po = boost::program_options;

namespace {

// A bag's scans as one robot's recording, named after the file.
lmf::mission::RecordedLog read_bag_recording(const std::filesystem::path& file, const lmf::bag::BagScanOptions& options) {
  lmf::bag::BagScans bag = lmf::bag::read_bag_scans(file, options);
  lmf::mission::RecordedLog recording;
  recording.file = file;
  recording.name = file.stem().string();
  recording.scans = std::move(bag.scans);
  recording.notes = std::move(bag.notes);
  return recording;
}

// "x,y,yaw" (m, m, rad).
lmf::Pose2 parse_mounting(const std::string& text) {
  double x = 0.0, y = 0.0, yaw = 0.0;
  char c1 = 0, c2 = 0;
  std::istringstream in(text);
  if (!(in >> x >> c1 >> y >> c2 >> yaw) || c1 != ',' || c2 != ',' || !(in >> std::ws).eof()) {
    throw std::invalid_argument("--laser-mounting: expected x,y,yaw (m, m, rad), got \"" + text + "\"");
  }
  return {x, y, yaw};
}

}  // namespace

int main(int argc, char** argv) {
  po::options_description options(
      "lmf-offline: runs one local map per robot and the global map over recorded or simulated\n"
      "robots in one deterministic process, then writes trajectories, the map and a report.\n\n"
      "Usage: lmf-offline (--log FILE... | --bag FILE...) [--split N] [--gt FILE] [--config FILE] --out DIR\n"
      "       lmf-offline --sim DIR [--config FILE] --out DIR\n\n"
      "Options");
  std::vector<std::string> logs;
  std::vector<std::string> bags;
  lmf::bag::BagScanOptions bag_options;
  std::string laser_mounting;
  int split = 1;
  std::string gt;
  std::string sim_dir;
  std::string config_file;
  std::string out;
  uint64_t seed = 0;
  options.add_options()("help,h", "print this help")(
      "log", po::value(&logs), "CARMEN log (plain or .gz); repeat for one robot per file")(
      "bag", po::value(&bags), "ROS 1 bag (docs/bags.md); repeat for one robot per file")(
      "scan-topic", po::value(&bag_options.scan_topic), "--bag: the LaserScan topic (default: the only one)")(
      "odom-topic", po::value(&bag_options.odom_topic), "--bag: the nav_msgs/Odometry topic (default: the only one)")(
      "odom-frame", po::value(&bag_options.odom_frame), "--bag: odometry from /tf, this frame (default odom) ...")(
      "base-frame", po::value(&bag_options.base_frame), "--bag: ... to this one (default: odom's only child in /tf)")(
      "no-odometry",
      "the scans have no odometry (a laser alone): the scan match carries the motion from a constant-velocity "
      "prior (docs/bags.md); with --log, the log's odometry is ignored")(
      "laser-mounting", po::value(&laser_mounting),
      "--bag: the laser on the base, x,y,yaw (m, m, rad); default: from /tf_static")(
      "split", po::value(&split)->default_value(1),
      "cut the single --log or --bag into N contiguous parts replayed as N simultaneous robots")(
      "gt", po::value(&gt),
      "reference poses (`t x y theta` or `index t x y theta`): joins robots after the first at their "
      "reference start plus sighting noise, and scores ATE/RPE")(
      "sim", po::value(&sim_dir), "an lmf-sim output folder (logs, ground truth, sightings)")(
      "config", po::value(&config_file), "JSON config (sections local_map, global_map, sighting_noise)")(
      "seed", po::value(&seed), "seed of the sighting noise (overrides the config's)")(
      "out", po::value(&out), "output folder (created)")(
      "map-graph", "draw the environment graph (submap nodes, consecutive and paired edges) in map.svg");
  po::variables_map vm;
  try {
    po::store(po::parse_command_line(argc, argv, options), vm);
    po::notify(vm);
  } catch (const std::exception& e) {
    std::cerr << "lmf-offline: " << e.what() << "\n(see --help)\n";
    return 2;
  }
  if (vm.count("help") != 0u) {
    std::cout << options << "\n";
    return 0;
  }
  if (out.empty() || (!logs.empty()) + (!bags.empty()) + (!sim_dir.empty()) != 1) {
    std::cerr << "lmf-offline: give --out and exactly one of --log, --bag or --sim (see --help)\n";
    return 2;
  }
  try {
    lmf::mission::MissionConfig config =
        config_file.empty() ? lmf::mission::MissionConfig{} : lmf::mission::load_mission_config(config_file);
    if (vm.count("seed") != 0u) config.sighting_noise.seed = seed;
    if (!laser_mounting.empty()) bag_options.laser_mounting = parse_mounting(laser_mounting);
    const bool no_odometry = vm.count("no-odometry") != 0u;
    bag_options.no_odometry = no_odometry;
    if (no_odometry) config.local_map.scans_have_odometry = false;
    lmf::mission::MissionInputs inputs;
    if (!sim_dir.empty()) {
      inputs = lmf::mission::load_sim_folder(sim_dir, config.sighting_noise);
    } else if (!bags.empty()) {
      std::vector<lmf::mission::RecordedLog> recordings;
      for (const auto& bag : bags) recordings.push_back(read_bag_recording(bag, bag_options));
      inputs = lmf::mission::load_recordings(std::move(recordings), split, gt, config.sighting_noise);
    } else {
      std::vector<lmf::mission::RecordedLog> recordings;
      for (const auto& log : logs) recordings.push_back(lmf::mission::read_carmen_recording(log));
      if (no_odometry) {
        for (auto& recording : recordings) {
          for (auto& scan : recording.scans) scan.odometry = lmf::Pose2();
          recording.notes.push_back("odometry ignored (--no-odometry)");
        }
      }
      inputs = lmf::mission::load_recordings(std::move(recordings), split, gt, config.sighting_noise);
    }
    lmf::mission::OfflineMission mission(config, std::move(inputs));
    const lmf::mission::MissionResult result = mission.run();
    const auto score = lmf::mission::score_mission(result, mission.inputs(), mission.global_map());
    lmf::fusion::MapSvgOptions svg;
    svg.graph = vm.count("map-graph") != 0u;
    lmf::mission::write_mission_outputs(out, mission, result, score, svg);
    std::cout << lmf::mission::summarize(mission, result, score) << "wrote " << out
              << "/{trajectory.txt, trajectories/, map.json, map.svg, report.json}\n";
  } catch (const std::exception& e) {
    std::cerr << "lmf-offline: " << e.what() << "\n";
    return 1;
  }
  return 0;
}
