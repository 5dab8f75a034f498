// A planar laser scan and the odometry pose read with it.
#pragma once

#include <cstdint>
#include <vector>

#include <Eigen/Core>

#include "lmf/geometry/pose2.hpp"

namespace lmf {

struct LaserScan {
  int64_t utime = 0;                 // sensor time, microseconds
  Pose2 odometry;                    // x_OR: robot pose in the odometry frame O when the scan was taken
  double angle_min_rad = 0.0;        // angle of beam 0 in the robot (= sensor) frame
  double angle_increment_rad = 0.0;  // angle between consecutive beams
  double max_range_m = 0.0;          // a reading at or beyond this (minus a small margin) is "no return"
  std::vector<double> ranges_m;      // one per beam, finite and >= 0

  double beam_angle(std::size_t i) const {
    return angle_min_rad + angle_increment_rad * static_cast<double>(i);
  }
  // Beam i's end point in the sensor frame (m).
  Eigen::Vector2d beam_point(std::size_t i) const;
};

// The scan as a laser_scan_t message carries it (angles, maximum range and
// ranges as float; time and odometry unchanged): lmf-offline feeds its local
// maps this, so that agents fed over LCM see the very same numbers.
LaserScan at_message_precision(const LaserScan& scan);

// The angular step of a 180° scan with `num_beams` beams from -pi/2 (datasets/README.md):
// pi/(n-1) for odd n, pi/n for even n.
double beam_increment_for_180deg(std::size_t num_beams);

}  // namespace lmf
