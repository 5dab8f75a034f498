// The frame registration step of the fusion (fusion_steps.hpp, relocate_frame).
#include <cmath>

#include <Eigen/Cholesky>

#include "lmf/fusion/fusion_steps.hpp"

namespace lmf::fusion {

void relocate_frame(FusionContext& f) {
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
  std::vector<RegistrationSegment> global;
  for (const Entity& e : state.entities()) {
    if (e.kind != EntityKind::kSegment || e.parent == f.L) continue;
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
  const Eigen::Vector3d delta(d.x, d.y, wrap_angle(d.phi));
  const double r = config.resolution_m;
  const Eigen::Matrix3d C =
      state.block(f.L, f.L) + Eigen::Vector3d(r * r, r * r, reg->angular_step_rad * reg->angular_step_rad).asDiagonal().toDenseMatrix();
  report.registration_offset = d;
  report.registration_distance2 = delta.dot(C.ldlt().solve(delta));
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
    frame.location = compose(frame.location, d);
    state.add_to_block(f.L, delta.cwiseAbs2().asDiagonal().toDenseMatrix());
  }
}

}  // namespace lmf::fusion
