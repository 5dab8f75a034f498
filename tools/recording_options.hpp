// The command-line options that choose a mission's recordings, shared by
// lmf-offline and lmf-player: CARMEN logs (--log) or ROS bags (--bag, with
// --scan-topic, --odom-topic, --odom-frame / --base-frame, --laser-mounting and
// --no-odometry; docs/bags.md), one robot per file. (--split, --gt and --sim
// stay with each program.)
#pragma once

#include <string>
#include <vector>

#include <boost/program_options.hpp>

#include "lmf/bag/bag_scans.hpp"
#include "lmf/mission/mission_inputs.hpp"

namespace lmf::tools {

struct RecordingOptions {
  std::vector<std::string> logs;
  std::vector<std::string> bags;
  bag::BagScanOptions bag;
  std::string laser_mounting;  // "x,y,yaw"
  std::vector<std::string> robots;  // "NAME=/namespace": several robots in the one --bag
  bool no_odometry = false;

  void add_to(boost::program_options::options_description& options);
  // After parsing: reads the flags that are not bound to a variable. Throws
  // std::invalid_argument for a malformed --laser-mounting.
  void finish(const boost::program_options::variables_map& vm);
  // How many of --log and --bag were given (0, 1 or 2 kinds).
  int kinds_given() const { return (logs.empty() ? 0 : 1) + (bags.empty() ? 0 : 1); }
  // Every file read, one robot each, named after the file (or, with --robot,
  // one robot per namespace of the one bag, named as given); with no_odometry
  // the scans' odometry is the identity (noted). Throws the readers' errors,
  // and std::invalid_argument for --robot without exactly one --bag or not NAME=/ns.
  std::vector<mission::RecordedLog> read() const;
};

}  // namespace lmf::tools
