#include "lmf/front_end/front_end.hpp"

#include <algorithm>

#include <Eigen/Cholesky>

#include "lmf/front_end/escalating_registration.hpp"
#include "lmf/front_end/motion_filter.hpp"

namespace lmf {
namespace {

// Q with each axis's variance raised to at least the search window's
// (search_window_covariance).
Eigen::Matrix3d at_least_the_window(const Eigen::Matrix3d& Q, const ScanMatcherConfig& matching) {
  const Eigen::Matrix3d window = search_window_covariance(matching);
  Eigen::Matrix3d widened = Q;
  for (int i = 0; i < 3; ++i) widened(i, i) += std::max(0.0, window(i, i) - Q(i, i));
  return widened;
}

}  // namespace

FrontEnd::FrontEnd(const FrontEndConfig& config)
    : matching_(config.motion_prior.scan_matching),
      motion_filter_(config.motion_filter),
      motion_prior_(config.motion_prior),
      local_submap_(config.motion_prior.scan_matching) {}

RegisteredScan FrontEnd::register_scan(const LaserScan& scan, bool take) {
  RegisteredScan out;
  ScanPoints points;  // the scan's, where it is registered
  // 1. The motion prior's prediction, which stage 0 needs first.
  const std::optional<MotionPrior::Prediction> prior = motion_prior_.predict(scan.utime, scan.odometry);
  // 0. The motion filter: a scan that is no new view is dead-reckoned.
  if (!take && motion_filter_ && prior && motion_prior_.with_odometry()) {
    const Pose2 step = skipped_since_taken_ ? between(*skipped_since_taken_, prior->motion.u) : prior->motion.u;
    if (!is_taken(prior->motion.u, step, matching_)) {
      out.motion = prior->motion;
      out.skipped = true;
      skipped_since_taken_ = prior->motion.u;
      return out;
    }
  }
  skipped_since_taken_.reset();
  // 2. Registration against the local submap, the prior as the centre of the
  //    search window and as the refinement's prior, the window escalating
  //    when the motion did more than it holds (Q is singular only for a
  //    standing robot with zero noise floors: no prior, no registration);
  //    its covariance with the point noise measured so far (stage 5).
  if (prior && matching_.enabled && !local_submap_.empty()) {
    out.registration_tried = true;
    if (Eigen::LLT<Eigen::Matrix3d>(prior->motion.Q).info() == Eigen::Success) {
      ScanMatcherConfig matching = matching_;
      matching.range_noise_per_m = range_noise_per_m();
      points = scan_points_by_kind(scan, matching);
      Registration registration = register_escalating(local_submap_.reference(), points,
                                                      prior->motion.u, prior->motion.Q, matching);
      out.registration = std::move(registration.match);
      out.search_escalated = registration.search_escalated;
      out.match_from_escalation = registration.match_from_escalation;
    }
  }
  // 3. The motion: the registration's, or the prior's where there was none.
  //    Where the registration was tried and failed, the prior goes unchecked:
  //    it then claims no more than the search window, which is sized to hold
  //    what the motion can physically do between two scans (σ = window / 3
  //    per axis, as the constant-velocity prior's).
  if (out.registration) {
    out.motion = MotionIncrement{out.registration->x_AB, out.registration->covariance};
  } else if (prior) {
    out.motion = prior->motion;
    if (out.registration_tried) out.motion->Q = at_least_the_window(out.motion->Q, matching_);
  }
  // 4. The prior learns.
  out.odometry_learning_weight = motion_prior_.advance(scan.utime, scan.odometry, prior,
                                                       out.motion.value_or(MotionIncrement{}),
                                                       out.registration ? &*out.registration : nullptr);
  // 5. The point noise's measure takes the registration's residuals: the
  //    points its estimate used (without the small objects where they moved)
  //    against the reference it was registered to. The local submap goes on
  //    from a registered motion. After the odometry's alone it restarts with
  //    this scan, as the odometry's error would enter the older scans' poses;
  //    without odometry the prediction is all there is to go on from.
  if (out.registration && matching_.range_noise_from_residuals) {
    range_noise_.add(range_noise_evidence(local_submap_.reference(),
                                          out.registration->objects_moving ? points.structure : points.all,
                                          out.registration->x_AB, matching_));
  }
  if (matching_.enabled) {
    const bool connected = out.registration.has_value() || (out.motion && !motion_prior_.with_odometry());
    local_submap_.add(scan, out.motion ? out.motion->u : Pose2(), connected);
  }
  return out;
}

double FrontEnd::range_noise_per_m() const {
  if (matching_.range_noise_from_residuals) {
    if (const std::optional<double> measured = range_noise_.range_noise_per_m()) return *measured;
  }
  return matching_.range_noise_per_m;
}

std::optional<MotionIncrement> FrontEnd::odometry_step(int64_t utime, const Pose2& odometry) {
  skipped_since_taken_.reset();  // every scan is taken here
  const std::optional<MotionPrior::Prediction> prior = motion_prior_.predict(utime, odometry);
  std::optional<MotionIncrement> motion;
  if (prior) motion = prior->motion;
  motion_prior_.advance(utime, odometry, prior, motion.value_or(MotionIncrement{}), nullptr);
  return motion;
}

void FrontEnd::resume(int64_t utime, const Pose2& odometry) {
  motion_prior_.restart_from(utime, odometry);
  local_submap_.clear();
  skipped_since_taken_.reset();
}

}  // namespace lmf
