// Map error against the true walls (simulator): how far the mapped segments lie
// from the walls they stand for, after the trajectory alignment that maps the
// map frame W into the truth's frame.
#pragma once

#include <vector>

#include <Eigen/Core>

#include "lmf/geometry/pose2.hpp"

namespace lmf::eval {

struct LineSegment {
  Eigen::Vector2d a = Eigen::Vector2d::Zero();  // m
  Eigen::Vector2d b = Eigen::Vector2d::Zero();
};

struct MapError {
  std::size_t segments = 0;           // mapped segments scored
  std::size_t unmatched_segments = 0; // farther than max_distance_m from parallel walls (clutter, ghosts)
  std::size_t points = 0;             // sample points on the matched segments
  double rms_m = 0.0;                 // RMS distance of those points to their wall face
  double max_m = 0.0;
};

// Samples every mapped segment (mapped into the truth's frame by x_TW) every
// `step_m`; each sample's distance is the one to the nearest wall face of the
// same direction (within max_angle_rad, either orientation), so a segment that
// spans several collinear faces (a wall interrupted by doors) is scored
// against all of them, and the part of it that bridges a door counts as error.
// A segment whose samples lie farther than max_distance_m on average matches no
// wall (clutter such as other robots, or a ghost). Throws std::invalid_argument
// for a non-positive step.
MapError map_error(const std::vector<LineSegment>& mapped_in_W, const std::vector<LineSegment>& walls,
                   const Pose2& x_TW, double step_m = 0.1, double max_distance_m = 0.5,
                   double max_angle_rad = 0.3);

}  // namespace lmf::eval
