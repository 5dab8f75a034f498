// The agent's front end (docs/design.md §4.1 and §10): for each scan, the
// motion since the previous one with its covariance, which the EKF local map
// predicts with (LocalMap, step 1). A short pipeline of stages, each in its
// own file:
//   1. the motion prior (motion_prior.hpp): odometry corrected by the learned
//      odometry model, or constant velocity;
//   2. registration (escalating_registration.hpp): the scan against the local
//      submap, a correlative search around the prior, escalating to a wider
//      window when the motion did more than it holds, and a refinement with
//      the prior;
//   3. the motion: the registration's where it succeeded; the prior's where
//      it failed, claiming no more than the search window (σ = window / 3);
//   4. the prior learns from what the laser measured;
//   5. the local submap (scan_history.hpp) goes on from the motion, and the
//      point noise's range-proportional part (range_noise_estimate.hpp) from
//      the registration's residuals.
//
// Pure and deterministic; not thread-safe.
#pragma once

#include <cstdint>
#include <optional>

#include "lmf/front_end/motion_prior.hpp"
#include "lmf/front_end/odometry_model.hpp"
#include "lmf/front_end/range_noise_estimate.hpp"
#include "lmf/front_end/scan_history.hpp"
#include "lmf/geometry/pose2.hpp"
#include "lmf/scan/laser_scan.hpp"
#include "lmf/scan/scan_matcher.hpp"

namespace lmf {

// What the front end made of one scan.
struct RegisteredScan {
  // x_{k-1,k} and its covariance; std::nullopt for the first scan.
  std::optional<MotionIncrement> motion;
  bool registration_tried = false;
  std::optional<ScanMatch> registration;  // when it succeeded: motion is its x_AB
  bool search_escalated = false;       // the search escalated (escalating_registration.hpp) ...
  bool match_from_escalation = false;  // ... and its wider window's match is the registration
  double odometry_learning_weight = 0.0;  // the increment's robust weight in the odometry model (0: not learned from)
};

class FrontEnd {
 public:
  // Throws std::invalid_argument for an invalid config.
  explicit FrontEnd(const MotionPriorConfig& config);

  // Stages 1-5 for one scan (its odometry x_OR finite).
  RegisteredScan register_scan(const LaserScan& scan);
  // Stage 1 alone, for a scan known only by its time and odometry (observations
  // extracted elsewhere): the motion from the prior.
  std::optional<MotionIncrement> odometry_step(int64_t utime, const Pose2& odometry);
  // Continues from a scan at `utime` with odometry x_OR `odometry` whose points
  // are gone (a restarted agent): the next scan is predicted from that reading
  // and not registered.
  void resume(int64_t utime, const Pose2& odometry);

  const MotionPrior& motion_prior() const { return motion_prior_; }
  const OdometryErrorModel& odometry_model() const { return motion_prior_.odometry_model(); }
  const ScanHistory& local_submap() const { return local_submap_; }
  const RangeNoiseEstimate& range_noise() const { return range_noise_; }
  // The point noise's range-proportional part the registration uses now, and
  // whether it was measured (range_noise_estimate.hpp) or is the configured one.
  double range_noise_per_m() const { return matching_.range_noise_per_m; }
  bool range_noise_measured() const { return range_noise_.range_noise_per_m().has_value(); }

 private:
  ScanMatcherConfig matching_;
  MotionPrior motion_prior_;
  // The last scans with their poses relative to the newest: relative to the
  // robot, so a new local map keeps it.
  ScanHistory local_submap_;
  RangeNoiseEstimate range_noise_;
};

}  // namespace lmf
