#include "tools/recording_options.hpp"

#include <sstream>
#include <stdexcept>

namespace lmf::tools {
namespace po = boost::program_options;

namespace {

// "x,y,yaw" (m, m, rad).
Pose2 parse_mounting(const std::string& text) {
  double x = 0.0, y = 0.0, yaw = 0.0;
  char c1 = 0, c2 = 0;
  std::istringstream in(text);
  if (!(in >> x >> c1 >> y >> c2 >> yaw) || c1 != ',' || c2 != ',' || !(in >> std::ws).eof()) {
    throw std::invalid_argument("--laser-mounting: expected x,y,yaw (m, m, rad), got \"" + text + "\"");
  }
  return {x, y, yaw};
}

}  // namespace

void RecordingOptions::add_to(po::options_description& options) {
  options.add_options()("log", po::value(&logs), "CARMEN log (plain or .gz); repeat for one robot per file")(
      "bag", po::value(&bags),
      "ROS bag: ROS 1 .bag, .mcap, rosbag2 .db3 or folder (docs/bags.md); repeat for one robot per file")(
      "scan-topic", po::value(&bag.scan_topic), "--bag: the LaserScan topic (default: the only one)")(
      "odom-topic", po::value(&bag.odom_topic), "--bag: the nav_msgs/Odometry topic (default: the only one)")(
      "odom-frame", po::value(&bag.odom_frame), "--bag: odometry from /tf, this frame (default odom) ...")(
      "base-frame", po::value(&bag.base_frame), "--bag: ... to this one (default: odom's only child in /tf)")(
      "laser-mounting", po::value(&laser_mounting),
      "--bag: the laser on the base, x,y,yaw (m, m, rad); default: from /tf_static")(
      "robot", po::value(&robots),
      "--bag: NAME=/namespace, a robot whose topics are under /namespace (/robot1/scan, /robot1/odom); repeat "
      "for each robot of the one bag")(
      "no-odometry",
      "the scans have no odometry (a laser alone): the scan match carries the motion from a constant-velocity "
      "prior (docs/bags.md); with --log, the log's odometry is ignored");
}

void RecordingOptions::finish(const po::variables_map& vm) {
  if (!laser_mounting.empty()) bag.laser_mounting = parse_mounting(laser_mounting);
  no_odometry = vm.count("no-odometry") != 0u;
  bag.no_odometry = no_odometry;
}

std::vector<mission::RecordedLog> RecordingOptions::read() const {
  std::vector<mission::RecordedLog> recordings;
  for (const auto& file : logs) {
    recordings.push_back(mission::read_carmen_recording(file));
    if (no_odometry) {
      for (auto& scan : recordings.back().scans) scan.odometry = Pose2();
      recordings.back().notes.push_back("odometry ignored (--no-odometry)");
    }
  }
  const auto read_bag = [&](const std::string& file, const std::string& name, const bag::BagScanOptions& options) {
    bag::BagScans scans = bag::read_bag_scans(file, options);
    mission::RecordedLog recording;
    recording.file = file;
    recording.name = name;
    recording.scans = std::move(scans.scans);
    recording.notes = std::move(scans.notes);
    recordings.push_back(std::move(recording));
  };
  if (!robots.empty()) {
    if (bags.size() != 1) throw std::invalid_argument("--robot: give exactly one --bag, the one the robots share");
    for (const auto& robot : robots) {
      const auto eq = robot.find('=');
      if (eq == std::string::npos || eq == 0 || eq + 1 == robot.size()) {
        throw std::invalid_argument("--robot: expected NAME=/namespace, got \"" + robot + "\"");
      }
      bag::BagScanOptions options = bag;
      options.robot_namespace = robot.substr(eq + 1);
      read_bag(bags.front(), robot.substr(0, eq), options);
    }
    return recordings;
  }
  for (const auto& file : bags) read_bag(file, std::filesystem::path(file).stem().string(), bag);
  return recordings;
}

}  // namespace lmf::tools
