#include "lmf/bag/bag_file.hpp"

#include <array>
#include <cstring>
#include <fstream>
#include <vector>

#include "lmf/bag/mcap_bag.hpp"
#include "lmf/bag/ros1_bag.hpp"
#include "lmf/bag/sqlite_bag.hpp"

namespace lmf::bag {

const char* to_string(BagFormat format) {
  switch (format) {
    case BagFormat::ros1:
      return "ROS 1 bag 2.0";
    case BagFormat::mcap:
      return "MCAP";
    case BagFormat::sqlite3:
      return "rosbag2 SQLite3";
  }
  return "?";
}

BagFormatError::BagFormatError(const std::filesystem::path& file, const std::string& what)
    : std::runtime_error(file.string() + ": " + what), file_(file) {}

namespace {

// A rosbag2 bag is a folder: metadata.yaml beside its storage files, .db3
// (the folder is read) or .mcap (the one file is read).
std::filesystem::path storage_path(const std::filesystem::path& file) {
  if (!std::filesystem::is_directory(file) || !sqlite::database_files(file).empty()) return file;
  std::vector<std::filesystem::path> mcaps;
  for (const auto& entry : std::filesystem::directory_iterator(file)) {
    if (entry.path().extension() == ".mcap") mcaps.push_back(entry.path());
  }
  if (mcaps.size() != 1) {
    throw BagFormatError(file, "a folder with " + std::to_string(mcaps.size()) +
                                   " .mcap files and no .db3: give the bag's file itself");
  }
  return mcaps.front();
}

}  // namespace

BagFormat detect_bag_format(const std::filesystem::path& path) {
  const std::filesystem::path file = storage_path(path);
  if (std::filesystem::is_directory(file)) return BagFormat::sqlite3;
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
  if (start.starts_with(std::string("\x89MCAP0\r\n", 8))) return BagFormat::mcap;
  if (start.starts_with("\x89MCAP")) throw BagFormatError(file, "byte 5: an MCAP file of a major version other than 0");
  if (start.starts_with(std::string("SQLite format 3\0", 16))) return BagFormat::sqlite3;
  throw BagFormatError(file, "byte 0: not a bag (neither \"#ROSBAG V2.0\", MCAP nor SQLite3 magic)");
}

BagSummary summarize_bag(const std::filesystem::path& path) {
  const std::filesystem::path file = storage_path(path);
  switch (detect_bag_format(file)) {
    case BagFormat::ros1:
      return ros1::summarize(file);
    case BagFormat::mcap:
      return mcap::summarize(file);
    case BagFormat::sqlite3:
      return sqlite::summarize(file);
  }
  throw BagFormatError(file, "unknown format");
}

void for_each_bag_message(const std::filesystem::path& path, const std::set<std::string>& topics,
                          const std::function<void(const BagMessage&)>& visit) {
  const std::filesystem::path file = storage_path(path);
  switch (detect_bag_format(file)) {
    case BagFormat::ros1:
      ros1::for_each_message(file, topics, visit);
      return;
    case BagFormat::mcap:
      mcap::for_each_message(file, topics, visit);
      return;
    case BagFormat::sqlite3:
      sqlite::for_each_message(file, topics, visit);
      return;
  }
}

}  // namespace lmf::bag
