// The relations the global map applies when it fuses a local map, each as a
// value plus Jacobians with respect to the perturbations involved (perturbations
// in each entity's own frame, docs/design.md §3). Every Jacobian here has a
// finite-difference test in tests/fusion.
//
// Frames: W global, L_r a robot's local-map frame, F_n a submap frame, R the
// robot at the end of its local map, A/B observer/observed robots.
// All functions are pure and thread-safe.
#pragma once

#include <cstdint>

#include <Eigen/Core>

#include "lmf/fusion/global_state.hpp"
#include "lmf/fusion/robot_sighting.hpp"
#include "lmf/geometry/pose2.hpp"
#include "lmf/spmap/ekf.hpp"

namespace lmf::fusion {

// Paper eq. (12), docs/design.md §5.2: h = B(⊖x_FnSi ⊖ x_WFn ⊕ x_WLr ⊕ x_LrSj) = 0 between
// the global segment S_i (child of its submap F_n) and the local segment S_j
// (child of L_r), both already in `state`. 2 rows (lateral, angle), R = 0:
// with both segments in the state the pairing is a perfect constraint.
spmap::ImplicitMeasurement pairing_measurement(const GlobalState& state, EntityId global_segment,
                                               EntityId local_segment);

// L_r ← L_r ⊕ x_R (docs/design.md §5.6): the next local frame is the robot's final pose.
// With x_WL = x̂_WL ⊕ p_L and x_LR = x̂_LR ⊕ p_R, the new frame's perturbation is
// p_L' = J_L p_L + J_R p_R (to first order) around x̂_WL' = x̂_WL ⊕ x̂_LR.
struct FrameAdvance {
  Pose2 x_WL_next;
  Eigen::Matrix3d J_L;
  Eigen::Matrix3d J_R;
};
FrameAdvance advance_frame(const Pose2& x_WL, const Pose2& x_LR);

// The inverse relation, for local maps that reach the server after a later frame
// of the same robot is already known: L_k = L_{k+1} ⊕ ⊖x_R(k), so
// p_Lk = J_next p_L(k+1) + J_R p_R around x̂_WLk = x̂_WL(k+1) ⊕ ⊖x̂_LR.
struct PreviousFrame {
  Pose2 x_WL_previous;
  Eigen::Matrix3d J_next;
  Eigen::Matrix3d J_R;
};
PreviousFrame previous_frame(const Pose2& x_WL_next, const Pose2& x_LR);

// x_WLB = x_WLA ⊕ x_LA ⊕ x_AB ⊕ ⊖x_LB. The perturbation of L_B is
// p_LB = J_LA p_LA + w with w independent of the map, Cov(w) = noise.
struct SightedFrame {
  Pose2 x_WLB;
  Eigen::Matrix3d J_LA;
  Eigen::Matrix3d noise;
};
SightedFrame sighted_frame(const Pose2& x_WLA, const RobotSighting& sighting);

// Covariance (2x2) of a state segment's (lateral, angular) error seen from W,
// through its parent frames.
Eigen::Matrix2d segment_world_covariance(const GlobalState& state, EntityId segment);

// Covariance (3x3) of an entity's pose error seen from W (its own frame's
// perturbation composed through its parents).
Eigen::Matrix3d frame_world_covariance(const GlobalState& state, EntityId frame);

}  // namespace lmf::fusion
