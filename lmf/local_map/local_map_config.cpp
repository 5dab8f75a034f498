#include "lmf/local_map/local_map_config.hpp"

#include <cmath>
#include <numbers>
#include <stdexcept>

#include "lmf/common/config_check.hpp"

namespace lmf {
namespace {

bool finite_nonnegative(double v) { return std::isfinite(v) && v >= 0.0; }
bool finite_positive(double v) { return std::isfinite(v) && v > 0.0; }
bool probability(double v) { return std::isfinite(v) && v > 0.0 && v < 1.0; }

}  // namespace

void LocalMapConfig::validate() const {
  const ConfigCheck require("LocalMapConfig");
  require(finite_nonnegative(odom_translation_noise_ratio), "odom_translation_noise_ratio",
          odom_translation_noise_ratio, "finite and >= 0");
  require(finite_nonnegative(odom_rotation_noise_ratio), "odom_rotation_noise_ratio", odom_rotation_noise_ratio,
          "finite and >= 0");
  require(finite_nonnegative(odom_drift_rad_per_m), "odom_drift_rad_per_m", odom_drift_rad_per_m,
          "finite and >= 0");
  require(finite_nonnegative(odom_noise_floor_m), "odom_noise_floor_m", odom_noise_floor_m, "finite and >= 0");
  require(finite_nonnegative(odom_noise_floor_rad), "odom_noise_floor_rad", odom_noise_floor_rad,
          "finite and >= 0");
  require(finite_nonnegative(observation_lateral_noise_m), "observation_lateral_noise_m",
          observation_lateral_noise_m, "finite and >= 0");
  require(finite_nonnegative(observation_angular_noise_rad), "observation_angular_noise_rad",
          observation_angular_noise_rad, "finite and >= 0");
  require(finite_nonnegative(observation_end_noise_m), "observation_end_noise_m", observation_end_noise_m,
          "finite and >= 0");
  require(probability(pairing_alpha), "pairing_alpha", pairing_alpha, "in (0, 1)");
  require(finite_nonnegative(overlap_gap_tolerance_m), "overlap_gap_tolerance_m", overlap_gap_tolerance_m,
          "finite and >= 0");
  require(probability(joint_alpha), "joint_alpha", joint_alpha, "in (0, 1)");
  require(std::isfinite(careful_inverse_tolerance) && careful_inverse_tolerance > 0.0 &&
              careful_inverse_tolerance < 1.0,
          "careful_inverse_tolerance", careful_inverse_tolerance, "in (0, 1)");
  require(probability(fusion_alpha), "fusion_alpha", fusion_alpha, "in (0, 1)");
  require(std::isfinite(constraint_max_angle_rad) && constraint_max_angle_rad >= 0.0 &&
              constraint_max_angle_rad < std::numbers::pi / 4.0,
          "constraint_max_angle_rad", constraint_max_angle_rad, "in [0, pi/4)");
  require(probability(constraint_alpha), "constraint_alpha", constraint_alpha, "in (0, 1)");
  require(finite_positive(ship_distance_m), "ship_distance_m", ship_distance_m, "finite and > 0");
  require(max_segments > 0, "max_segments", max_segments, "> 0");
  require(finite_nonnegative(covariance_tolerance), "covariance_tolerance", covariance_tolerance,
          "finite and >= 0");
  require(scans_have_odometry || scan_matching.enabled, "scans_have_odometry", scans_have_odometry,
          "true unless scan_matching.enabled (without odometry only the scan match measures the motion)");
  odometry_learning.validate();
  extraction.validate();
  scan_matching.validate();
  see_through.validate();
}

}  // namespace lmf
