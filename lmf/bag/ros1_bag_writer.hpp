// Writing ROS 1 bags (2.0) through Debian's librosbag-storage, for the
// messages lmf converts its logs into (lmf-convert): sensor_msgs/LaserScan,
// nav_msgs/Odometry and tf2_msgs/TFMessage, already serialised
// (wire_encoder.hpp). Each connection carries the type's md5sum and message
// definition, so ROS's own tools read the result.
//
// Synchronous; not thread-safe.
#pragma once

#include <cstdint>
#include <filesystem>
#include <memory>
#include <span>
#include <string>

namespace lmf::bag {

class Ros1BagWriter {
 public:
  enum class Compression { none, bz2, lz4 };

  // Creates (or truncates) `file`. Throws BagFormatError when it cannot.
  Ros1BagWriter(const std::filesystem::path& file, Compression compression);
  ~Ros1BagWriter();
  Ros1BagWriter(const Ros1BagWriter&) = delete;
  Ros1BagWriter& operator=(const Ros1BagWriter&) = delete;

  // `type` is one of the three above (ROS 1 names); `data` its ROS 1
  // serialisation. Throws std::invalid_argument for another type and
  // BagFormatError when writing fails.
  void write(const std::string& topic, const std::string& type, std::int64_t log_time_ns,
             std::span<const std::uint8_t> data);
  // Writes the index; also done by the destructor (which swallows errors).
  void close();

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

}  // namespace lmf::bag
