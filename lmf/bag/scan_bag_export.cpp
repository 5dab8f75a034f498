#include "lmf/bag/scan_bag_export.hpp"

#include <cmath>

#include "lmf/bag/ros_messages.hpp"
#include "lmf/bag/wire_encoder.hpp"

namespace lmf::bag {
namespace {

RosPose3 pose3(const Pose2& x) {
  RosPose3 p;
  p.translation = {x.x, x.y, 0.0};
  p.rotation = Eigen::Quaterniond(Eigen::AngleAxisd(x.phi, Eigen::Vector3d::UnitZ()));
  return p;
}

}  // namespace

void write_ros1_scan_bag(const std::filesystem::path& file, const std::vector<LaserScan>& scans,
                         const std::optional<Pose2>& x_BL, const ScanBagExportOptions& options) {
  constexpr auto kRos1 = MessageEncoding::ros1;
  Ros1BagWriter bag(file, options.compression);
  const Pose2 mounting = x_BL.value_or(Pose2{});
  const Pose2 x_LB = inverse(mounting);
  const std::int64_t first_ns = scans.empty() ? 0 : scans.front().utime * 1000;

  RosTransform mount;
  mount.header = {first_ns, "base_link"};
  mount.child_frame_id = "laser";
  mount.transform = pose3(mounting);
  bag.write("/tf_static", "tf2_msgs/TFMessage", first_ns, encode_tf_message({mount}, kRos1));

  for (const LaserScan& scan : scans) {
    const std::int64_t t_ns = scan.utime * 1000;
    const Pose2 x_OB = compose(scan.odometry, x_LB);
    if (options.odometry_as_tf) {
      RosTransform t;
      t.header = {t_ns, "odom"};
      t.child_frame_id = "base_link";
      t.transform = pose3(x_OB);
      bag.write("/tf", "tf2_msgs/TFMessage", t_ns, encode_tf_message({t}, kRos1));
    } else {
      RosOdometry o;
      o.header = {t_ns, "odom"};
      o.child_frame_id = "base_link";
      o.pose = pose3(x_OB);
      bag.write("/odom", "nav_msgs/Odometry", t_ns, encode_odometry(o, kRos1));
    }
    RosLaserScan s;
    s.header = {t_ns, "laser"};
    s.angle_min = static_cast<float>(scan.angle_min_rad);
    s.angle_increment = static_cast<float>(scan.angle_increment_rad);
    s.angle_max = static_cast<float>(scan.angle_min_rad +
                                     scan.angle_increment_rad * static_cast<double>(scan.ranges_m.size() - 1));
    s.range_min = 0.0f;
    s.range_max = static_cast<float>(scan.max_range_m);
    s.ranges.assign(scan.ranges_m.begin(), scan.ranges_m.end());
    bag.write("/scan", "sensor_msgs/LaserScan", t_ns, encode_laser_scan(s, kRos1));
  }
  bag.close();
}

}  // namespace lmf::bag
