// Recorded ROS bags, whatever their container (docs/bags.md): the messages of
// the topics asked for, in time order, as raw bytes with their encoding, and a
// summary like `rosbag info` / `ros2 bag info`. Containers:
//   * ROS 1 bag 2.0 ("#ROSBAG V2.0"; ros1_bag.hpp: uncompressed, bz2 and lz4
//     chunks, chunks in any order, with or without the index);
//   * ROS 2 MCAP (mcap_bag.hpp: uncompressed, zstd and lz4 chunks);
//   * ROS 2 SQLite3 (rosbag2's .db3 files, or their folder with metadata.yaml;
//     sqlite_bag.hpp), through Debian's libsqlite3.
// A file in any other format (the pre-2010 "#ROSRECORD V1.2" among them) is
// refused with BagFormatError.
//
// Pure, synchronous.
#pragma once

#include <cstdint>
#include <filesystem>
#include <functional>
#include <optional>
#include <set>
#include <span>
#include <stdexcept>
#include <string>
#include <vector>

#include "lmf/bag/wire_decoder.hpp"

namespace lmf::bag {

enum class BagFormat { ros1, mcap, sqlite3 };
const char* to_string(BagFormat format);

// A file that is not a bag lmf reads, or is damaged: what() names the file,
// where (record, offset or table) when the reader knows it, and the reason.
class BagFormatError : public std::runtime_error {
 public:
  BagFormatError(const std::filesystem::path& file, const std::string& what);
  const std::filesystem::path& file() const { return file_; }

 private:
  std::filesystem::path file_;
};

struct BagMessage {
  const std::string& topic;
  const std::string& type;  // as the bag names it: "sensor_msgs/LaserScan", "sensor_msgs/msg/LaserScan"
  std::int64_t log_time_ns;  // when it was recorded (not the header's stamp)
  MessageEncoding encoding;
  std::span<const std::uint8_t> data;
};

struct BagTopic {
  std::string name;
  std::string type;
  std::size_t count = 0;
  std::int64_t first_ns = 0;  // log times
  std::int64_t last_ns = 0;
};

struct BagSummary {
  BagFormat format = BagFormat::ros1;
  std::string compression;  // of the chunks: "none", "bz2", "lz4", or several joined by ','
  std::size_t messages = 0;
  std::int64_t start_ns = 0;
  std::int64_t end_ns = 0;
  std::vector<BagTopic> topics;  // by name
  // The file ends inside a record (its recorder was killed): what was read is
  // up to there, and this says where. (A ROS 1 bag without its index is refused
  // by the library instead.)
  std::optional<std::string> cut_short;
};

// The format of `file` from its first bytes. Throws BagFormatError when it is
// none lmf reads (naming what it is, when known) and std::runtime_error when it
// cannot be opened.
BagFormat detect_bag_format(const std::filesystem::path& file);

// Throws BagFormatError.
BagSummary summarize_bag(const std::filesystem::path& file);

// Calls `visit` for each message of `topics` (every topic when empty) in log
// time order. Throws BagFormatError; exceptions from `visit` pass through.
void for_each_bag_message(const std::filesystem::path& file, const std::set<std::string>& topics,
                          const std::function<void(const BagMessage&)>& visit);

}  // namespace lmf::bag
