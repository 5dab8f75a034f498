#include "lmf/front_end/motion_prior.hpp"

namespace lmf {

MotionPrior::MotionPrior(const MotionPriorConfig& config)
    : config_(config),
      odometry_learner_(config.odometry_prior, config.odometry_learning),
      velocity_prior_((config.scan_matching.validate(), config.scan_matching)) {}

std::optional<MotionPrior::Prediction> MotionPrior::predict(int64_t utime, const Pose2& odometry) const {
  if (!last_odometry_) return std::nullopt;
  if (!config_.scans_have_odometry) {
    const Pose2 u = velocity_prior_.predict(utime - last_utime_);
    return Prediction{u, {u, velocity_prior_.covariance()}};
  }
  const Pose2 u = between(*last_odometry_, odometry);
  const OdometryErrorModel& model = odometry_model();
  return Prediction{u, {model.corrected(u), model.covariance(u)}};
}

double MotionPrior::advance(int64_t utime, const Pose2& odometry, const std::optional<Prediction>& prediction,
                            const MotionIncrement& motion, const ScanMatch* registered) {
  double learning_weight = 0.0;
  if (prediction) {
    if (!config_.scans_have_odometry) {
      velocity_prior_.observe(motion.u, utime - last_utime_);
    } else if (registered != nullptr && config_.odometry_learning.enabled) {
      // The static structure's increment: an object that moves along with the
      // robot would otherwise become the learned scale (ScanMatch::static_x_AB).
      learning_weight = odometry_learner_.observe(prediction->odometry_increment, registered->static_x_AB,
                                                  registered->static_laser_information);
    }
  }
  restart_from(utime, odometry);
  return learning_weight;
}

void MotionPrior::restart_from(int64_t utime, const Pose2& odometry) {
  last_odometry_ = odometry;
  last_utime_ = utime;
}

}  // namespace lmf
