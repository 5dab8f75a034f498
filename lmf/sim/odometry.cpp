#include "lmf/sim/odometry.hpp"

#include <cmath>
#include <stdexcept>

namespace lmf::sim {

void OdometryNoiseConfig::validate() const {
  auto in01 = [](double v) { return v >= 0.0 && v <= 1.0; };
  if (!in01(translation_fraction)) throw std::invalid_argument("OdometryNoiseConfig: translation_fraction must be in [0, 1]");
  if (!in01(rotation_fraction)) throw std::invalid_argument("OdometryNoiseConfig: rotation_fraction must be in [0, 1]");
  if (!in01(heading_drift_rad_per_m)) {
    throw std::invalid_argument("OdometryNoiseConfig: heading_drift_rad_per_m must be in [0, 1]");
  }
}

namespace {
struct Sigmas {
  double xy;
  double phi;
};
Sigmas sigmas(const Pose2& u, const OdometryNoiseConfig& config) {
  const double d = std::hypot(u.x, u.y);
  return {config.translation_fraction * d,
          config.rotation_fraction * std::abs(u.phi) + config.heading_drift_rad_per_m * d};
}
}  // namespace

Eigen::Matrix3d odometry_noise_covariance(const Pose2& u, const OdometryNoiseConfig& config) {
  const Sigmas s = sigmas(u, config);
  return Eigen::Vector3d(s.xy * s.xy, s.xy * s.xy, s.phi * s.phi).asDiagonal();
}

Pose2 noisy_increment(const Pose2& u, const OdometryNoiseConfig& config, Rng& rng) {
  const Sigmas s = sigmas(u, config);
  const double nx = rng.normal();
  const double ny = rng.normal();
  const double nphi = rng.normal();
  return {u.x + s.xy * nx, u.y + s.xy * ny, wrap_angle(u.phi + s.phi * nphi)};
}

}  // namespace lmf::sim
