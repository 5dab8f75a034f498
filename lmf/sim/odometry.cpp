#include "lmf/sim/odometry.hpp"

#include <cmath>
#include <numbers>
#include <stdexcept>
#include <string>

#include "lmf/common/config_check.hpp"

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


// ---------------------------------------------------------------------------
// The real-robot model.

void RealOdometryConfig::validate() const {
  const ConfigCheck require("RealOdometryConfig");
  // Written so that NaN fails every check.
  const auto in = [](double v, double lo, double hi) { return v >= lo && v <= hi; };
  require(in(translation_scale_sigma, 0.0, 0.2), "translation_scale_sigma", translation_scale_sigma, "in [0, 0.2]");
  require(in(rotation_scale_sigma, 0.0, 0.2), "rotation_scale_sigma", rotation_scale_sigma, "in [0, 0.2]");
  require(in(heading_bias_sigma_rad_per_m, 0.0, 0.1), "heading_bias_sigma_rad_per_m", heading_bias_sigma_rad_per_m,
          "in [0, 0.1]");
  require(in(translation_noise_fraction, 0.0, 1.0), "translation_noise_fraction", translation_noise_fraction,
          "in [0, 1]");
  require(in(rotation_noise_fraction, 0.0, 1.0), "rotation_noise_fraction", rotation_noise_fraction, "in [0, 1]");
  require(in(heading_noise_rad2_per_m, 0.0, 0.1), "heading_noise_rad2_per_m", heading_noise_rad2_per_m, "in [0, 0.1]");
  require(in(heading_noise_per_step_rad, 0.0, 0.2), "heading_noise_per_step_rad", heading_noise_per_step_rad,
          "in [0, 0.2]");
  require(in(slip_per_m, 0.0, 1.0), "slip_per_m", slip_per_m, "in [0, 1]");
  require(in(slip_per_rad, 0.0, 1.0), "slip_per_rad", slip_per_rad, "in [0, 1]");
  require(in(heading_glitch_rate_per_m, 0.0, 10.0), "heading_glitch_rate_per_m", heading_glitch_rate_per_m,
          "in [0, 10]");
  require(in(heading_glitch_min_rad, 0.0, std::numbers::pi / 2), "heading_glitch_min_rad", heading_glitch_min_rad,
          "in [0, pi/2]");
  require(in(heading_glitch_max_rad, heading_glitch_min_rad, std::numbers::pi / 2), "heading_glitch_max_rad",
          heading_glitch_max_rad, "in [heading_glitch_min_rad, pi/2]");
  require(in(translation_glitch_rate_per_m, 0.0, 10.0), "translation_glitch_rate_per_m", translation_glitch_rate_per_m,
          "in [0, 10]");
  require(in(translation_glitch_min_m, 0.0, 2.0), "translation_glitch_min_m", translation_glitch_min_m, "in [0, 2]");
  require(in(translation_glitch_max_m, translation_glitch_min_m, 2.0), "translation_glitch_max_m",
          translation_glitch_max_m, "in [translation_glitch_min_m, 2]");
}

RealOdometry::RealOdometry(const RealOdometryConfig& config, const RealOdometryErrors& errors)
    : config_(config), errors_(errors) {
  config_.validate();
}

RealOdometry::RealOdometry(const RealOdometryConfig& config, Rng& rng) : config_(config) {
  config_.validate();
  errors_.translation_scale = 1.0 + config_.translation_scale_sigma * rng.normal();
  errors_.rotation_scale = 1.0 + config_.rotation_scale_sigma * rng.normal();
  errors_.heading_bias_rad_per_m = config_.heading_bias_sigma_rad_per_m * rng.normal();
}

Pose2 RealOdometry::increment(const Pose2& u, Rng& rng) const {
  const RealOdometryConfig& c = config_;
  // The same draws on every call, so one robot's stream does not depend on its glitches.
  const double n_x = rng.normal();
  const double n_y = rng.normal();
  const double n_phi = rng.normal();
  const double heading_glitch_u = rng.uniform01();
  const double heading_glitch_size = rng.uniform(c.heading_glitch_min_rad, c.heading_glitch_max_rad);
  const bool heading_glitch_positive = rng.bernoulli(0.5);
  const double translation_glitch_u = rng.uniform01();
  const double translation_glitch_size = rng.uniform(c.translation_glitch_min_m, c.translation_glitch_max_m);

  const double d = std::hypot(u.x, u.y);
  const double turn = std::abs(u.phi);
  if (d == 0.0 && turn == 0.0) return Pose2();  // standing still: no encoder ticks

  const double sigma_x = c.translation_noise_fraction * d;
  const double sigma_y = c.slip_per_m * d + c.slip_per_rad * turn;
  const double var_phi = std::pow(c.rotation_noise_fraction * turn, 2) + c.heading_noise_rad2_per_m * d +
                         std::pow(c.heading_noise_per_step_rad, 2);
  // Poisson arrivals along the path: at least one glitch in this step with probability 1 - exp(-rate d).
  const bool heading_glitch = heading_glitch_u < -std::expm1(-c.heading_glitch_rate_per_m * d);
  const bool translation_glitch = translation_glitch_u < -std::expm1(-c.translation_glitch_rate_per_m * d);

  const RealOdometryErrors& e = errors_;
  const double x = e.translation_scale * u.x + sigma_x * n_x + (translation_glitch ? translation_glitch_size : 0.0);
  const double y = e.translation_scale * u.y + sigma_y * n_y;
  const double phi = e.rotation_scale * u.phi + e.heading_bias_rad_per_m * d + std::sqrt(var_phi) * n_phi +
                     (heading_glitch ? (heading_glitch_positive ? 1.0 : -1.0) * heading_glitch_size : 0.0);
  return {x, y, wrap_angle(phi)};
}

// ---------------------------------------------------------------------------
// One robot's odometry.

const char* odometry_model_name(OdometryModel model) {
  switch (model) {
    case OdometryModel::kProportional: return "proportional";
    case OdometryModel::kReal: return "real";
  }
  return "unknown";
}

OdometryModel parse_odometry_model(const std::string& name) {
  if (name == "proportional") return OdometryModel::kProportional;
  if (name == "real") return OdometryModel::kReal;
  throw std::invalid_argument("odometry model \"" + name + "\" is not one of \"proportional\", \"real\"");
}

RobotOdometry::RobotOdometry(OdometryModel model, const OdometryNoiseConfig& proportional,
                             const RealOdometryConfig& real, uint64_t seed)
    : model_(model), proportional_(proportional), rng_(seed) {
  proportional_.validate();
  if (model_ == OdometryModel::kReal) real_.emplace(real, rng_);
}

Pose2 RobotOdometry::increment(const Pose2& u) {
  return real_ ? real_->increment(u, rng_) : noisy_increment(u, proportional_, rng_);
}

RealOdometryErrors RobotOdometry::errors() const { return real_ ? real_->errors() : RealOdometryErrors{}; }

}  // namespace lmf::sim
