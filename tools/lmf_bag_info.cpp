// lmf-bag-info: what a ROS bag holds (format, compression, time span, and per
// topic its type, message count and time span), like `rosbag info`; with
// --scans, also what lmf-offline --bag would map from it. See --help.
#include <cstdio>
#include <exception>
#include <iostream>
#include <string>

#include <boost/program_options.hpp>

#include "lmf/bag/bag_file.hpp"
#include "lmf/bag/bag_scans.hpp"

namespace po = boost::program_options;

namespace {

std::string seconds(std::int64_t ns) {
  char text[32];
  std::snprintf(text, sizeof text, "%.3f", static_cast<double>(ns) * 1e-9);
  return text;
}

}  // namespace

int main(int argc, char** argv) {
  po::options_description options(
      "lmf-bag-info: a ROS bag's format, topics, types, message counts and time spans.\n\n"
      "Usage: lmf-bag-info FILE [--scans]\n\nOptions");
  std::string file;
  options.add_options()("help,h", "print this help")("bag", po::value(&file), "the bag")(
      "scans", "also read the scans and odometry as lmf-offline --bag would (default topics), and say what it found");
  po::positional_options_description positional;
  positional.add("bag", 1);
  po::variables_map vm;
  try {
    po::store(po::command_line_parser(argc, argv).options(options).positional(positional).run(), vm);
    po::notify(vm);
  } catch (const std::exception& e) {
    std::cerr << "lmf-bag-info: " << e.what() << "\n(see --help)\n";
    return 2;
  }
  if (vm.count("help") != 0u) {
    std::cout << options << "\n";
    return 0;
  }
  if (file.empty()) {
    std::cerr << "lmf-bag-info: give a bag (see --help)\n";
    return 2;
  }
  try {
    const lmf::bag::BagSummary summary = lmf::bag::summarize_bag(file);
    std::cout << "path:        " << file << "\n"
              << "format:      " << lmf::bag::to_string(summary.format) << "\n"
              << "compression: " << summary.compression << "\n"
              << "messages:    " << summary.messages << "\n";
    if (summary.messages > 0) {
      std::cout << "start:       " << seconds(summary.start_ns) << " s\n"
                << "end:         " << seconds(summary.end_ns) << " s\n"
                << "duration:    " << seconds(summary.end_ns - summary.start_ns) << " s\n";
    }
    std::cout << "topics:\n";
    for (const auto& t : summary.topics) {
      std::cout << "  " << t.name << "  " << t.count << " msgs  " << t.type << "  " << seconds(t.first_ns) << " .. "
                << seconds(t.last_ns) << " s\n";
    }
    if (vm.count("scans") != 0u) {
      const lmf::bag::BagScans scans = lmf::bag::read_bag_scans(file);
      std::cout << "lmf-offline --bag would read:\n";
      for (const auto& note : scans.notes) std::cout << "  " << note << "\n";
    }
  } catch (const std::exception& e) {
    std::cerr << "lmf-bag-info: " << e.what() << "\n";
    return 1;
  }
  return 0;
}
