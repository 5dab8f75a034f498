#include "lmf/sim/laser.hpp"

#include <algorithm>
#include <cmath>
#include <numbers>
#include <stdexcept>

namespace lmf::sim {

void LaserConfig::validate() const {
  if (num_beams < 2 || num_beams > 100000) throw std::invalid_argument("LaserConfig: num_beams must be in [2, 100000]");
  if (!(range_noise_sigma_m >= 0.0) || range_noise_sigma_m > 1.0) {
    throw std::invalid_argument("LaserConfig: range_noise_sigma_m must be in [0, 1]");
  }
  if (!(range_noise_per_m >= 0.0) || range_noise_per_m > 0.1) {
    throw std::invalid_argument("LaserConfig: range_noise_per_m must be in [0, 0.1]");
  }
  if (!(max_range_m > 0.0) || max_range_m > 1000.0) throw std::invalid_argument("LaserConfig: max_range_m must be in (0, 1000]");
}

LaserScan simulate_scan(const WallIndex& walls, const Pose2& x_WR, const LaserConfig& config,
                        const std::vector<Circle>& obstacles, Rng& rng) {
  LaserScan scan;
  scan.angle_min_rad = -std::numbers::pi / 2.0;
  scan.angle_increment_rad = beam_increment_for_180deg(config.num_beams);
  scan.max_range_m = config.max_range_m;
  scan.ranges_m.resize(config.num_beams);

  const Eigen::Vector2d origin(x_WR.x, x_WR.y);
  // Only discs that can be within range matter for this scan.
  std::vector<Circle> near;
  for (const auto& c : obstacles) {
    if ((c.center - origin).norm() - c.radius_m < config.max_range_m) near.push_back(c);
  }
  for (std::size_t i = 0; i < config.num_beams; ++i) {
    const double angle = x_WR.phi + scan.beam_angle(i);
    double range = walls.cast_ray(origin, angle, config.max_range_m).value_or(config.max_range_m);
    if (!near.empty()) {
      const Eigen::Vector2d dir(std::cos(angle), std::sin(angle));
      for (const auto& c : near) {
        const auto t = ray_circle_distance(origin, dir, c);
        if (t && *t < range) range = *t;
      }
    }
    const bool hit = range < config.max_range_m;
    const double sigma = std::hypot(config.range_noise_sigma_m, config.range_noise_per_m * range);
    const double noise = config.range_noise_sigma_m > 0.0 || config.range_noise_per_m > 0.0 ? sigma * rng.normal() : 0.0;
    scan.ranges_m[i] = hit ? std::clamp(range + noise, 0.0, config.max_range_m) : config.max_range_m;
  }
  return scan;
}

}  // namespace lmf::sim
