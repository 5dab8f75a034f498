// Synthetic laser scans for the scan tests: beams intersected with known walls
// (line segments) and discs, plus optional seeded Gaussian range noise.
#pragma once

#include <cmath>
#include <limits>
#include <numbers>
#include <optional>
#include <random>
#include <vector>

#include <Eigen/Core>

#include "lmf/geometry/pose2.hpp"
#include "lmf/scan/laser_scan.hpp"

namespace lmf::testing {

struct Wall {
  Eigen::Vector2d a;  // world frame (m)
  Eigen::Vector2d b;
};

struct Disc {
  Eigen::Vector2d center;  // world frame (m)
  double radius_m = 0.1;
};

struct SyntheticWorld {
  std::vector<Wall> walls;
  std::vector<Disc> discs;
};

// Distance along the ray (origin o, unit direction u) to the wall, if hit in front.
inline std::optional<double> ray_wall(const Eigen::Vector2d& o, const Eigen::Vector2d& u, const Wall& w) {
  const Eigen::Vector2d e = w.b - w.a;
  const double denom = u.x() * e.y() - u.y() * e.x();  // cross(u, e)
  if (std::abs(denom) < 1e-12) return std::nullopt;
  const Eigen::Vector2d d = w.a - o;
  const double t = (d.x() * e.y() - d.y() * e.x()) / denom;  // along the ray
  const double s = (d.x() * u.y() - d.y() * u.x()) / denom;  // along the wall, in [0, 1]
  if (t <= 0.0 || s < 0.0 || s > 1.0) return std::nullopt;
  return t;
}

inline std::optional<double> ray_disc(const Eigen::Vector2d& o, const Eigen::Vector2d& u, const Disc& c) {
  const Eigen::Vector2d d = o - c.center;
  const double b = u.dot(d);
  const double disc = b * b - (d.squaredNorm() - c.radius_m * c.radius_m);
  if (disc < 0.0) return std::nullopt;
  const double t = -b - std::sqrt(disc);
  if (t <= 0.0) return std::nullopt;
  return t;
}

// A 180° scan (from -pi/2, counter-clockwise) taken at x_WR. Beams that hit
// nothing read max_range_m. Noise: N(0, noise_m² + (noise_per_m r)²) on every
// hit at range r, from `rng`.
inline LaserScan make_scan(const SyntheticWorld& world, const Pose2& x_WR = {}, std::size_t num_beams = 361,
                           double max_range_m = 80.0, double noise_m = 0.0, std::mt19937* rng = nullptr,
                           double noise_per_m = 0.0) {
  LaserScan scan;
  scan.odometry = x_WR;
  scan.angle_min_rad = -std::numbers::pi / 2.0;
  scan.angle_increment_rad = beam_increment_for_180deg(num_beams);
  scan.max_range_m = max_range_m;
  scan.ranges_m.resize(num_beams);
  std::normal_distribution<double> normal(0.0, 1.0);
  const Eigen::Vector2d o(x_WR.x, x_WR.y);
  for (std::size_t i = 0; i < num_beams; ++i) {
    const double a = x_WR.phi + scan.beam_angle(i);
    const Eigen::Vector2d u(std::cos(a), std::sin(a));
    double best = std::numeric_limits<double>::infinity();
    for (const Wall& w : world.walls) {
      if (auto t = ray_wall(o, u, w)) best = std::min(best, *t);
    }
    for (const Disc& c : world.discs) {
      if (auto t = ray_disc(o, u, c)) best = std::min(best, *t);
    }
    if (!std::isfinite(best) || best >= max_range_m) {
      scan.ranges_m[i] = max_range_m;
      continue;
    }
    if (rng != nullptr && (noise_m > 0.0 || noise_per_m > 0.0)) best += std::hypot(noise_m, noise_per_m * best) * normal(*rng);
    scan.ranges_m[i] = std::max(0.0, best);
  }
  return scan;
}

}  // namespace lmf::testing
