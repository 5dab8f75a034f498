// The front end's first stage (docs/design.md §4.1 and §10): the motion since
// the previous scan as it is known before the scan is looked at, u with the
// covariance Q of its perturbation p_u (u_true = u ⊕ p_u, as LocalMap::predict
// takes it).
//  * With odometry: û = between(x_OR previous, x_OR now), corrected by the
//    learned odometry error model, ū = corrected(û), Q = covariance(û)
//    (odometry_model.hpp). The model learns from every increment the laser
//    registered.
//  * Without odometry (LocalMapConfig::scans_have_odometry false): the
//    constant-velocity prediction and its window-wide covariance
//    (constant_velocity_prior.hpp), which follows every increment settled on.
//
// Pure and deterministic; not thread-safe.
#pragma once

#include <cstdint>
#include <optional>

#include <Eigen/Core>

#include "lmf/front_end/constant_velocity_prior.hpp"
#include "lmf/front_end/odometry_model.hpp"
#include "lmf/geometry/pose2.hpp"
#include "lmf/scan/scan_matcher.hpp"

namespace lmf {

// An increment between two scans, x_{k-1,k}, with the covariance of its perturbation.
struct MotionIncrement {
  Pose2 u;
  Eigen::Matrix3d Q = Eigen::Matrix3d::Zero();
};

struct MotionPriorConfig {
  OdometryErrorModel odometry_prior;           // the learner's starting model
  OdometryLearningConfig odometry_learning;
  ScanMatcherConfig scan_matching;             // the constant-velocity prior is as wide as its window
  bool scans_have_odometry = true;
};

class MotionPrior {
 public:
  // What the prior says about one scan.
  struct Prediction {
    Pose2 odometry_increment;  // û as read (the constant-velocity prediction without odometry)
    MotionIncrement motion;    // (ū, Q)
  };

  // Throws std::invalid_argument for an invalid config.
  explicit MotionPrior(const MotionPriorConfig& config);

  // The prior for the scan at `utime` whose odometry reading is x_OR
  // `odometry` (ignored without odometry); std::nullopt before the first scan
  // (no previous pose to move from).
  std::optional<Prediction> predict(int64_t utime, const Pose2& odometry) const;

  // The scan at `utime` was settled with `motion` (prediction as predict()
  // gave it; `registered`, when the laser measured the increment): the
  // odometry model learns from a registered increment, the constant velocity
  // follows any, and the scan becomes the previous one. Returns the
  // increment's robust weight in the odometry model (0 when not learned from).
  double advance(int64_t utime, const Pose2& odometry, const std::optional<Prediction>& prediction,
                 const MotionIncrement& motion, const ScanMatch* registered);

  // Starts again from a scan at `utime` with odometry x_OR `odometry`, as if
  // it had just been advanced past (a restarted agent resuming its chain).
  void restart_from(int64_t utime, const Pose2& odometry);

  // The odometry model that corrects the increments (the learned one, or the prior).
  const OdometryErrorModel& odometry_model() const { return odometry_learner_.model(); }
  const OdometryLearningStats& odometry_learning_stats() const { return odometry_learner_.stats(); }
  bool with_odometry() const { return config_.scans_have_odometry; }

 private:
  MotionPriorConfig config_;
  OdometryModelLearner odometry_learner_;
  ConstantVelocityPrior velocity_prior_;
  std::optional<Pose2> last_odometry_;  // x_OR of the previous scan
  int64_t last_utime_ = 0;
};

}  // namespace lmf
