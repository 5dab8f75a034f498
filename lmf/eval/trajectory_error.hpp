// Trajectory scoring against a reference (datasets/README.md): poses associated
// by timestamp, one rigid SE(2) alignment, then ATE (RMSE of position and
// heading) and RPE (errors of the relative motion over a given travelled distance).
#pragma once

#include <cstdint>
#include <optional>
#include <vector>

#include "lmf/geometry/pose2.hpp"
#include "lmf/geometry/stamped_pose.hpp"

namespace lmf::eval {

struct PosePair {
  Pose2 estimate;
  Pose2 reference;
};

// Pairs each estimate with the reference pose of the nearest timestamp within
// `tolerance_us`; estimates without one are left out. Both inputs must be sorted
// by time (throws std::invalid_argument otherwise).
std::vector<PosePair> associate_by_time(const std::vector<StampedPose>& estimate,
                                        const std::vector<StampedPose>& reference, int64_t tolerance_us = 1000);

// The rigid transform x_RE (reference frame R from estimate frame E) minimising
// Σ |p_ref - x_RE(p_est)|² over positions (closed form, 2-D Kabsch without scale).
// Throws std::invalid_argument with fewer than 2 pairs.
Pose2 align_se2(const std::vector<PosePair>& pairs);

struct AbsoluteError {
  std::size_t count = 0;
  double position_rmse_m = 0.0;
  double heading_rmse_deg = 0.0;
  double position_max_m = 0.0;
  Pose2 alignment;  // x_RE applied to the estimate
};

// ATE after align_se2 (or with the identity when `align` is false).
AbsoluteError absolute_trajectory_error(const std::vector<PosePair>& pairs, bool align = true);

struct RelativeError {
  double distance_m = 0.0;   // travelled distance the relative motions span
  std::size_t count = 0;     // relative motions scored
  double translation_rmse_m = 0.0;
  double rotation_rmse_deg = 0.0;
};

// RPE: for every pair i, the first later pair j at least `distance_m` further
// along the reference path; compares between(est_i, est_j) with
// between(ref_i, ref_j). Pairs must be in time order. count = 0 when the path is shorter.
RelativeError relative_pose_error(const std::vector<PosePair>& pairs, double distance_m);

// Path length of the reference poses, in order.
double reference_path_length(const std::vector<PosePair>& pairs);

}  // namespace lmf::eval
