#include "lmf/bag/bag_scans.hpp"

#include <algorithm>
#include <cmath>
#include <map>
#include <queue>
#include <stdexcept>

#include <Eigen/Geometry>

#include "lmf/bag/bag_file.hpp"
#include "lmf/bag/planar_pose.hpp"
#include "lmf/bag/ros_messages.hpp"

namespace lmf::bag {
namespace {

std::string without_leading_slash(const std::string& name) {
  return name.starts_with('/') ? name.substr(1) : name;
}

const BagTopic* find_topic(const BagSummary& summary, const std::string& name) {
  for (const auto& t : summary.topics) {
    if (without_leading_slash(t.name) == without_leading_slash(name)) return &t;
  }
  return nullptr;
}

std::string topic_list(const BagSummary& summary, bool (*accepts)(const std::string&)) {
  std::string list;
  for (const auto& t : summary.topics) {
    if (accepts != nullptr && !accepts(t.type)) continue;
    list += (list.empty() ? "" : ", ") + t.name + " (" + t.type + ")";
  }
  return list.empty() ? "none" : list;
}

std::vector<const BagTopic*> topics_of_type(const BagSummary& summary, bool (*accepts)(const std::string&)) {
  std::vector<const BagTopic*> found;
  for (const auto& t : summary.topics) {
    if (accepts(t.type)) found.push_back(&t);
  }
  return found;
}

// The topic named, or the only one of its type.
const BagTopic& choose_topic(const BagSummary& summary, const std::string& name, bool (*accepts)(const std::string&),
                             const std::string& what, const std::string& flag) {
  if (!name.empty()) {
    const BagTopic* t = find_topic(summary, name);
    if (t == nullptr) {
      throw std::invalid_argument("no topic " + name + " in the bag; its " + what + " topics: " +
                                  topic_list(summary, accepts));
    }
    if (!accepts(t->type)) throw std::invalid_argument(name + " is a " + t->type + ", not a " + what);
    return *t;
  }
  const auto found = topics_of_type(summary, accepts);
  if (found.size() != 1) {
    throw std::invalid_argument(std::to_string(found.size()) + " " + what + " topics in the bag (" +
                                topic_list(summary, accepts) + "): choose one with " + flag);
  }
  return *found.front();
}

bool finite(const RosPose3& p) { return p.translation.allFinite() && p.rotation.coeffs().allFinite() && p.rotation.norm() > 0.5; }

// A chain of static transforms from `from` to `to`, each usable in either
// direction: T_from,to, or nothing.
std::optional<Eigen::Isometry3d> static_chain(const std::vector<RosTransform>& statics, const std::string& from,
                                              const std::string& to) {
  std::map<std::string, std::vector<std::pair<std::string, Eigen::Isometry3d>>> edges;
  for (const auto& t : statics) {
    const std::string parent = without_leading_slash(t.header.frame_id);
    const std::string child = without_leading_slash(t.child_frame_id);
    const Eigen::Isometry3d T = isometry(t.transform);
    edges[parent].emplace_back(child, T);
    edges[child].emplace_back(parent, T.inverse());
  }
  std::map<std::string, Eigen::Isometry3d> reached{{without_leading_slash(from), Eigen::Isometry3d::Identity()}};
  std::queue<std::string> open;
  open.push(without_leading_slash(from));
  while (!open.empty()) {
    const std::string frame = open.front();
    open.pop();
    if (frame == without_leading_slash(to)) return reached.at(frame);
    for (const auto& [next, T] : edges[frame]) {
      if (reached.contains(next)) continue;
      reached[next] = reached.at(frame) * T;
      open.push(next);
    }
  }
  return std::nullopt;
}

struct StampedPose2 {
  std::int64_t stamp_ns;
  Pose2 pose;
};

// The pose at `t`, interpolated between the samples around it; nothing outside their span.
std::optional<Pose2> interpolate(const std::vector<StampedPose2>& samples, std::int64_t t) {
  if (samples.empty() || t < samples.front().stamp_ns || t > samples.back().stamp_ns) return std::nullopt;
  const auto after = std::lower_bound(samples.begin(), samples.end(), t,
                                      [](const StampedPose2& s, std::int64_t v) { return s.stamp_ns < v; });
  if (after->stamp_ns == t || after == samples.begin()) return after->pose;
  const auto& a = *(after - 1);
  const auto& b = *after;
  const double s = static_cast<double>(t - a.stamp_ns) / static_cast<double>(b.stamp_ns - a.stamp_ns);
  return Pose2::from_vector({a.pose.x + s * (b.pose.x - a.pose.x), a.pose.y + s * (b.pose.y - a.pose.y),
                             a.pose.phi + s * wrap_angle(b.pose.phi - a.pose.phi)});
}

// lmf's LaserScan in the laser's frame: counter-clockwise, "no return" at max_range_m.
std::optional<LaserScan> to_laser_scan(const RosLaserScan& ros, std::size_t& no_returns) {
  const std::size_t n = ros.ranges.size();
  if (n < 2 || !std::isfinite(ros.angle_min) || !std::isfinite(ros.angle_increment) || ros.angle_increment == 0.0f ||
      !std::isfinite(ros.range_max) || !(ros.range_max > 0.0f)) {
    return std::nullopt;
  }
  LaserScan scan;
  scan.max_range_m = ros.range_max;
  scan.ranges_m.reserve(n);
  for (const float r : ros.ranges) {
    // lmf reads any range at or beyond max_range_m as "no return": a finite one
    // beyond range_max keeps its value (as a CARMEN log gives it), the others
    // (NaN, inf, below range_min) become max_range_m.
    const bool usable = std::isfinite(r) && r >= ros.range_min;
    if (!usable || r > ros.range_max) ++no_returns;
    scan.ranges_m.push_back(usable ? static_cast<double>(r) : scan.max_range_m);
  }
  double first = ros.angle_min;
  double step = ros.angle_increment;
  if (step < 0.0) {  // clockwise: reverse into counter-clockwise order
    first += step * static_cast<double>(n - 1);
    step = -step;
    std::reverse(scan.ranges_m.begin(), scan.ranges_m.end());
  }
  scan.angle_min_rad = first;
  scan.angle_increment_rad = step;
  return scan;
}

// The topics under a robot's namespace ("/robot1": "/robot1/scan", ...), or all without one.
BagSummary in_namespace(const BagSummary& all, const std::string& robot_namespace) {
  if (robot_namespace.empty()) return all;
  const std::string prefix = "/" + without_leading_slash(robot_namespace) + "/";
  BagSummary summary = all;
  std::erase_if(summary.topics, [&](const BagTopic& t) { return !("/" + without_leading_slash(t.name)).starts_with(prefix); });
  return summary;
}

// A topic name given relative to the robot's namespace.
std::string under_namespace(const std::string& robot_namespace, const std::string& name) {
  if (robot_namespace.empty() || name.empty()) return name;
  return "/" + without_leading_slash(robot_namespace) + "/" + without_leading_slash(name);
}

}  // namespace

BagScans read_bag_scans(const std::filesystem::path& file, const BagScanOptions& options) {
  const BagSummary everything = summarize_bag(file);
  // A robot's own topics; its /tf and /tf_static, when it has none of its own, are the bag's.
  const BagSummary summary = in_namespace(everything, options.robot_namespace);
  const std::string& ns = options.robot_namespace;
  const auto shared_topic = [&](const std::string& name) {
    const BagTopic* own = ns.empty() ? nullptr : find_topic(summary, under_namespace(ns, name));
    return own != nullptr ? own : find_topic(everything, name);
  };
  const BagTopic& scan_topic = choose_topic(summary, under_namespace(ns, options.scan_topic), is_laser_scan_type,
                                            "LaserScan", "--scan-topic");

  // The odometry source: an Odometry topic, or /tf from odom_frame to base_frame.
  const BagTopic* odom_topic = nullptr;
  const BagTopic* tf_topic = shared_topic("/tf");
  const bool use_tf = !options.no_odometry && options.odom_topic.empty() &&
                      (!options.odom_frame.empty() || !options.base_frame.empty() ||
                       topics_of_type(summary, is_odometry_type).empty());
  if (!options.no_odometry && !use_tf) {
    odom_topic = &choose_topic(summary, under_namespace(ns, options.odom_topic), is_odometry_type, "Odometry",
                               "--odom-topic");
  }
  if (use_tf && (tf_topic == nullptr || !is_tf_type(tf_topic->type))) {
    throw std::invalid_argument("no odometry in the bag: no nav_msgs/Odometry topic and no /tf (topics: " +
                                topic_list(summary, nullptr) + "); map with --no-odometry");
  }
  // The odometry frame: given, or "odom", or in a namespace also "<robot>/odom" (tf_prefix style).
  std::vector<std::string> odom_frames{options.odom_frame.empty() ? "odom" : without_leading_slash(options.odom_frame)};
  if (options.odom_frame.empty() && !ns.empty()) odom_frames.push_back(without_leading_slash(ns) + "/odom");
  std::string odom_frame = odom_frames.front();
  std::string base_frame = without_leading_slash(options.base_frame);

  std::set<std::string> wanted{scan_topic.name};
  if (odom_topic != nullptr) wanted.insert(odom_topic->name);
  if (use_tf) wanted.insert(tf_topic->name);
  const BagTopic* tf_static_topic = shared_topic("/tf_static");
  if (tf_static_topic != nullptr && is_tf_type(tf_static_topic->type)) wanted.insert(tf_static_topic->name);

  BagScans out;
  std::vector<std::pair<RosHeader, LaserScan>> laser_scans;
  std::vector<StampedPose2> odometry;
  std::vector<RosTransform> statics;
  std::map<std::string, std::map<std::string, std::vector<StampedPose2>>> tf_edges;  // parent -> child -> poses
  std::string odometry_child;
  std::map<std::string, std::size_t> index;
  for_each_bag_message(file, wanted, [&](const BagMessage& m) {
    const std::size_t i = index[m.topic]++;
    try {
      if (m.topic == scan_topic.name) {
        RosLaserScan ros = decode_laser_scan(m.data, m.encoding);
        if (ros.header.stamp_ns == 0) ros.header.stamp_ns = m.log_time_ns;
        std::size_t no_returns = 0;
        auto scan = to_laser_scan(ros, no_returns);
        if (!scan) {
          ++out.rejected_scans;
          return;
        }
        out.no_return_readings += no_returns;
        scan->utime = ros.header.stamp_ns / 1000;
        laser_scans.emplace_back(ros.header, std::move(*scan));
      } else if (odom_topic != nullptr && m.topic == odom_topic->name) {
        const RosOdometry o = decode_odometry(m.data, m.encoding);
        if (!finite(o.pose)) return;
        odometry_child = without_leading_slash(o.child_frame_id);
        odometry.push_back({o.header.stamp_ns == 0 ? m.log_time_ns : o.header.stamp_ns, planar_pose(o.pose)});
      } else if (tf_static_topic != nullptr && m.topic == tf_static_topic->name) {
        for (auto& t : decode_tf_message(m.data, m.encoding)) {
          if (finite(t.transform)) statics.push_back(std::move(t));
        }
      } else if (use_tf && m.topic == tf_topic->name) {
        for (const auto& t : decode_tf_message(m.data, m.encoding)) {
          const std::string parent = without_leading_slash(t.header.frame_id);
          if (std::find(odom_frames.begin(), odom_frames.end(), parent) == odom_frames.end() || !finite(t.transform)) {
            continue;
          }
          tf_edges[parent][without_leading_slash(t.child_frame_id)].push_back(
              {t.header.stamp_ns, planar_pose(t.transform)});
        }
      }
    } catch (const WireDecodeError& e) {
      throw BagFormatError(file, m.topic + " message " + std::to_string(i) + " (" + m.type + "): " + e.what());
    }
  });

  if (use_tf) {
    for (const auto& candidate : odom_frames) {
      if (tf_edges.contains(candidate)) {
        odom_frame = candidate;
        break;
      }
    }
    auto& tf_children = tf_edges[odom_frame];
    if (base_frame.empty()) {
      if (tf_children.size() != 1) {
        std::string children;
        for (const auto& [child, poses] : tf_children) children += (children.empty() ? "" : ", ") + child;
        throw std::invalid_argument("/tf has " + std::to_string(tf_children.size()) + " children of \"" + odom_frame +
                                    "\" (" + (children.empty() ? "none" : children) +
                                    "): name the robot's with --base-frame, or the odometry frame with --odom-frame");
      }
      base_frame = tf_children.begin()->first;
    }
    if (!tf_children.contains(base_frame)) {
      throw std::invalid_argument("/tf has no transform from \"" + odom_frame + "\" to \"" + base_frame + "\"");
    }
    odometry = std::move(tf_children[base_frame]);
    out.notes.push_back("odometry: /tf " + odom_frame + " -> " + base_frame + ", " + std::to_string(odometry.size()) +
                        " poses");
  } else if (odom_topic != nullptr) {
    base_frame = odometry_child;
    out.notes.push_back("odometry: " + odom_topic->name + " (" + std::to_string(odometry.size()) + " poses, base \"" +
                        base_frame + "\")");
  } else {
    out.notes.push_back("no odometry (--no-odometry): the scan matcher carries the motion");
  }
  std::stable_sort(odometry.begin(), odometry.end(),
                   [](const StampedPose2& a, const StampedPose2& b) { return a.stamp_ns < b.stamp_ns; });

  // The laser's mounting on the base.
  const std::string laser_frame = laser_scans.empty() ? "" : without_leading_slash(laser_scans.front().first.frame_id);
  Pose2 x_BL;
  bool mirrored = false;
  if (options.laser_mounting) {
    x_BL = *options.laser_mounting;
    out.notes.push_back("laser mounting: given");
  } else if (!options.no_odometry && !laser_frame.empty() && laser_frame != base_frame) {
    const auto T_BL = static_chain(statics, base_frame, laser_frame);
    if (T_BL) {
      x_BL = planar_pose(*T_BL);
      mirrored = T_BL->rotation()(2, 2) < 0.0;
      out.notes.push_back("laser mounting: /tf_static " + base_frame + " -> " + laser_frame + " (" +
                          std::to_string(x_BL.x) + ", " + std::to_string(x_BL.y) + ", " + std::to_string(x_BL.phi) +
                          " rad" + (mirrored ? ", upside down" : "") + ")");
    } else {
      out.notes.push_back("laser mounting: no /tf_static chain " + base_frame + " -> " + laser_frame +
                          ": the laser is taken to sit at the base's origin (give --laser-mounting)");
    }
  }

  std::stable_sort(laser_scans.begin(), laser_scans.end(),
                   [](const auto& a, const auto& b) { return a.second.utime < b.second.utime; });
  for (auto& [header, scan] : laser_scans) {
    if (mirrored) {
      // Seen from above, a laser mounted upside down turns the other way: every
      // angle changes sign, and reversing the beams keeps them counter-clockwise.
      std::reverse(scan.ranges_m.begin(), scan.ranges_m.end());
      scan.angle_min_rad = -(scan.angle_min_rad + scan.angle_increment_rad * static_cast<double>(scan.ranges_m.size() - 1));
    }
    if (!options.no_odometry) {
      const auto x_OB = interpolate(odometry, header.stamp_ns);
      if (!x_OB) {
        ++out.scans_outside_odometry;
        continue;
      }
      scan.odometry = compose(*x_OB, x_BL);
    }
    out.scans.push_back(std::move(scan));
  }
  out.notes.push_back("scans: " + scan_topic.name + ", " + std::to_string(out.scans.size()) + " used");
  if (!ns.empty()) out.notes.push_back("robot namespace: " + ns);
  if (summary.cut_short) out.notes.push_back("CUT SHORT: " + *summary.cut_short + " (read up to there)");
  if (out.scans_outside_odometry > 0) {
    out.notes.push_back(std::to_string(out.scans_outside_odometry) + " scans outside the odometry's time span dropped");
  }
  if (out.rejected_scans > 0) {
    out.notes.push_back(std::to_string(out.rejected_scans) + " scans with unusable geometry rejected");
  }
  if (out.no_return_readings > 0) {
    out.notes.push_back(std::to_string(out.no_return_readings) +
                        " readings NaN, infinite or outside [range_min, range_max] read as \"no return\"");
  }
  return out;
}

}  // namespace lmf::bag
