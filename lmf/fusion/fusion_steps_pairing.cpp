// Steps 1-3 of the fusion (docs/design.md §5): augmentation, the pairing tests and the
// EKF update (fusion_steps.hpp).
#include <algorithm>
#include <cmath>
#include <cstdint>
#include <numeric>
#include <unordered_map>

#include <Eigen/Eigenvalues>

#include "lmf/fusion/fusion_equations.hpp"
#include "lmf/fusion/fusion_steps.hpp"
#include "lmf/spmap/careful_inverse.hpp"
#include "lmf/spmap/segment_ops.hpp"

namespace lmf::fusion {

FusionContext::FusionContext(GlobalState& state_in, const GlobalMapConfig& config_in, int robot, const LocalMapSnapshot& s,
                             const RobotArrivals::FrameSlot& frame)
    : state(state_in),
      config(config_in),
      robot_id(robot),
      snapshot(s),
      L(frame.frame),
      anchored_robot(frame.robot),
      careful{config_in.careful_relative_tolerance, config_in.careful_absolute_floor},
      chi2(config_in.alpha) {
  report.robot_id = robot;
  report.seq = s.seq;
  report.local_segments = static_cast<int>(s.segments.size());
  report.anchored_backward = anchored();
}

// ---------------------------------------------------------------------------
// Step 1: augmentation

void augment(FusionContext& f) {
  // Eq. (4): the local map is independent of the global one,
  // P⁻ = [[P, 0], [0, P_Mr]]; robot and local segments are children of L_r.
  GlobalState& state = f.state;
  const LocalMapSnapshot& s = f.snapshot;
  f.report.x_WL_predicted = state.root_location(f.L);
  const Eigen::MatrixXd P_Mr = f.config.local_map_covariance_scale * s.covariance;
  const std::size_t k = s.segments.size();
  const auto k_rows = static_cast<Eigen::Index>(2 * k);
  f.local.resize(k);
  std::vector<GlobalState::NewEntity> additions;
  if (!f.anchored()) additions.push_back({EntityKind::kRobot, s.x_LR, f.L, 0.0});
  for (const SegmentEstimate& seg : s.segments) additions.push_back({EntityKind::kSegment, seg.location, f.L, seg.length_m});
  const std::vector<EntityId> added = state.add_many(additions);
  std::copy(added.end() - static_cast<std::ptrdiff_t>(k), added.end(), f.local.begin());
  if (!f.anchored()) {
    f.R = added.front();
    state.set_marginal(added, P_Mr);
    return;
  }
  // The robot is already in the state (it defined L_r); the segments join
  // conditioned on it: p_S = A p_R + w, A = P_SR P_RR⁺, Cov(w) = P_SS − A P_RS.
  f.R = *f.anchored_robot;
  const Eigen::MatrixXd P_RR = P_Mr.topLeftCorner(3, 3);
  const Eigen::MatrixXd P_SR = P_Mr.bottomLeftCorner(k_rows, 3);
  const spmap::CarefulInverse ci = spmap::careful_inverse(P_RR, f.config.careful_relative_tolerance);
  Eigen::MatrixXd P_RR_pinv = Eigen::MatrixXd::Zero(3, 3);
  for (std::size_t a = 0; a < ci.kept.size(); ++a) {
    for (std::size_t b = 0; b < ci.kept.size(); ++b) {
      P_RR_pinv(ci.kept[a], ci.kept[b]) = ci.inverse(static_cast<Eigen::Index>(a), static_cast<Eigen::Index>(b));
    }
  }
  const Eigen::MatrixXd A = P_SR * P_RR_pinv;
  for (std::size_t j = 0; j < k; ++j) {
    state.replace_perturbation(f.local[j], {{f.R, A.middleRows(static_cast<Eigen::Index>(2 * j), 2)}});
  }
  Eigen::MatrixXd residual = P_Mr.bottomRightCorner(k_rows, k_rows) - A * P_SR.transpose();
  residual = (0.5 * (residual + residual.transpose())).eval();
  state.add_to_marginal(f.local, residual);
}

// ---------------------------------------------------------------------------
// Step 2: gate, individual compatibility and overlap

namespace {

// A segment as the gate sees it: midpoint and direction in its parent frame,
// and the standard deviations of its own (lateral, angular) error.
struct GateSegment {
  EntityId id = 0;
  Pose2 location;  // in the parent frame
  double c = 1.0;  // cos, sin of location.phi
  double s = 0.0;
  double half_length = 0.0;
  double sigma_lateral = 0.0;  // m
  double sigma_angle = 0.0;    // rad
};

GateSegment gate_segment(const GlobalState& state, const Entity& e) {
  return {e.id,
          e.location,
          std::cos(e.location.phi),
          std::sin(e.location.phi),
          0.5 * e.length_m,
          std::sqrt(std::max(0.0, state.covariance(e.offset, e.offset))),
          std::sqrt(std::max(0.0, state.covariance(e.offset + 1, e.offset + 1)))};
}

// The relative location x_FL = ⊖x_WF ⊕ x_WL of L_r in a submap F and the
// covariance of its (x, y, phi).
struct RelativeFrame {
  Pose2 x_FL;
  Eigen::Matrix3d Sigma;
};

RelativeFrame relative_frame(const GlobalState& state, EntityId F, EntityId L, const Pose2& x_WL) {
  const Pose2 x_WF = state.root_location(F);
  const spmap::ImplicitMeasurement relative = spmap::measurement_from_chain(
      {{x_WF, EntityKind::kFrame, true, F}, {x_WL, EntityKind::kFrame, false, L}}, {0, 1, 2});
  Eigen::MatrixXd J(3, 6);
  J.leftCols(3) = relative.blocks[0].entity == F ? relative.blocks[0].J : relative.blocks[1].J;
  J.rightCols(3) = relative.blocks[0].entity == F ? relative.blocks[1].J : relative.blocks[0].J;
  return {between(x_WF, x_WL), J * state.marginal({F, L}) * J.transpose()};
}

// Whether the local segment l (midpoint x_F_Sj in F, position covariance cov_p)
// and the global segment g of F may be one wall: angle, lateral offset and
// extent gap within the fixed gate plus gate_sigmas conservative standard
// deviations (|cov| <= σa σb: the gate is never narrower than chi2 would need).
bool passes_gate(const GlobalMapConfig& config, const GateSegment& g, const GateSegment& l, const Pose2& x_F_Sj,
                 const Eigen::Matrix2d& cov_p, double sigma_frame_angle) {
  const double gs = config.gate_sigmas;
  const double angle_sigma = sigma_frame_angle + g.sigma_angle + l.sigma_angle;
  if (std::abs(wrap_angle(x_F_Sj.phi - g.location.phi)) > config.gate_angle_rad + gs * angle_sigma) return false;
  const Eigen::Vector2d d(x_F_Sj.x - g.location.x, x_F_Sj.y - g.location.y);
  const Eigen::Vector2d t(g.c, g.s);
  const Eigen::Vector2d nrm(-g.s, g.c);
  const double along = t.dot(d);
  const double lateral = nrm.dot(d);
  const double lateral_sigma = std::sqrt(std::max(0.0, nrm.dot(cov_p * nrm))) + g.sigma_lateral +
                               std::abs(along) * g.sigma_angle + l.sigma_lateral;
  if (std::abs(lateral) > config.gate_distance_m + gs * lateral_sigma) return false;
  // Extent gap along the global segment's axis (projection of the local one).
  const double reach = l.half_length * std::abs(std::cos(x_F_Sj.phi - g.location.phi));
  const double gap = std::max(along - reach - g.half_length, -g.half_length - (along + reach));
  const double along_sigma = std::sqrt(std::max(0.0, t.dot(cov_p * t)));
  return !(gap > config.gate_gap_m + gs * along_sigma);
}

// Whether the registration's window holds the χ² region (3 dof, `chi2`) of
// the frame relative to a submap, covariance Sigma: along every axis
// sqrt(chi2 Σ_ii) at most the window, the position's by its largest
// eigenvalue. Beyond it the registration could not have seen that submap's
// walls where the frame may be, and its finding nothing says nothing.
bool window_holds(const FrameRegistrationConfig& registration, const Eigen::Matrix3d& Sigma, double chi2) {
  const double position_variance = Eigen::SelfAdjointEigenSolver<Eigen::Matrix2d>(
                                       Sigma.topLeftCorner<2, 2>(), Eigen::EigenvaluesOnly).eigenvalues().maxCoeff();
  return chi2 * position_variance <= registration.window_m * registration.window_m &&
         chi2 * Sigma(2, 2) <= registration.window_rad * registration.window_rad;
}

}  // namespace

void gate(FusionContext& f) {
  // Per submap F_n in F_n's frame with the RELATIVE covariance of L_r and F_n
  // (their absolute uncertainty grows without bound in a large map while the
  // relative one stays small).
  const GlobalState& state = f.state;
  std::vector<EntityId> submap_order;
  std::unordered_map<EntityId, std::vector<GateSegment>> by_submap;
  for (const Entity& e : state.entities()) {
    if (e.kind != EntityKind::kSegment || !e.parent || *e.parent == f.L) continue;
    auto [it, inserted] = by_submap.try_emplace(*e.parent);
    if (inserted) submap_order.push_back(*e.parent);
    it->second.push_back(gate_segment(state, e));
  }
  std::vector<GateSegment> locals;
  for (const EntityId id : f.local) locals.push_back(gate_segment(state, state.entity(id)));
  const Pose2 x_WL = state.root_location(f.L);
  std::int64_t globals_count = 0;
  // Pairings with the established map (every submap but the robot's own
  // recent ones, which drifted with its frame) close a loop or join two
  // robots' maps: where the registration searched and found nothing, they are
  // not made (FrameRegistrationConfig::confirm_pairings).
  const bool found_nothing = f.config.registration.confirm_pairings &&
                             f.report.registration == RegistrationOutcome::kNothingNearby;
  for (const EntityId F : submap_order) {
    const std::vector<GateSegment>& globals = by_submap.at(F);
    globals_count += static_cast<std::int64_t>(globals.size());
    const RelativeFrame rel = relative_frame(state, F, f.L, x_WL);
    const bool confirmed = !found_nothing || f.own_recent_submaps.contains(F) ||
                           !window_holds(f.config.registration, rel.Sigma, f.chi2(3));
    const double sigma_frame_angle = std::sqrt(std::max(0.0, rel.Sigma(2, 2)));
    const double cf = std::cos(rel.x_FL.phi);
    const double sf = std::sin(rel.x_FL.phi);
    for (std::size_t j = 0; j < locals.size(); ++j) {
      const GateSegment& l = locals[j];
      // The local midpoint in F and the covariance of its position from Sigma.
      const Pose2 x_F_Sj = compose(rel.x_FL, l.location);
      Eigen::Matrix<double, 2, 3> G;
      G << 1.0, 0.0, -sf * l.location.x - cf * l.location.y,  //
          0.0, 1.0, cf * l.location.x - sf * l.location.y;
      const Eigen::Matrix2d cov_p = G * rel.Sigma * G.transpose();
      for (const GateSegment& g : globals) {
        if (!passes_gate(f.config, g, l, x_F_Sj, cov_p, sigma_frame_angle)) continue;
        if (confirmed) {
          f.gated.emplace_back(g.id, j);
        } else {
          ++f.report.unconfirmed_pairs;
        }
      }
    }
  }
  f.report.pairs_considered = globals_count * static_cast<std::int64_t>(f.local.size());
  f.report.gate_rejected =
      f.report.pairs_considered - static_cast<std::int64_t>(f.gated.size()) - f.report.unconfirmed_pairs;
}

void test_individual_compatibility(FusionContext& f) {
  // One joint innovation covariance of all gated pairs serves both tests: each
  // individual S is a diagonal block of it, the joint test's S the block of the candidates.
  const GlobalState& state = f.state;
  std::vector<spmap::ImplicitMeasurement> gated_measurements;
  gated_measurements.reserve(f.gated.size());
  for (const auto& [global_id, j] : f.gated) {
    gated_measurements.push_back(pairing_measurement(state, global_id, f.local[j]));
  }
  if (!f.gated.empty()) {
    const spmap::StackedMeasurements stacked = spmap::stack(state, gated_measurements, "test_individual_compatibility");
    f.gated_innovation = spmap::innovation(state.lower_view(), stacked);
    f.gated_h = stacked.h;
  }
  const spmap::Innovation& in = f.gated_innovation;
  Eigen::Index row = 0;
  for (std::size_t g = 0; g < f.gated.size(); ++g) {
    PairingCandidate c;
    c.global_segment = f.gated[g].first;
    c.local_index = f.gated[g].second;
    c.local_segment = f.local[c.local_index];
    c.measurement = std::move(gated_measurements[g]);
    c.row = row;
    const Eigen::Index dim = c.measurement.h.size();
    row += dim;
    const spmap::CompatibilityTest t = spmap::chi2_test(in.S.block(c.row, c.row, dim, dim), c.measurement.h,
                                                        in.row_scale.segment(c.row, dim).maxCoeff(), f.careful, f.chi2);
    if (!t.passed) {
      ++f.report.chi2_rejected;
      continue;
    }
    const Pose2 x_SiSj = between(state.root_location(c.global_segment), state.root_location(c.local_segment));
    if (spmap::extent_overlap(x_SiSj, state.entity(c.global_segment).length_m,
                              state.entity(c.local_segment).length_m) < f.config.min_overlap_m) {
      ++f.report.overlap_rejected;
      continue;
    }
    c.distance2 = t.distance2;
    f.candidates.push_back(std::move(c));
  }
  f.report.jc_candidates = static_cast<int>(f.candidates.size());
}

// ---------------------------------------------------------------------------
// Step 3: joint compatibility and the EKF update

void test_joint_compatibility(FusionContext& f) {
  std::vector<PairingCandidate>& candidates = f.candidates;
  if (candidates.empty()) return;
  // Best individual distance first.
  std::vector<std::size_t> order(candidates.size());
  std::iota(order.begin(), order.end(), std::size_t{0});
  std::stable_sort(order.begin(), order.end(), [&](std::size_t a, std::size_t b) {
    return candidates[a].distance2 < candidates[b].distance2;
  });
  // The candidates' rows of the gated innovation, in test order.
  std::vector<spmap::JointCompatibility::Rows> rows;
  rows.reserve(order.size());
  for (const std::size_t c : order) rows.push_back({candidates[c].row, candidates[c].measurement.h.size()});
  spmap::JointCompatibility jc(f.gated_innovation.S, f.gated_innovation.row_scale, f.gated_h, std::move(rows),
                               f.careful, f.chi2);
  for (std::size_t c = 0; c < order.size(); ++c) {
    if (!jc.try_add(c)) {
      ++f.report.jc_rejected;
      continue;
    }
    f.accepted.push_back(order[c]);
    f.accepted_measurements.push_back(std::move(candidates[order[c]].measurement));
  }
}

void update_with_pairings(FusionContext& f) {
  FusionReport& rep = f.report;
  rep.pairings_accepted = static_cast<int>(f.accepted.size());
  rep.update_dimension = f.state.dimension();
  const spmap::UpdateReport u = spmap::ekf_update(f.state, f.accepted_measurements, f.careful);
  rep.update_rows = u.rows;
  rep.rows_dropped = u.rows_dropped;
  rep.rows_kept = u.rows_kept;
  rep.update_distance2 = u.distance2;
}

}  // namespace lmf::fusion
