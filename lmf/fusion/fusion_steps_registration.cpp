// The frame registration step of the fusion (fusion_steps.hpp, relocate_frame).
#include <cmath>
#include <set>

#include <Eigen/Cholesky>

#include "lmf/fusion/fusion_steps.hpp"

namespace lmf::fusion {

void relocate_frame(FusionContext& f, const EnvironmentGraph& graph) {
  const FrameRegistrationConfig& config = f.config.registration;
  if (!config.enabled || f.anchored()) return;
  GlobalState& state = f.state;
  const LocalMapSnapshot& s = f.snapshot;

  std::vector<RegistrationSegment> local;
  double extent = 0.0;  // of the local map around L_r
  for (const SegmentEstimate& seg : s.segments) {
    local.push_back({seg.location, seg.length_m});
    extent = std::max(extent, std::hypot(seg.location.x, seg.location.y) + 0.5 * seg.length_m);
  }
  const Pose2 x_WL = state.root_location(f.L);
  const double reach = extent + config.window_m;
  // The robot's own recent submaps moved with its frame (FrameRegistrationConfig::own_recent_maps).
  std::set<EntityId>& recent_own = f.own_recent_submaps;
  for (const SubmapRecord& submap : graph.submaps()) {
    if (submap.robot_id == f.robot_id && submap.seq >= s.seq - config.own_recent_maps) recent_own.insert(submap.frame);
  }
  std::vector<RegistrationSegment> global;
  for (const Entity& e : state.entities()) {
    if (e.kind != EntityKind::kSegment || e.parent == f.L) continue;
    if (e.parent && recent_own.count(*e.parent) != 0) continue;
    const Pose2 x_WS = state.root_location(e.id);
    if (std::hypot(x_WS.x - x_WL.x, x_WS.y - x_WL.y) > reach + 0.5 * e.length_m) continue;
    global.push_back({x_WS, e.length_m});
  }
  const std::optional<FrameRegistration> reg = register_frame(local, global, x_WL, config);
  FusionReport& report = f.report;
  if (!reg) {
    report.registration = RegistrationOutcome::kNothingNearby;
    return;
  }
  const Pose2 d = between(x_WL, reg->x_WL);  // in L_r's own frame, as its perturbation
  Eigen::Vector3d delta(d.x, d.y, wrap_angle(d.phi));
  const double r = config.resolution_m;
  const Eigen::Matrix3d C =
      state.block(f.L, f.L) + Eigen::Vector3d(r * r, r * r, reg->angular_step_rad * reg->angular_step_rad).asDiagonal().toDenseMatrix();
  const Eigen::LDLT<Eigen::Matrix3d> C_ldlt(C);
  if (reg->unresolved) {
    // The walls say nothing along u: keep the prediction there, i.e. the
    // offset nearest to zero in C's metric among those the walls fix,
    // δ ← δ − u (uᵀC⁻¹δ)/(uᵀC⁻¹u).
    const Eigen::Vector3d& u = *reg->unresolved;
    const Eigen::Vector3d Wu = C_ldlt.solve(u);
    delta -= u * (Wu.dot(delta) / Wu.dot(u));
    report.registration_unresolved = true;
  }
  report.registration_offset = Pose2(delta.x(), delta.y(), delta.z());
  report.registration_distance2 = delta.dot(C_ldlt.solve(delta));
  report.registration_score = reg->score;
  if (report.registration_distance2 <= f.chi2(3)) {
    report.registration = RegistrationOutcome::kAgrees;
  } else if (reg->ambiguous) {
    report.registration = RegistrationOutcome::kAmbiguous;
  } else if (reg->degenerate) {
    report.registration = RegistrationOutcome::kDegenerate;
  } else {
    report.registration = RegistrationOutcome::kRelocated;
    Entity& frame = state.mutable_entity(f.L);
    frame.location = compose(frame.location, report.registration_offset);
    state.add_to_block(f.L, delta.cwiseAbs2().asDiagonal().toDenseMatrix());
  }
}

}  // namespace lmf::fusion
