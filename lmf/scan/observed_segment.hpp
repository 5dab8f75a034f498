// A wall segment extracted from one scan, as an SPmap entity E in the sensor frame.
#pragma once

#include <Eigen/Core>

#include "lmf/geometry/pose2.hpp"

namespace lmf {

struct ObservedSegment {
  // x_RE: the segment frame in the sensor (= robot) frame: origin at the
  // midpoint, x along the segment in the scan's counter-clockwise order, so the
  // sensor always lies on the segment's left (positive y of the segment frame):
  // a fixed side, so the two faces of a thin wall are different features.
  Pose2 location;
  double length_m = 0.0;
  // Cov(p_E), p_E = (lateral, angular) perturbation in the segment frame (m, rad).
  Eigen::Matrix2d covariance = Eigen::Matrix2d::Zero();
  Eigen::Vector2d first_point = Eigen::Vector2d::Zero();  // end points in the sensor frame (m)
  Eigen::Vector2d last_point = Eigen::Vector2d::Zero();
  int num_points = 0;  // scan points supporting the fit
};

}  // namespace lmf
