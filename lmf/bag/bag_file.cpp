#include "lmf/bag/bag_file.hpp"

#include <array>
#include <cstring>
#include <fstream>

#include "lmf/bag/ros1_bag.hpp"

namespace lmf::bag {

const char* to_string(BagFormat format) {
  switch (format) {
    case BagFormat::ros1:
      return "ROS 1 bag 2.0";
  }
  return "?";
}

BagFormatError::BagFormatError(const std::filesystem::path& file, const std::string& what)
    : std::runtime_error(file.string() + ": " + what), file_(file) {}

BagFormat detect_bag_format(const std::filesystem::path& file) {
  if (std::filesystem::is_directory(file)) {
    throw BagFormatError(file, "a folder (a rosbag2 SQLite3 bag?): lmf reads ROS 1 bags only so far");
  }
  std::ifstream in(file, std::ios::binary);
  if (!in) throw std::runtime_error(file.string() + ": cannot open");
  std::array<char, 16> head{};
  in.read(head.data(), head.size());
  const std::string start(head.data(), static_cast<std::size_t>(in.gcount()));
  if (start.starts_with("#ROSBAG V2.0\n")) return BagFormat::ros1;
  if (start.starts_with("#ROSBAG V") || start.starts_with("#ROSRECORD V")) {
    const std::string version = start.substr(0, start.find('\n'));
    throw BagFormatError(file, "byte 0: \"" + version +
                                   "\" is a ROS 1 bag format before 2.0 (2010): unsupported; "
                                   "`rosbag fix` converts it to 2.0");
  }
  if (start.starts_with("\x89MCAP")) throw BagFormatError(file, "byte 0: an MCAP file: not read yet (ROS 1 bags only)");
  if (start.starts_with("SQLite format 3")) {
    throw BagFormatError(file, "byte 0: an SQLite3 database (rosbag2?): not read yet (ROS 1 bags only)");
  }
  throw BagFormatError(file, "byte 0: not a bag (no \"#ROSBAG V2.0\" magic)");
}

BagSummary summarize_bag(const std::filesystem::path& file) {
  switch (detect_bag_format(file)) {
    case BagFormat::ros1:
      return ros1::summarize(file);
  }
  throw BagFormatError(file, "unknown format");
}

void for_each_bag_message(const std::filesystem::path& file, const std::set<std::string>& topics,
                          const std::function<void(const BagMessage&)>& visit) {
  switch (detect_bag_format(file)) {
    case BagFormat::ros1:
      ros1::for_each_message(file, topics, visit);
      return;
  }
}

}  // namespace lmf::bag
