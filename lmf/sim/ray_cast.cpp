#include "lmf/sim/ray_cast.hpp"

#include <algorithm>
#include <cmath>
#include <limits>
#include <stdexcept>

namespace lmf::sim {

namespace {
double cross(const Eigen::Vector2d& a, const Eigen::Vector2d& b) { return a.x() * b.y() - a.y() * b.x(); }
}  // namespace

std::optional<double> ray_segment_distance(const Eigen::Vector2d& origin, const Eigen::Vector2d& dir,
                                           const Wall& wall) {
  const Eigen::Vector2d e = wall.b - wall.a;
  const double denom = cross(dir, e);
  if (std::abs(denom) < 1e-12) return std::nullopt;  // parallel: a grazing ray sees no wall
  const Eigen::Vector2d w = wall.a - origin;
  const double t = cross(w, e) / denom;
  const double s = cross(w, dir) / denom;
  // A small tolerance on s so that a ray through the shared end of two faces is never let through.
  if (t <= 0.0 || s < -1e-9 || s > 1.0 + 1e-9) return std::nullopt;
  return t;
}

std::optional<double> ray_circle_distance(const Eigen::Vector2d& origin, const Eigen::Vector2d& dir,
                                          const Circle& circle) {
  const Eigen::Vector2d m = origin - circle.center;
  const double b = m.dot(dir);
  const double c = m.squaredNorm() - circle.radius_m * circle.radius_m;
  if (c <= 0.0) return std::nullopt;  // the origin is inside: the sensor cannot see this disc
  const double disc = b * b - c;
  if (disc < 0.0 || b > 0.0) return std::nullopt;
  return -b - std::sqrt(disc);
}

double point_segment_distance(const Eigen::Vector2d& p, const Eigen::Vector2d& a, const Eigen::Vector2d& b) {
  const Eigen::Vector2d e = b - a;
  const double len2 = e.squaredNorm();
  const double s = len2 > 0.0 ? std::clamp((p - a).dot(e) / len2, 0.0, 1.0) : 0.0;
  return (a + s * e - p).norm();
}

WallIndex::WallIndex(std::vector<Wall> walls, double cell_m) : walls_(std::move(walls)), cell_m_(cell_m) {
  if (!(cell_m > 0.0)) throw std::invalid_argument("WallIndex: cell_m must be positive");
  Eigen::Vector2d lo(0.0, 0.0);
  Eigen::Vector2d hi(1.0, 1.0);
  if (!walls_.empty()) {
    lo = walls_.front().a;
    hi = lo;
    for (const auto& w : walls_) {
      lo = lo.cwiseMin(w.a).cwiseMin(w.b);
      hi = hi.cwiseMax(w.a).cwiseMax(w.b);
    }
  }
  origin_ = lo - Eigen::Vector2d::Constant(cell_m_);
  cols_ = static_cast<int>(std::ceil((hi.x() - origin_.x()) / cell_m_)) + 2;
  rows_ = static_cast<int>(std::ceil((hi.y() - origin_.y()) / cell_m_)) + 2;
  const std::size_t n = static_cast<std::size_t>(cols_) * rows_;
  // Each wall goes into every cell its (slightly grown) bounding box touches.
  auto for_cells = [&](const Wall& w, auto&& f) {
    const double eps = 1e-9;
    const int i0 = static_cast<int>(std::floor((std::min(w.a.x(), w.b.x()) - eps - origin_.x()) / cell_m_));
    const int i1 = static_cast<int>(std::floor((std::max(w.a.x(), w.b.x()) + eps - origin_.x()) / cell_m_));
    const int j0 = static_cast<int>(std::floor((std::min(w.a.y(), w.b.y()) - eps - origin_.y()) / cell_m_));
    const int j1 = static_cast<int>(std::floor((std::max(w.a.y(), w.b.y()) + eps - origin_.y()) / cell_m_));
    for (int j = j0; j <= j1; ++j)
      for (int i = i0; i <= i1; ++i) f(static_cast<std::size_t>(j) * cols_ + i);
  };
  std::vector<int> count(n + 1, 0);
  for (const auto& w : walls_) for_cells(w, [&](std::size_t c) { ++count[c + 1]; });
  cell_start_.assign(n + 1, 0);
  for (std::size_t c = 0; c < n; ++c) cell_start_[c + 1] = cell_start_[c] + count[c + 1];
  wall_ids_.assign(static_cast<std::size_t>(cell_start_[n]), 0);
  std::vector<int> fill(cell_start_.begin(), cell_start_.end() - 1);
  for (std::size_t k = 0; k < walls_.size(); ++k) {
    for_cells(walls_[k], [&](std::size_t c) { wall_ids_[static_cast<std::size_t>(fill[c]++)] = static_cast<int>(k); });
  }
}

std::optional<double> WallIndex::cast_ray(const Eigen::Vector2d& origin, double angle_rad,
                                          double max_range_m) const {
  const Eigen::Vector2d dir(std::cos(angle_rad), std::sin(angle_rad));
  // Amanatides–Woo traversal of the grid cells along the ray.
  const Eigen::Vector2d local = (origin - origin_) / cell_m_;
  int i = static_cast<int>(std::floor(local.x()));
  int j = static_cast<int>(std::floor(local.y()));
  const int step_i = dir.x() > 0.0 ? 1 : -1;
  const int step_j = dir.y() > 0.0 ? 1 : -1;
  const double inf = std::numeric_limits<double>::infinity();
  const double t_delta_x = dir.x() != 0.0 ? cell_m_ / std::abs(dir.x()) : inf;
  const double t_delta_y = dir.y() != 0.0 ? cell_m_ / std::abs(dir.y()) : inf;
  double t_max_x = dir.x() != 0.0 ? ((dir.x() > 0.0 ? (i + 1 - local.x()) : (local.x() - i)) * cell_m_) / std::abs(dir.x()) : inf;
  double t_max_y = dir.y() != 0.0 ? ((dir.y() > 0.0 ? (j + 1 - local.y()) : (local.y() - j)) * cell_m_) / std::abs(dir.y()) : inf;
  double best = inf;
  if (i < 0 || j < 0 || i >= cols_ || j >= rows_) {
    // Outside the grid (never in a generated world): test every wall.
    for (const auto& w : walls_) {
      const auto t = ray_segment_distance(origin, dir, w);
      if (t && *t < best) best = *t;
    }
    if (best <= max_range_m) return best;
    return std::nullopt;
  }
  double t_cell_start = 0.0;
  while (t_cell_start <= max_range_m) {
    if (i < 0 || j < 0 || i >= cols_ || j >= rows_) break;
    const std::size_t c = static_cast<std::size_t>(j) * cols_ + i;
    for (int k = cell_start_[c]; k < cell_start_[c + 1]; ++k) {
      const auto t = ray_segment_distance(origin, dir, walls_[static_cast<std::size_t>(wall_ids_[static_cast<std::size_t>(k)])]);
      if (t && *t < best) best = *t;
    }
    const double t_cell_end = std::min(t_max_x, t_max_y);
    // A hit inside this cell (or in an earlier one) cannot be beaten by later cells.
    if (best <= t_cell_end) break;
    t_cell_start = t_cell_end;
    if (t_max_x < t_max_y) {
      t_max_x += t_delta_x;
      i += step_i;
    } else {
      t_max_y += t_delta_y;
      j += step_j;
    }
  }
  if (best <= max_range_m) return best;
  return std::nullopt;
}

bool WallIndex::blocks(const Eigen::Vector2d& a, const Eigen::Vector2d& b) const {
  const Eigen::Vector2d d = b - a;
  const double len = d.norm();
  if (len <= 0.0) return false;
  const auto t = cast_ray(a, std::atan2(d.y(), d.x()), len);
  return t.has_value() && *t < len;
}

std::optional<double> WallIndex::distance_to_nearest(const Eigen::Vector2d& p, double search_radius_m) const {
  const Eigen::Vector2d lo = (p - origin_) / cell_m_ - Eigen::Vector2d::Constant(search_radius_m / cell_m_);
  const Eigen::Vector2d hi = (p - origin_) / cell_m_ + Eigen::Vector2d::Constant(search_radius_m / cell_m_);
  const int i0 = std::max(0, static_cast<int>(std::floor(lo.x())));
  const int j0 = std::max(0, static_cast<int>(std::floor(lo.y())));
  const int i1 = std::min(cols_ - 1, static_cast<int>(std::floor(hi.x())));
  const int j1 = std::min(rows_ - 1, static_cast<int>(std::floor(hi.y())));
  double best = std::numeric_limits<double>::infinity();
  for (int j = j0; j <= j1; ++j) {
    for (int i = i0; i <= i1; ++i) {
      const std::size_t c = static_cast<std::size_t>(j) * cols_ + i;
      for (int k = cell_start_[c]; k < cell_start_[c + 1]; ++k) {
        const Wall& w = walls_[static_cast<std::size_t>(wall_ids_[static_cast<std::size_t>(k)])];
        best = std::min(best, point_segment_distance(p, w.a, w.b));
      }
    }
  }
  if (best <= search_radius_m) return best;
  return std::nullopt;
}

}  // namespace lmf::sim
