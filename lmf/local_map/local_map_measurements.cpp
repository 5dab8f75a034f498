#include "lmf/local_map/local_map_measurements.hpp"

#include <cmath>
#include <numbers>
#include <stdexcept>
#include <string>
#include <vector>

#include "lmf/spmap/relative_location.hpp"

namespace lmf::local_map {
namespace {

using spmap::ChainLink;
using spmap::EntityKind;

void require_kind(const spmap::StochasticMap& map, spmap::EntityId id, EntityKind kind, const char* where) {
  if (!map.contains(id) || map.entity(id).kind != kind) {
    throw std::invalid_argument(std::string(where) + ": entity " + std::to_string(id) + " is not a " +
                                (kind == EntityKind::kSegment ? "segment" : "robot") + " of the map");
  }
}

}  // namespace

PredictionJacobians prediction_jacobians(const Pose2& x_LR, const Pose2& u) {
  PredictionJacobians out;
  out.x_LR = compose(x_LR, u);
  // p_R' = ⊖x̂_LR' ⊕ (x̂_LR ⊕ p_R) ⊕ (û ⊕ p_u): a chain whose value is the identity
  // at p = 0, so its Jacobians are those of the new perturbation (docs/design.md §4.1).
  const std::vector<ChainLink> links = {
      {inverse(out.x_LR), EntityKind::kFrame, false, std::nullopt},
      {x_LR, EntityKind::kRobot, false, std::nullopt},
      {u, EntityKind::kFrame, false, std::nullopt},
  };
  const spmap::ChainValue chain = spmap::evaluate_chain(links);
  out.J_R = chain.jacobians[1];
  out.J_u = chain.jacobians[2];
  return out;
}

OdometryErrorModel odometry_prior(const LocalMapConfig& config) {
  // Proportional odometry error (paper §IV; LocalMapConfig, step 1).
  return OdometryErrorModel::proportional(config.odom_translation_noise_ratio, config.odom_rotation_noise_ratio,
                                          config.odom_drift_rad_per_m, config.odom_noise_floor_m,
                                          config.odom_noise_floor_rad);
}

Eigen::Matrix3d odometry_noise(const Pose2& u, const LocalMapConfig& config) {
  return odometry_prior(config).covariance(u);
}

spmap::ImplicitMeasurement pairing_measurement(const spmap::StochasticMap& map, spmap::EntityId segment,
                                               spmap::EntityId robot, const ObservedSegment& observation) {
  require_kind(map, segment, EntityKind::kSegment, "pairing_measurement");
  require_kind(map, robot, EntityKind::kRobot, "pairing_measurement");
  // Paper eqs. (5)–(7) in the local frame: h = B_S(⊖x_LS ⊕ x_LR ⊕ x_RE), with S
  // inverted, R, and E whose perturbation is observation noise, not state.
  std::vector<ChainLink> links = spmap::chain_between(map, segment, robot);
  links.push_back({observation.location, EntityKind::kSegment, false, std::nullopt});
  std::vector<Eigen::MatrixXd> noise;
  noise.reserve(links.size());
  for (const ChainLink& link : links) {
    const int n = spmap::dof(link.kind);
    noise.push_back(link.entity ? Eigen::MatrixXd::Zero(n, n) : Eigen::MatrixXd(observation.covariance));
  }
  return spmap::measurement_from_chain(links, {1, 2}, noise);
}

RotatedPose::RotatedPose(const Pose2& pose) : x(pose), c(std::cos(pose.phi)), s(std::sin(pose.phi)) {}

PairingJacobians pairing_jacobians(const RotatedPose& x_LS, const RotatedPose& x_LR, const Pose2& x_RE,
                                   const RotatedPose& x_LE) {
  PairingJacobians out;
  // v = ⊖x_LS ⊕ x_LE: E's frame in S's frame.
  const double dx = x_LE.x.x - x_LS.x.x;
  const double dy = x_LE.x.y - x_LS.x.y;
  const double vx = x_LS.c * dx + x_LS.s * dy;
  const double vy = -x_LS.s * dx + x_LS.c * dy;
  out.cos_SE = x_LE.c * x_LS.c + x_LE.s * x_LS.s;
  out.x_SE = Pose2(vx, vy, wrap_angle(x_LE.x.phi - x_LS.x.phi));
  out.h = {vy, out.x_SE.phi};
  // S's perturbation moves its frame: the lateral error at E's midpoint is
  // -p_y - v.x p_phi; the angle -p_phi.
  out.H_S << -1.0, -vx, 0.0, -1.0;
  // R's perturbation (in R's frame) seen in S's frame: rotation by phi_R - phi_S.
  const double c_rs = x_LR.c * x_LS.c + x_LR.s * x_LS.s;
  const double s_rs = x_LR.s * x_LS.c - x_LR.c * x_LS.s;
  const double e_x = c_rs * x_RE.x - s_rs * x_RE.y;  // (R(phi_R - phi_S) t_RE).x
  out.H_R << s_rs, c_rs, e_x, 0.0, 0.0, 1.0;
  // E's lateral error is along E's own normal: cos of E's angle in S.
  out.J_E << out.cos_SE, 0.0, 0.0, 1.0;
  return out;
}

PairingJacobians pairing_jacobians(const Pose2& x_LS, const Pose2& x_LR, const Pose2& x_RE) {
  return pairing_jacobians(RotatedPose(x_LS), RotatedPose(x_LR), x_RE, RotatedPose(compose(x_LR, x_RE)));
}

Pose2 observation_in_segment(const spmap::StochasticMap& map, spmap::EntityId segment, spmap::EntityId robot,
                             const ObservedSegment& observation) {
  return compose(between(map.root_location(segment), map.root_location(robot)), observation.location);
}

AdditionJacobians addition_jacobians(const Pose2& x_LR, const Pose2& x_RE) {
  AdditionJacobians out;
  out.x_LS = compose(x_LR, x_RE);
  // p_S = B_S(⊖x̂_LS ⊕ (x̂_LR ⊕ p_R) ⊕ (x_RE ⊕ B_Eᵀ p_E)), identity at p = 0 (docs/design.md §4.8).
  const std::vector<ChainLink> links = {
      {inverse(out.x_LS), EntityKind::kFrame, false, std::nullopt},
      {x_LR, EntityKind::kRobot, false, std::nullopt},
      {x_RE, EntityKind::kSegment, false, std::nullopt},
  };
  const spmap::ChainValue chain = spmap::evaluate_chain(links);
  out.J_R = chain.jacobians[1].bottomRows<2>();
  out.J_E = chain.jacobians[2].bottomRows<2>();
  return out;
}

spmap::ImplicitMeasurement angular_constraint(const spmap::StochasticMap& map, spmap::EntityId a,
                                              spmap::EntityId b, double target_rad) {
  require_kind(map, a, EntityKind::kSegment, "angular_constraint");
  require_kind(map, b, EntityKind::kSegment, "angular_constraint");
  // docs/design.md §4.9: a perfect (R = 0) constraint on the relative angle only.
  const std::vector<ChainLink> links = spmap::chain_between(map, a, b);
  Eigen::VectorXd target(1);
  target(0) = target_rad;
  return spmap::measurement_from_chain(links, {2}, {}, target);
}

double nearest_right_angle(double angle_rad) {
  constexpr double kHalfPi = std::numbers::pi / 2.0;
  const double quarter_turns = std::round(wrap_angle(angle_rad) / kHalfPi);
  return wrap_angle(quarter_turns * kHalfPi);
}

}  // namespace lmf::local_map
