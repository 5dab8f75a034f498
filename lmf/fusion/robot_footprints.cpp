#include "lmf/fusion/robot_footprints.hpp"

#include <cmath>
#include <stdexcept>
#include <string>

namespace lmf::fusion {

RobotFootprints::RobotFootprints(double radius_m) : radius_(radius_m) {
  if (!(std::isfinite(radius_m) && radius_m > 0.0)) {
    throw std::invalid_argument("RobotFootprints: radius must be finite and > 0, got " + std::to_string(radius_m));
  }
}

std::int64_t RobotFootprints::cell(double v) const { return static_cast<std::int64_t>(std::floor(v / radius_)); }

std::uint64_t RobotFootprints::key(std::int64_t ix, std::int64_t iy) const {
  return (static_cast<std::uint64_t>(ix) << 32) ^ static_cast<std::uint64_t>(static_cast<std::uint32_t>(iy));
}

template <typename Pred>
bool RobotFootprints::any_near(const Eigen::Vector2d& a, Pred pred) const {
  const std::int64_t ix = cell(a.x());
  const std::int64_t iy = cell(a.y());
  for (std::int64_t dx = -1; dx <= 1; ++dx) {
    for (std::int64_t dy = -1; dy <= 1; ++dy) {
      const auto it = grid_.find(key(ix + dx, iy + dy));
      if (it == grid_.end()) continue;
      for (const std::uint32_t i : it->second) {
        if (pred(positions_[i])) return true;
      }
    }
  }
  return false;
}

bool RobotFootprints::add(const Eigen::Vector2d& position_W) {
  if (!position_W.allFinite()) throw std::invalid_argument("RobotFootprints::add: position is not finite");
  const double s2 = min_spacing() * min_spacing();
  if (any_near(position_W, [&](const Eigen::Vector2d& p) { return (position_W - p).squaredNorm() <= s2; })) {
    return false;
  }
  grid_[key(cell(position_W.x()), cell(position_W.y()))].push_back(static_cast<std::uint32_t>(positions_.size()));
  positions_.push_back(position_W);
  return true;
}

bool RobotFootprints::covers(const Eigen::Vector2d& a, const Eigen::Vector2d& b) const {
  if (!a.allFinite() || !b.allFinite()) return false;
  const double r2 = radius_ * radius_;
  if ((a - b).squaredNorm() > 4.0 * r2) return false;  // longer than the disc's diameter
  return any_near(a, [&](const Eigen::Vector2d& p) { return (a - p).squaredNorm() <= r2 && (b - p).squaredNorm() <= r2; });
}

}  // namespace lmf::fusion
