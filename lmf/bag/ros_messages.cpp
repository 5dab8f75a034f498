#include "lmf/bag/ros_messages.hpp"

namespace lmf::bag {
namespace {

RosHeader read_header(WireDecoder& d) {
  RosHeader h;
  if (d.encoding() == MessageEncoding::ros1) d.u32("header.seq");
  h.stamp_ns = d.time_ns("header.stamp");
  h.frame_id = d.string("header.frame_id");
  return h;
}

// geometry_msgs/Pose or Transform: a Point / Vector3 and a Quaternion (x y z w), all float64.
RosPose3 read_pose(WireDecoder& d, const char* what) {
  RosPose3 p;
  for (int i = 0; i < 3; ++i) p.translation[i] = d.f64(what);
  const double x = d.f64(what), y = d.f64(what), z = d.f64(what), w = d.f64(what);
  p.rotation = Eigen::Quaterniond(w, x, y, z);
  return p;
}

void skip_f64(WireDecoder& d, int n, const char* what) {
  for (int i = 0; i < n; ++i) d.f64(what);
}

}  // namespace

bool is_laser_scan_type(const std::string& type) {
  return type == "sensor_msgs/LaserScan" || type == "sensor_msgs/msg/LaserScan";
}
bool is_odometry_type(const std::string& type) {
  return type == "nav_msgs/Odometry" || type == "nav_msgs/msg/Odometry";
}
bool is_tf_type(const std::string& type) {
  return type == "tf/tfMessage" || type == "tf2_msgs/TFMessage" || type == "tf2_msgs/msg/TFMessage";
}

RosLaserScan decode_laser_scan(std::span<const std::uint8_t> bytes, MessageEncoding encoding) {
  WireDecoder d(bytes, encoding);
  RosLaserScan s;
  s.header = read_header(d);
  s.angle_min = d.f32("angle_min");
  s.angle_max = d.f32("angle_max");
  s.angle_increment = d.f32("angle_increment");
  d.f32("time_increment");
  d.f32("scan_time");
  s.range_min = d.f32("range_min");
  s.range_max = d.f32("range_max");
  s.ranges = d.f32_sequence("ranges");
  d.f32_sequence("intensities");
  return s;
}

RosOdometry decode_odometry(std::span<const std::uint8_t> bytes, MessageEncoding encoding) {
  WireDecoder d(bytes, encoding);
  RosOdometry o;
  o.header = read_header(d);
  o.child_frame_id = d.string("child_frame_id");
  o.pose = read_pose(d, "pose.pose");
  skip_f64(d, 36, "pose.covariance");
  skip_f64(d, 6, "twist.twist");
  skip_f64(d, 36, "twist.covariance");
  return o;
}

std::vector<RosTransform> decode_tf_message(std::span<const std::uint8_t> bytes, MessageEncoding encoding) {
  WireDecoder d(bytes, encoding);
  // Each TransformStamped is at least a header (8 + 4 bytes), a child (4) and 7 float64.
  const std::uint32_t n = d.sequence_length(12 + 4 + 56, "transforms");
  std::vector<RosTransform> transforms(n);
  for (auto& t : transforms) {
    t.header = read_header(d);
    t.child_frame_id = d.string("child_frame_id");
    t.transform = read_pose(d, "transform");
  }
  return transforms;
}

}  // namespace lmf::bag
