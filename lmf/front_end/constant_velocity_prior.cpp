#include "lmf/front_end/constant_velocity_prior.hpp"

namespace lmf {

ConstantVelocityPrior::ConstantVelocityPrior(const ScanMatcherConfig& matching)
    : covariance_(search_window_covariance(matching)) {}

Pose2 ConstantVelocityPrior::predict(int64_t dt_us) const {
  const Eigen::Vector3d u = velocity_ * (static_cast<double>(dt_us) * 1e-6);
  return Pose2::from_vector(u);
}

void ConstantVelocityPrior::observe(const Pose2& u, int64_t dt_us) {
  if (dt_us <= 0) return;  // no time passed: no velocity to learn from
  velocity_ = Eigen::Vector3d(u.x, u.y, u.phi) / (static_cast<double>(dt_us) * 1e-6);
}

}  // namespace lmf
