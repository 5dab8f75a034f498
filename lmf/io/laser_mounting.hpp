// The laser's mounting on the robot, x_RS, from a log that records both the
// laser's pose and the robot's pose with every scan (CARMEN FLASER's
// `x y theta` and `odom_x odom_y odom_theta`; ROBOTLASER1's laser and robot
// poses). In a raw log both are odometry poses, x_OS = x_OR ⊕ x_RS, so each
// scan gives x_RS = ⊖x_OR ⊕ x_OS.
//
// lmf's robot frame is the sensor frame (LaserScan): a scan's odometry pose is
// the laser's, x_OR ⊕ x_RS. The mounting is used only when the log shows it to
// be rigid: the per-scan values agree with their median within the tolerance
// below for all but a small fraction of scans. Otherwise the two poses are in
// different frames (a log whose laser pose was corrected by a localiser, say)
// and the robot's pose is kept as it was, with the reason in `note`.
#pragma once

#include <cstddef>
#include <optional>
#include <string>
#include <vector>

#include "lmf/geometry/pose2.hpp"

namespace lmf::io {

struct LaserMountingTolerance {
  // A rigid mount varies between scans only by the log's rounding and by the
  // two poses' timing: at 1 m/s and 1 rad/s a 10 ms skew moves 1 cm and 0.6°.
  // Twice that is the band; a mount shorter than the band is no mount at all.
  double translation_m = 0.02;
  double rotation_rad = 0.02;
  // Scans allowed outside the band (a glitch in a pose field), as a fraction.
  double outlier_fraction = 0.05;
  // A laser sits on the robot: a rigid offset farther than this from the
  // robot's origin (m) is two frames that differ by a constant, not a mount.
  double max_offset_m = 2.0;
};

struct LaserMounting {
  std::optional<Pose2> x_RS;  // set when rigid and distinct from the identity
  std::size_t scans = 0;
  std::size_t scans_outside = 0;  // outside the tolerance band around the median
  std::string note;               // one line for the user: what was found and used
};

// x_RS from each scan's robot pose x_OR and laser pose x_OS (same length).
// Throws std::invalid_argument when the lengths differ.
LaserMounting estimate_laser_mounting(const std::vector<Pose2>& robot_poses, const std::vector<Pose2>& laser_poses,
                                      const LaserMountingTolerance& tolerance = {});

}  // namespace lmf::io
