#include "lmf/io/laser_mounting.hpp"

#include <algorithm>
#include <cmath>
#include <utility>
#include <numbers>
#include <sstream>
#include <stdexcept>

#include "lmf/common/median.hpp"

namespace lmf::io {
namespace {

std::string describe(const Pose2& x) {
  std::ostringstream out;
  out.precision(3);
  out << std::fixed << "(" << x.x << " m, " << x.y << " m, " << x.phi * 180.0 / std::numbers::pi << " deg)";
  return out.str();
}

}  // namespace

LaserMounting estimate_laser_mounting(const std::vector<Pose2>& robot_poses, const std::vector<Pose2>& laser_poses,
                                      const LaserMountingTolerance& tolerance) {
  if (robot_poses.size() != laser_poses.size()) {
    throw std::invalid_argument("estimate_laser_mounting: " + std::to_string(robot_poses.size()) +
                                " robot poses but " + std::to_string(laser_poses.size()) + " laser poses");
  }
  LaserMounting out;
  out.scans = robot_poses.size();
  if (out.scans == 0) {
    out.note = "no scans";
    return out;
  }
  std::vector<Pose2> mounts;
  mounts.reserve(out.scans);
  for (std::size_t i = 0; i < out.scans; ++i) mounts.push_back(between(robot_poses[i], laser_poses[i]));

  // The median per component; the angle about the first scan's, so a mount
  // near ±π does not average across the cut.
  std::vector<double> xs, ys, dphis;
  for (const Pose2& m : mounts) {
    xs.push_back(m.x);
    ys.push_back(m.y);
    dphis.push_back(wrap_angle(m.phi - mounts.front().phi));
  }
  const Pose2 x_RS(median(xs), median(ys), wrap_angle(mounts.front().phi + median(dphis)));
  for (const Pose2& m : mounts) {
    if (!is_near(m, x_RS, tolerance.translation_m, tolerance.rotation_rad)) ++out.scans_outside;
  }
  const double outside = static_cast<double>(out.scans_outside) / static_cast<double>(out.scans);
  if (outside > tolerance.outlier_fraction) {
    std::ostringstream note;
    note << "laser pose not used: its offset from the robot pose varies (" << out.scans_outside << " of " << out.scans
         << " scans beyond " << tolerance.translation_m << " m / " << tolerance.rotation_rad
         << " rad of the median " << describe(x_RS) << "), so the two poses are in different frames";
    out.note = note.str();
    return out;
  }
  if (!(std::hypot(x_RS.x, x_RS.y) <= tolerance.max_offset_m)) {
    out.note = "laser pose not used: its offset from the robot pose " + describe(x_RS) + " is constant but farther than " +
               std::to_string(tolerance.max_offset_m) + " m, so it is a frame offset, not a mount";
    return out;
  }
  if (is_near(x_RS, Pose2(), tolerance.translation_m, tolerance.rotation_rad)) {
    out.note = "laser at the robot's pose (no mounting offset in the log)";
    return out;
  }
  out.x_RS = x_RS;
  out.note = "laser mounted at x_RS = " + describe(x_RS) + " (from the log's laser and robot poses; " +
             std::to_string(out.scans_outside) + " of " + std::to_string(out.scans) + " scans outside the band)";
  return out;
}

}  // namespace lmf::io
