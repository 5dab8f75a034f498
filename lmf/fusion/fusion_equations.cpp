#include "lmf/fusion/fusion_equations.hpp"

#include <vector>

namespace lmf::fusion {
namespace {

// Placeholder ids for the chains below that never touch a map: measurement_from_chain
// only groups Jacobians by id.
constexpr EntityId kFirst = 0;
constexpr EntityId kSecond = 1;

// ⊖x̂_new as the first link makes a chain's value the perturbation of the new
// entity in its own frame (≈ 0 at the estimate), and its Jacobians the
// derivatives of that perturbation.
spmap::ChainLink own_frame_of(const Pose2& x_new) { return {x_new, EntityKind::kFrame, true, std::nullopt}; }

Eigen::Matrix3d block_of(const spmap::ImplicitMeasurement& m, EntityId id) {
  for (const spmap::JacobianBlock& b : m.blocks) {
    if (b.entity == id) return b.J;
  }
  return Eigen::Matrix3d::Zero();
}

}  // namespace

spmap::ImplicitMeasurement pairing_measurement(const GlobalState& state, EntityId global_segment,
                                               EntityId local_segment) {
  // Eq. (12): the chain ⊖x_FnSi ⊖ x_WFn ⊕ x_WLr ⊕ x_LrSj, rows B = (y, phi).
  return spmap::measurement_from_chain(state.chain_between(global_segment, local_segment), {1, 2});
}

FrameAdvance advance_frame(const Pose2& x_WL, const Pose2& x_LR) {
  FrameAdvance out;
  out.x_WL_next = compose(x_WL, x_LR);
  // p_L' = ⊖x̂_WL' ⊕ (x̂_WL ⊕ p_L) ⊕ (x̂_LR ⊕ p_R).
  const spmap::ImplicitMeasurement m = spmap::measurement_from_chain(
      {own_frame_of(out.x_WL_next), {x_WL, EntityKind::kFrame, false, kFirst},
       {x_LR, EntityKind::kRobot, false, kSecond}},
      {0, 1, 2});
  out.J_L = block_of(m, kFirst);
  out.J_R = block_of(m, kSecond);
  return out;
}

PreviousFrame previous_frame(const Pose2& x_WL_next, const Pose2& x_LR) {
  PreviousFrame out;
  out.x_WL_previous = compose(x_WL_next, inverse(x_LR));
  // p_Lk = ⊖x̂_WLk ⊕ (x̂_WL(k+1) ⊕ p_L(k+1)) ⊕ ⊖(x̂_LR ⊕ p_R).
  const spmap::ImplicitMeasurement m = spmap::measurement_from_chain(
      {own_frame_of(out.x_WL_previous), {x_WL_next, EntityKind::kFrame, false, kFirst},
       {x_LR, EntityKind::kRobot, true, kSecond}},
      {0, 1, 2});
  out.J_next = block_of(m, kFirst);
  out.J_R = block_of(m, kSecond);
  return out;
}

SightedFrame sighted_frame(const Pose2& x_WLA, const RobotSighting& s) {
  SightedFrame out;
  out.x_WLB = compose(compose(compose(x_WLA, s.x_LA), s.x_AB), inverse(s.x_LB));
  // p_LB = ⊖x̂_WLB ⊕ (x̂_WLA ⊕ p_LA) ⊕ (x_LA ⊕ n_LA) ⊕ (x_AB ⊕ n_AB) ⊕ ⊖(x_LB ⊕ n_LB);
  // the n's are outside the map: their covariance enters as R.
  const Eigen::MatrixXd none;
  const spmap::ImplicitMeasurement m = spmap::measurement_from_chain(
      {own_frame_of(out.x_WLB), {x_WLA, EntityKind::kFrame, false, kFirst},
       {s.x_LA, EntityKind::kRobot, false, std::nullopt}, {s.x_AB, EntityKind::kRobot, false, std::nullopt},
       {s.x_LB, EntityKind::kRobot, true, std::nullopt}},
      {0, 1, 2}, {none, none, s.cov_LA, s.cov_AB, s.cov_LB});
  out.J_LA = block_of(m, kFirst);
  out.noise = m.R;
  return out;
}

namespace {

Eigen::MatrixXd world_covariance(const GlobalState& state, EntityId id, const std::vector<int>& rows) {
  std::vector<spmap::ChainLink> links{own_frame_of(state.root_location(id))};
  const std::vector<spmap::ChainLink> chain = state.chain_from_root(id);
  links.insert(links.end(), chain.begin(), chain.end());
  const spmap::ImplicitMeasurement m = spmap::measurement_from_chain(links, rows);
  std::vector<EntityId> ids;
  Eigen::MatrixXd J(static_cast<Eigen::Index>(rows.size()), 0);
  for (const spmap::JacobianBlock& b : m.blocks) {
    ids.push_back(b.entity);
    Eigen::MatrixXd wider(J.rows(), J.cols() + b.J.cols());
    wider << J, b.J;
    J = std::move(wider);
  }
  return J * state.marginal(ids) * J.transpose();
}

}  // namespace

Eigen::Matrix2d segment_world_covariance(const GlobalState& state, EntityId segment) {
  return world_covariance(state, segment, {1, 2});
}

Eigen::Matrix3d frame_world_covariance(const GlobalState& state, EntityId frame) {
  return world_covariance(state, frame, {0, 1, 2});
}

}  // namespace lmf::fusion
