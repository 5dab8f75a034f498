// The agent's front end (docs/design.md §4.1 and §10): for each scan, the
// motion since the previous one with its covariance, which the EKF local map
// predicts with (LocalMap, step 1). A short pipeline of stages, each in its
// own file:
//   0. the motion filter (motion_filter.hpp): with odometry, a scan that has
//      not moved a keyframe from the last scan taken (to the nearest scan)
//      is not a new view: it gets the prior's
//      motion since the last scan taken and goes no further, and the stages
//      below see the next scan taken;
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
  // x_{k-1,k} and its covariance, k-1 the last scan taken; std::nullopt for the first scan.
  std::optional<MotionIncrement> motion;
  // Not a new view (stage 0): `motion` is the prior's since the last scan
  // taken, nothing else was done, and the next scan's motion spans this one.
  bool skipped = false;
  bool registration_tried = false;
  std::optional<ScanMatch> registration;  // when it succeeded: motion is its x_AB
  bool search_escalated = false;       // the search escalated (escalating_registration.hpp) ...
  bool match_from_escalation = false;  // ... and its wider window's match is the registration
  double odometry_learning_weight = 0.0;  // the increment's robust weight in the odometry model (0: not learned from)
};

struct FrontEndConfig {
  MotionPriorConfig motion_prior;
  // Stage 0, with odometry (without it nothing is known of the motion before
  // the scan is registered, so every scan is).
  bool motion_filter = true;
};

class FrontEnd {
 public:
  // Throws std::invalid_argument for an invalid config.
  explicit FrontEnd(const FrontEndConfig& config);

  // Stages 0-5 for one scan (its odometry x_OR finite); `take`: stages 1-5
  // whatever the motion filter says (a scan the map must end at).
  RegisteredScan register_scan(const LaserScan& scan, bool take = false);
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
  double range_noise_per_m() const;
  bool range_noise_measured() const { return range_noise_.range_noise_per_m().has_value(); }

 private:
  ScanMatcherConfig matching_;
  bool motion_filter_;
  MotionPrior motion_prior_;
  // The last scans with their poses relative to the newest: relative to the
  // robot, so a new local map keeps it.
  ScanHistory local_submap_;
  RangeNoiseEstimate range_noise_;
  std::optional<Pose2> skipped_since_taken_;  // the last scan's motion since the last taken, when it was skipped
};

}  // namespace lmf
