// A robot's local-map frame as the fusion corrected it (light: the agents and
// the wire conversions in runtime/ use it without the fusion core).
#pragma once

#include <cstdint>

#include <Eigen/Core>

#include "lmf/geometry/pose2.hpp"

namespace lmf::fusion {

// The frame L_r in W where robot r's local map `map_seq` begins: the next local
// map the fusion expects from r (every earlier one is fused). On the wire
// (corrected_frames_t) the same frame is sent as last_applied_seq = map_seq - 1.
struct CorrectedFrame {
  int robot_id = 0;
  std::int64_t map_seq = 0;
  Pose2 x_WL;
  Eigen::Matrix3d covariance = Eigen::Matrix3d::Zero();  // of p_L (L's own frame), symmetric PSD
};

}  // namespace lmf::fusion
