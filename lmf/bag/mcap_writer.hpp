// Writing MCAP files (lmf-convert): the ROS 2 profile, CDR messages of the
// types lmf converts its logs into (LaserScan, Odometry, TFMessage, with their
// ros2msg schemas), in chunks of about 1 MiB (uncompressed or zstd through
// Debian's libzstd) with their CRC-32, then Data End and the Footer. No summary
// section (it is optional: readers that need one build it). The inverse of
// mcap_bag.hpp.
//
// Synchronous; not thread-safe.
#pragma once

#include <cstdint>
#include <filesystem>
#include <fstream>
#include <map>
#include <span>
#include <string>
#include <vector>

namespace lmf::bag {

class McapWriter {
 public:
  enum class Compression { none, zstd };

  // Creates (or truncates) `file`. Throws BagFormatError when it cannot.
  McapWriter(const std::filesystem::path& file, Compression compression);
  ~McapWriter();
  McapWriter(const McapWriter&) = delete;
  McapWriter& operator=(const McapWriter&) = delete;

  // `type` in ROS 2 naming (sensor_msgs/msg/LaserScan, nav_msgs/msg/Odometry,
  // tf2_msgs/msg/TFMessage); `data` its CDR serialisation. Throws
  // std::invalid_argument for another type, BagFormatError when writing fails.
  void write(const std::string& topic, const std::string& type, std::int64_t log_time_ns,
             std::span<const std::uint8_t> data);
  // Flushes the last chunk and writes Data End, the Footer and the magic; also
  // done by the destructor (which swallows errors).
  void close();

 private:
  void flush_chunk();
  void put_record(std::vector<std::uint8_t>& out, std::uint8_t opcode, const std::vector<std::uint8_t>& content);

  std::filesystem::path file_;
  std::ofstream out_;
  Compression compression_;
  std::map<std::string, std::uint16_t> schemas_;   // type -> schema id
  std::map<std::string, std::uint16_t> channels_;  // topic -> channel id
  std::vector<std::uint8_t> chunk_;                // records of the open chunk
  std::int64_t chunk_start_ns_ = 0;
  std::int64_t chunk_end_ns_ = 0;
  std::uint32_t sequence_ = 0;
  bool closed_ = false;
};

}  // namespace lmf::bag
