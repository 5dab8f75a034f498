// lmf-convert: CARMEN logs as a ROS 1 bag (written through Debian's
// librosbag-storage) or an MCAP file (docs/bags.md): the scans, the odometry
// and the laser's mounting that lmf-offline --bag reads back. See --help.
#include <exception>
#include <filesystem>
#include <iostream>
#include <string>
#include <vector>

#include <boost/program_options.hpp>

#include "lmf/bag/scan_bag_export.hpp"
#include "lmf/io/carmen.hpp"

namespace po = boost::program_options;

int main(int argc, char** argv) {
  po::options_description options(
      "lmf-convert: writes a CARMEN log as a ROS 1 bag (FILE.bag) or an MCAP file (FILE.mcap, ROS 2):\n"
      "/scan (sensor_msgs/LaserScan, frame laser), /odom (nav_msgs/Odometry odom -> base_link; or /tf\n"
      "with --odometry-tf) and /tf_static (base_link -> laser, the log's laser mounting).\n\n"
      "With several --log, robot i's topics are under /robot<i> and its frames prefixed robot<i>/ (read them\n"
      "back with lmf-offline --bag F --robot NAME=/robot<i>).\n\n"
      "Usage: lmf-convert --log FILE... --out FILE.bag|FILE.mcap [--compression C] [--odometry-tf]\n\nOptions");
  std::vector<std::string> logs;
  std::string out;
  std::string compression = "none";
  options.add_options()("help,h", "print this help")(
      "log", po::value(&logs), "CARMEN log (plain or .gz); repeat for several robots")(
      "out", po::value(&out), "the bag to write")(
      "compression", po::value(&compression)->default_value("none"),
      "chunk compression: none, bz2 or lz4 (.bag); none or zstd (.mcap)")(
      "odometry-tf", "write the odometry as /tf instead of /odom");
  po::variables_map vm;
  try {
    po::store(po::parse_command_line(argc, argv, options), vm);
    po::notify(vm);
  } catch (const std::exception& e) {
    std::cerr << "lmf-convert: " << e.what() << "\n(see --help)\n";
    return 2;
  }
  if (vm.count("help") != 0u) {
    std::cout << options << "\n";
    return 0;
  }
  if (logs.empty() || out.empty()) {
    std::cerr << "lmf-convert: give --log and --out (see --help)\n";
    return 2;
  }
  lmf::bag::ScanBagExportOptions export_options;
  export_options.odometry_as_tf = vm.count("odometry-tf") != 0u;
  export_options.compression = compression;
  export_options.format =
      std::filesystem::path(out).extension() == ".mcap" ? lmf::bag::BagFormat::mcap : lmf::bag::BagFormat::ros1;
  try {
    std::vector<lmf::bag::RobotScans> robots;
    std::size_t scans = 0;
    for (std::size_t i = 0; i < logs.size(); ++i) {
      lmf::io::CarmenLog carmen = lmf::io::read_carmen_log(logs[i]);
      scans += carmen.scans.size();
      const std::string robot_namespace = logs.size() > 1 ? "/robot" + std::to_string(i + 1) : "";
      robots.push_back({robot_namespace, std::move(carmen.scans), carmen.laser_mounting.x_RS});
    }
    lmf::bag::write_scan_bag(out, robots, export_options);
    std::cout << "lmf-convert: " << scans << " scans of " << logs.size() << " log(s) written to " << out << "\n";
  } catch (const std::exception& e) {
    std::cerr << "lmf-convert: " << e.what() << "\n";
    return 1;
  }
  return 0;
}
