#include "lmf/bag/mcap_writer.hpp"

#include <algorithm>
#include <stdexcept>

#include <zlib.h>
#include <zstd.h>

#include "lmf/bag/bag_file.hpp"

namespace lmf::bag {
namespace {

constexpr char kMagic[] = "\x89MCAP0\r\n";
constexpr std::size_t kChunkBytes = 1 << 20;

void put_uint(std::vector<std::uint8_t>& out, std::uint64_t v, int size) {
  for (int i = 0; i < size; ++i) out.push_back(static_cast<std::uint8_t>(v >> (8 * i)));
}
void put_string(std::vector<std::uint8_t>& out, const std::string& s) {
  put_uint(out, s.size(), 4);
  out.insert(out.end(), s.begin(), s.end());
}

// ros2msg schemas: the type's fields, then each dependency after a separator line.
const std::string kSep = "================================================================================\n";
const std::string kHeader = kSep + "MSG: std_msgs/Header\nbuiltin_interfaces/Time stamp\nstring frame_id\n" + kSep +
                            "MSG: builtin_interfaces/Time\nint32 sec\nuint32 nanosec\n";
const std::string kVector3 = kSep + "MSG: geometry_msgs/Vector3\nfloat64 x\nfloat64 y\nfloat64 z\n";
const std::string kQuaternion = kSep + "MSG: geometry_msgs/Quaternion\nfloat64 x\nfloat64 y\nfloat64 z\nfloat64 w\n";

const std::string& schema_text(const std::string& type) {
  static const std::map<std::string, std::string> kSchemas = {
      {"sensor_msgs/msg/LaserScan",
       "std_msgs/Header header\nfloat32 angle_min\nfloat32 angle_max\nfloat32 angle_increment\n"
       "float32 time_increment\nfloat32 scan_time\nfloat32 range_min\nfloat32 range_max\nfloat32[] ranges\n"
       "float32[] intensities\n" +
           kHeader},
      {"nav_msgs/msg/Odometry",
       "std_msgs/Header header\nstring child_frame_id\ngeometry_msgs/PoseWithCovariance pose\n"
       "geometry_msgs/TwistWithCovariance twist\n" +
           kHeader + kSep + "MSG: geometry_msgs/PoseWithCovariance\ngeometry_msgs/Pose pose\nfloat64[36] covariance\n" +
           kSep + "MSG: geometry_msgs/Pose\ngeometry_msgs/Point position\ngeometry_msgs/Quaternion orientation\n" +
           kSep + "MSG: geometry_msgs/Point\nfloat64 x\nfloat64 y\nfloat64 z\n" + kQuaternion + kSep +
           "MSG: geometry_msgs/TwistWithCovariance\ngeometry_msgs/Twist twist\nfloat64[36] covariance\n" + kSep +
           "MSG: geometry_msgs/Twist\ngeometry_msgs/Vector3 linear\ngeometry_msgs/Vector3 angular\n" + kVector3},
      {"tf2_msgs/msg/TFMessage",
       "geometry_msgs/TransformStamped[] transforms\n" + kSep +
           "MSG: geometry_msgs/TransformStamped\nstd_msgs/Header header\nstring child_frame_id\n"
           "geometry_msgs/Transform transform\n" +
           kHeader + kSep +
           "MSG: geometry_msgs/Transform\ngeometry_msgs/Vector3 translation\ngeometry_msgs/Quaternion rotation\n" +
           kVector3 + kQuaternion},
  };
  const auto it = kSchemas.find(type);
  if (it == kSchemas.end()) throw std::invalid_argument("McapWriter: cannot write type " + type);
  return it->second;
}

}  // namespace

McapWriter::McapWriter(const std::filesystem::path& file, Compression compression)
    : file_(file), out_(file, std::ios::binary | std::ios::trunc), compression_(compression) {
  if (!out_) throw BagFormatError(file, "cannot write an MCAP file here");
  out_.write(kMagic, 8);
  std::vector<std::uint8_t> header;
  put_string(header, "ros2");
  put_string(header, "lmf");
  std::vector<std::uint8_t> record;
  put_record(record, 0x01, header);
  out_.write(reinterpret_cast<const char*>(record.data()), static_cast<std::streamsize>(record.size()));
}

McapWriter::~McapWriter() {
  try {
    close();
  } catch (const std::exception&) {
  }
}

void McapWriter::put_record(std::vector<std::uint8_t>& out, std::uint8_t opcode,
                            const std::vector<std::uint8_t>& content) {
  out.push_back(opcode);
  put_uint(out, content.size(), 8);
  out.insert(out.end(), content.begin(), content.end());
}

void McapWriter::write(const std::string& topic, const std::string& type, std::int64_t log_time_ns,
                       std::span<const std::uint8_t> data) {
  if (closed_) throw std::logic_error("McapWriter: write after close");
  if (!schemas_.contains(type)) {
    const auto id = static_cast<std::uint16_t>(schemas_.size() + 1);
    std::vector<std::uint8_t> schema;
    put_uint(schema, id, 2);
    put_string(schema, type);
    put_string(schema, "ros2msg");
    put_string(schema, schema_text(type));  // data: uint32 length + bytes, as a string is
    put_record(chunk_, 0x03, schema);
    schemas_[type] = id;
  }
  if (!channels_.contains(topic)) {
    const auto id = static_cast<std::uint16_t>(channels_.size() + 1);
    std::vector<std::uint8_t> channel;
    put_uint(channel, id, 2);
    put_uint(channel, schemas_.at(type), 2);
    put_string(channel, topic);
    put_string(channel, "cdr");
    put_uint(channel, 0, 4);  // no metadata
    put_record(chunk_, 0x04, channel);
    channels_[topic] = id;
  }
  std::vector<std::uint8_t> message;
  put_uint(message, channels_.at(topic), 2);
  put_uint(message, sequence_++, 4);
  put_uint(message, static_cast<std::uint64_t>(log_time_ns), 8);
  put_uint(message, static_cast<std::uint64_t>(log_time_ns), 8);  // publish time
  message.insert(message.end(), data.begin(), data.end());
  if (chunk_start_ns_ == 0 || log_time_ns < chunk_start_ns_) chunk_start_ns_ = log_time_ns;
  chunk_end_ns_ = std::max(chunk_end_ns_, log_time_ns);
  put_record(chunk_, 0x05, message);
  if (chunk_.size() >= kChunkBytes) flush_chunk();
}

void McapWriter::flush_chunk() {
  if (chunk_.empty()) return;
  std::vector<std::uint8_t> stored = chunk_;
  if (compression_ == Compression::zstd) {
    stored.resize(ZSTD_compressBound(chunk_.size()));
    const std::size_t n = ZSTD_compress(stored.data(), stored.size(), chunk_.data(), chunk_.size(), 3);
    if (ZSTD_isError(n) != 0u) throw BagFormatError(file_, std::string("zstd: ") + ZSTD_getErrorName(n));
    stored.resize(n);
  }
  std::vector<std::uint8_t> content;
  put_uint(content, static_cast<std::uint64_t>(chunk_start_ns_), 8);
  put_uint(content, static_cast<std::uint64_t>(chunk_end_ns_), 8);
  put_uint(content, chunk_.size(), 8);
  put_uint(content, static_cast<std::uint32_t>(crc32(0L, chunk_.data(), static_cast<uInt>(chunk_.size()))), 4);
  put_string(content, compression_ == Compression::zstd ? "zstd" : "");
  put_uint(content, stored.size(), 8);
  content.insert(content.end(), stored.begin(), stored.end());
  std::vector<std::uint8_t> record;
  put_record(record, 0x06, content);
  out_.write(reinterpret_cast<const char*>(record.data()), static_cast<std::streamsize>(record.size()));
  chunk_.clear();
  chunk_start_ns_ = chunk_end_ns_ = 0;
}

void McapWriter::close() {
  if (closed_) return;
  closed_ = true;
  flush_chunk();
  std::vector<std::uint8_t> tail;
  std::vector<std::uint8_t> data_end;
  put_uint(data_end, 0, 4);  // data section CRC not computed
  put_record(tail, 0x0F, data_end);
  std::vector<std::uint8_t> footer;
  put_uint(footer, 0, 8);  // no summary section
  put_uint(footer, 0, 8);
  put_uint(footer, 0, 4);
  put_record(tail, 0x02, footer);
  out_.write(reinterpret_cast<const char*>(tail.data()), static_cast<std::streamsize>(tail.size()));
  out_.write(kMagic, 8);
  out_.close();
  if (!out_) throw BagFormatError(file_, "writing failed");
}

}  // namespace lmf::bag
