#include "lmf/bag/scan_bag_export.hpp"

#include <functional>
#include <memory>
#include <stdexcept>

#include "lmf/bag/mcap_writer.hpp"
#include "lmf/bag/planar_pose.hpp"
#include "lmf/bag/ros1_bag_writer.hpp"
#include "lmf/bag/ros_messages.hpp"
#include "lmf/bag/wire_encoder.hpp"

namespace lmf::bag {
namespace {

// The message types by their ROS 1 name; ROS 2 adds "/msg".
std::string ros2_name(const std::string& ros1) { return ros1.substr(0, ros1.find('/')) + "/msg" + ros1.substr(ros1.find('/')); }

// write(topic, ROS 1 type name, log time, bytes) for the chosen container.
using Write = std::function<void(const std::string&, const std::string&, std::int64_t, std::span<const std::uint8_t>)>;

}  // namespace

void write_scan_bag(const std::filesystem::path& file, const std::vector<LaserScan>& scans,
                    const std::optional<Pose2>& x_BL, const ScanBagExportOptions& options) {
  write_scan_bag(file, std::vector<RobotScans>{{"", scans, x_BL}}, options);
}

void write_scan_bag(const std::filesystem::path& file, const std::vector<RobotScans>& robots,
                    const ScanBagExportOptions& options) {
  std::unique_ptr<Ros1BagWriter> ros1;
  std::unique_ptr<McapWriter> mcap;
  MessageEncoding encoding = MessageEncoding::ros1;
  Write write;
  if (options.format == BagFormat::ros1) {
    const auto& c = options.compression;
    if (c != "none" && c != "bz2" && c != "lz4") throw std::invalid_argument("ROS 1 bag compression: none, bz2 or lz4");
    ros1 = std::make_unique<Ros1BagWriter>(file, c == "bz2"   ? Ros1BagWriter::Compression::bz2
                                                 : c == "lz4" ? Ros1BagWriter::Compression::lz4
                                                              : Ros1BagWriter::Compression::none);
    write = [&](const std::string& topic, const std::string& type, std::int64_t t, std::span<const std::uint8_t> d) {
      ros1->write(topic, type, t, d);
    };
  } else if (options.format == BagFormat::mcap) {
    const auto& c = options.compression;
    if (c != "none" && c != "zstd") throw std::invalid_argument("MCAP compression: none or zstd");
    mcap = std::make_unique<McapWriter>(file, c == "zstd" ? McapWriter::Compression::zstd : McapWriter::Compression::none);
    encoding = MessageEncoding::cdr;
    write = [&](const std::string& topic, const std::string& type, std::int64_t t, std::span<const std::uint8_t> d) {
      mcap->write(topic, ros2_name(type), t, d);
    };
  } else {
    throw std::invalid_argument("write_scan_bag: lmf writes ROS 1 bags and MCAP files");
  }

  for (const RobotScans& robot : robots) {
    const std::string name = robot.robot_namespace.starts_with('/') ? robot.robot_namespace.substr(1)
                                                                    : robot.robot_namespace;
    const std::string topic_prefix = name.empty() ? "" : "/" + name;
    const std::string frame_prefix = name.empty() ? "" : name + "/";
    const std::vector<LaserScan>& scans = robot.scans;
    const Pose2 mounting = robot.x_BL.value_or(Pose2{});
    const Pose2 x_LB = inverse(mounting);
    const std::int64_t first_ns = scans.empty() ? 0 : scans.front().utime * 1000;
    RosTransform mount;
    mount.header = {first_ns, frame_prefix + "base_link"};
    mount.child_frame_id = frame_prefix + "laser";
    mount.transform = ros_pose(mounting);
    write("/tf_static", "tf2_msgs/TFMessage", first_ns, encode_tf_message({mount}, encoding));

    for (const LaserScan& scan : scans) {
      const std::int64_t t_ns = scan.utime * 1000;
      const Pose2 x_OB = compose(scan.odometry, x_LB);
      if (options.odometry_as_tf) {
        RosTransform t;
        t.header = {t_ns, frame_prefix + "odom"};
        t.child_frame_id = frame_prefix + "base_link";
        t.transform = ros_pose(x_OB);
        write("/tf", "tf2_msgs/TFMessage", t_ns, encode_tf_message({t}, encoding));
      } else {
        RosOdometry o;
        o.header = {t_ns, frame_prefix + "odom"};
        o.child_frame_id = frame_prefix + "base_link";
        o.pose = ros_pose(x_OB);
        write(topic_prefix + "/odom", "nav_msgs/Odometry", t_ns, encode_odometry(o, encoding));
      }
      RosLaserScan s;
      s.header = {t_ns, frame_prefix + "laser"};
      s.angle_min = static_cast<float>(scan.angle_min_rad);
      s.angle_increment = static_cast<float>(scan.angle_increment_rad);
      s.angle_max = static_cast<float>(scan.angle_min_rad +
                                       scan.angle_increment_rad * static_cast<double>(scan.ranges_m.size() - 1));
      s.range_min = 0.0f;
      s.range_max = static_cast<float>(scan.max_range_m);
      s.ranges.assign(scan.ranges_m.begin(), scan.ranges_m.end());
      write(topic_prefix + "/scan", "sensor_msgs/LaserScan", t_ns, encode_laser_scan(s, encoding));
    }
  }
  if (ros1) ros1->close();
  if (mcap) mcap->close();
}

}  // namespace lmf::bag
