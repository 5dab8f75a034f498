#include "lmf/bag/ros1_bag_writer.hpp"

#include <cstring>
#include <stdexcept>

#include <ros/message_traits.h>
#include <ros/serialization.h>
#include <rosbag/bag.h>
#include <rosbag/exceptions.h>

#include "lmf/bag/bag_file.hpp"

namespace lmf::bag {
namespace {

struct MessageType {
  const char* name;
  const char* md5sum;
  const char* definition;
};

// The message definitions as ROS 1 publishes them (fields only, dependencies
// after a separator line each), with their md5sums.
constexpr const char* kSeparator = "================================================================================\n";
const std::string kHeader = std::string(kSeparator) + "MSG: std_msgs/Header\nuint32 seq\ntime stamp\nstring frame_id\n";
const std::string kLaserScanDefinition =
    "std_msgs/Header header\nfloat32 angle_min\nfloat32 angle_max\nfloat32 angle_increment\nfloat32 time_increment\n"
    "float32 scan_time\nfloat32 range_min\nfloat32 range_max\nfloat32[] ranges\nfloat32[] intensities\n" +
    kHeader;
const std::string kPose = std::string(kSeparator) +
                          "MSG: geometry_msgs/Point\nfloat64 x\nfloat64 y\nfloat64 z\n" + kSeparator +
                          "MSG: geometry_msgs/Quaternion\nfloat64 x\nfloat64 y\nfloat64 z\nfloat64 w\n";
const std::string kOdometryDefinition =
    "std_msgs/Header header\nstring child_frame_id\ngeometry_msgs/PoseWithCovariance pose\n"
    "geometry_msgs/TwistWithCovariance twist\n" +
    kHeader + kSeparator + "MSG: geometry_msgs/PoseWithCovariance\ngeometry_msgs/Pose pose\nfloat64[36] covariance\n" +
    kSeparator + "MSG: geometry_msgs/Pose\ngeometry_msgs/Point position\ngeometry_msgs/Quaternion orientation\n" + kPose +
    kSeparator + "MSG: geometry_msgs/TwistWithCovariance\ngeometry_msgs/Twist twist\nfloat64[36] covariance\n" +
    kSeparator + "MSG: geometry_msgs/Twist\ngeometry_msgs/Vector3 linear\ngeometry_msgs/Vector3 angular\n" +
    kSeparator + "MSG: geometry_msgs/Vector3\nfloat64 x\nfloat64 y\nfloat64 z\n";
const std::string kTfDefinition =
    "geometry_msgs/TransformStamped[] transforms\n" + std::string(kSeparator) +
    "MSG: geometry_msgs/TransformStamped\nstd_msgs/Header header\nstring child_frame_id\n"
    "geometry_msgs/Transform transform\n" +
    kHeader + kSeparator + "MSG: geometry_msgs/Transform\ngeometry_msgs/Vector3 translation\n"
    "geometry_msgs/Quaternion rotation\n" + kSeparator + "MSG: geometry_msgs/Vector3\nfloat64 x\nfloat64 y\nfloat64 z\n" +
    kSeparator + "MSG: geometry_msgs/Quaternion\nfloat64 x\nfloat64 y\nfloat64 z\nfloat64 w\n";

const MessageType& message_type(const std::string& name) {
  static const MessageType kTypes[] = {
      {"sensor_msgs/LaserScan", "90c7ef2dc6895d81024acba2ac42f369", kLaserScanDefinition.c_str()},
      {"nav_msgs/Odometry", "cd5e73d190d741a2f92e81eda573aca7", kOdometryDefinition.c_str()},
      {"tf2_msgs/TFMessage", "94810edda583a504dfda3829e70d7eec", kTfDefinition.c_str()},
  };
  for (const auto& t : kTypes) {
    if (name == t.name) return t;
  }
  throw std::invalid_argument("Ros1BagWriter: cannot write type " + name);
}

// A message already serialised, with its type's identity.
struct SerializedMessage {
  const MessageType* type;
  std::span<const std::uint8_t> data;
};

}  // namespace
}  // namespace lmf::bag

namespace ros::message_traits {
template <>
struct MD5Sum<lmf::bag::SerializedMessage> {
  static const char* value(const lmf::bag::SerializedMessage& m) { return m.type->md5sum; }
};
template <>
struct DataType<lmf::bag::SerializedMessage> {
  static const char* value(const lmf::bag::SerializedMessage& m) { return m.type->name; }
};
template <>
struct Definition<lmf::bag::SerializedMessage> {
  static const char* value(const lmf::bag::SerializedMessage& m) { return m.type->definition; }
};
}  // namespace ros::message_traits

namespace ros::serialization {
template <>
struct Serializer<lmf::bag::SerializedMessage> {
  template <typename Stream>
  static void write(Stream& stream, const lmf::bag::SerializedMessage& m) {
    std::memcpy(stream.advance(static_cast<std::uint32_t>(m.data.size())), m.data.data(), m.data.size());
  }
  static std::uint32_t serializedLength(const lmf::bag::SerializedMessage& m) {
    return static_cast<std::uint32_t>(m.data.size());
  }
};
}  // namespace ros::serialization

namespace lmf::bag {

struct Ros1BagWriter::Impl {
  std::filesystem::path file;
  rosbag::Bag bag;
};

Ros1BagWriter::Ros1BagWriter(const std::filesystem::path& file, Compression compression)
    : impl_(std::make_unique<Impl>()) {
  impl_->file = file;
  try {
    impl_->bag.open(file.string(), rosbag::bagmode::Write);
    impl_->bag.setCompression(compression == Compression::bz2   ? rosbag::compression::BZ2
                              : compression == Compression::lz4 ? rosbag::compression::LZ4
                                                                : rosbag::compression::Uncompressed);
  } catch (const rosbag::BagException& e) {
    throw BagFormatError(file, std::string("cannot write a ROS 1 bag: ") + e.what());
  }
}

Ros1BagWriter::~Ros1BagWriter() {
  try {
    close();
  } catch (const std::exception&) {
  }
}

void Ros1BagWriter::write(const std::string& topic, const std::string& type, std::int64_t log_time_ns,
                          std::span<const std::uint8_t> data) {
  const SerializedMessage message{&message_type(type), data};
  try {
    ros::Time time;
    time.fromNSec(static_cast<std::uint64_t>(log_time_ns));
    impl_->bag.write(topic, time, message);
  } catch (const rosbag::BagException& e) {
    throw BagFormatError(impl_->file, std::string("writing ") + topic + ": " + e.what());
  }
}

void Ros1BagWriter::close() {
  if (!impl_->bag.isOpen()) return;
  try {
    impl_->bag.close();
  } catch (const rosbag::BagException& e) {
    throw BagFormatError(impl_->file, std::string("closing: ") + e.what());
  }
}

}  // namespace lmf::bag
