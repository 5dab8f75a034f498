// The equations of the robot local map (docs/design.md §4; paper §II.B), as small pure
// functions so each can be tested against finite differences.
//
// Frames: L the local map's frame (the root of the StochasticMap), R the robot,
// S a map segment, E an observed segment (in R). Perturbations as in
// lmf/spmap/entity.hpp: x = x̂ ⊕ Bᵀ p with B = I3 for R and B = [[0,1,0],[0,0,1]]
// for segments. Pure functions; thread-safe.
#pragma once

#include <Eigen/Core>

#include "lmf/geometry/pose2.hpp"
#include "lmf/local_map/local_map_config.hpp"
#include "lmf/scan/observed_segment.hpp"
#include "lmf/spmap/ekf.hpp"
#include "lmf/spmap/stochastic_map.hpp"

namespace lmf::local_map {

// Step 1, prediction x̂_LR' = x̂_LR ⊕ û. The new perturbation, defined by
// x̂_LR' ⊕ p_R' = (x̂_LR ⊕ p_R) ⊕ (û ⊕ p_u), is to first order
// p_R' = J_R p_R + J_u p_u.
struct PredictionJacobians {
  Pose2 x_LR;          // x̂_LR' (m, rad)
  Eigen::Matrix3d J_R;  // ∂p_R'/∂p_R
  Eigen::Matrix3d J_u;  // ∂p_R'/∂p_u
};
PredictionJacobians prediction_jacobians(const Pose2& x_LR, const Pose2& u);

// Step 1, the configured odometry model (the learner's prior; LocalMapConfig, step 1)
// and its Q = Cov(p_u) for an odometry increment u: diagonal.
OdometryErrorModel odometry_prior(const LocalMapConfig& config);
Eigen::Matrix3d odometry_noise(const Pose2& u, const LocalMapConfig& config);

// Step 3, the implicit measurement of observation E on map segment S
// (paper eqs. 5–7 in the local frame, docs/design.md §4.3):
//   h = B_S (⊖x_LS ⊕ x_LR ⊕ x_RE) = 0,
// rows (lateral, angular) of E's frame in S's frame; H has blocks for S and R;
// R = J_E Cov(p_E) J_Eᵀ. Throws std::invalid_argument if the ids are not a
// segment and a robot of `map`.
spmap::ImplicitMeasurement pairing_measurement(const spmap::StochasticMap& map, spmap::EntityId segment,
                                               spmap::EntityId robot, const ObservedSegment& observation);

// The same measurement in fixed-size, closed form for the hot pairing loop:
// value and Jacobians of h = B_S(⊖x_LS ⊕ x_LR ⊕ x_RE) with respect to p_S, p_R
// and p_E (R = J_E Cov(p_E) J_Eᵀ), and E seen from S. Equal to
// pairing_measurement() (tested). With v = ⊖x_LS ⊕ x_LE (x_LE = x_LR ⊕ x_RE):
//   H_S = [[-1, -v.x], [0, -1]],
//   H_R = [[sin(phi_R - phi_S), cos(phi_R - phi_S), (R(phi_R - phi_S) t_RE).x], [0, 0, 1]],
//   J_E = [[cos(v.phi), 0], [0, 1]].
struct PairingJacobians {
  Eigen::Vector2d h;                // (lateral m, angle rad, wrapped)
  Eigen::Matrix2d H_S;
  Eigen::Matrix<double, 2, 3> H_R;
  Eigen::Matrix2d J_E;
  Pose2 x_SE;                       // v: E seen from S
  double cos_SE = 1.0;              // cos(v.phi)
};

// A location with the cosine and sine of its angle, computed once.
struct RotatedPose {
  Pose2 x;
  double c = 1.0;
  double s = 0.0;
  RotatedPose() = default;
  explicit RotatedPose(const Pose2& pose);
};

// No trigonometry: x_LE must be x_LR ⊕ x_RE.
PairingJacobians pairing_jacobians(const RotatedPose& x_LS, const RotatedPose& x_LR, const Pose2& x_RE,
                                   const RotatedPose& x_LE);
PairingJacobians pairing_jacobians(const Pose2& x_LS, const Pose2& x_LR, const Pose2& x_RE);

// E seen from S at the current estimate: ⊖x̂_LS ⊕ x̂_LR ⊕ x_RE.
Pose2 observation_in_segment(const spmap::StochasticMap& map, spmap::EntityId segment, spmap::EntityId robot,
                             const ObservedSegment& observation);

// Step 8, a new segment from observation E: x_LS = x̂_LR ⊕ x_RE and, to first
// order, p_S = J_R p_R + J_E p_E (p_S = B_S(⊖x̂_LS ⊕ x_LR ⊕ x_RE ⊕ B_Eᵀ p_E)).
struct AdditionJacobians {
  Pose2 x_LS;
  Eigen::Matrix<double, 2, 3> J_R;
  Eigen::Matrix2d J_E;
};
AdditionJacobians addition_jacobians(const Pose2& x_LR, const Pose2& x_RE);

// Step 9, the perfect angular constraint between segments a and b (docs/design.md §4.9):
//   h = angle(⊖x_La ⊕ x_Lb) - target_rad = 0 (wrapped), R = 0,
// target_rad one of 0, ±pi/2, pi (parallel, perpendicular, anti-parallel).
spmap::ImplicitMeasurement angular_constraint(const spmap::StochasticMap& map, spmap::EntityId a,
                                              spmap::EntityId b, double target_rad);

// The multiple of pi/2 nearest to the wrapped angle, in (-pi, pi].
double nearest_right_angle(double angle_rad);

}  // namespace lmf::local_map
