#include "lmf/front_end/scan_history.hpp"

#include <cmath>
#include <utility>

#include <Eigen/Geometry>

namespace lmf {

ScanHistory::ScanHistory(const ScanMatcherConfig& config) : config_(config) { config_.validate(); }

void ScanHistory::add(const LaserScan& scan, const Pose2& x_NN, bool connected) {
  add(oriented_points(scan, config_), x_NN, connected);
}

void ScanHistory::add(OrientedPoints points, const Pose2& x_NN, bool connected) {
  if (!connected) keyframes_.clear();
  // x_N'K = ⊖x_NN' ⊕ x_NK.
  const Pose2 x_new_old = inverse(x_NN);
  for (Keyframe& k : keyframes_) k.x_NK = compose(x_new_old, k.x_NK);
  keyframes_.push_front({Pose2(), std::move(points)});

  // Keep the newest; an older one when it is far enough from the last kept
  // (a scan taken from nearly the same pose adds little) and within the count.
  std::deque<Keyframe> kept;
  for (Keyframe& k : keyframes_) {
    if (static_cast<int>(kept.size()) >= config_.history_scans) break;
    if (!kept.empty()) {
      const Pose2 d = between(kept.back().x_NK, k.x_NK);
      if (std::hypot(d.x, d.y) < config_.keyframe_distance_m && std::abs(d.phi) < config_.keyframe_angle_rad) continue;
    }
    kept.push_back(std::move(k));
  }
  keyframes_ = std::move(kept);

  // The union in the newest frame, newest points first (they win the thinning).
  OrientedPoints all;
  for (const Keyframe& k : keyframes_) {
    const Eigen::Rotation2Dd R(k.x_NK.phi);
    const Eigen::Vector2d t(k.x_NK.x, k.x_NK.y);
    for (std::size_t i = 0; i < k.points.points.size(); ++i) {
      all.points.push_back(t + R * k.points.points[i]);
      all.normals.push_back(R * k.points.normals[i]);
    }
    for (const Eigen::Vector2d& p : k.points.unoriented) all.unoriented.push_back(t + R * p);
  }
  reference_ = ReferenceScan::from_points(all, config_);
}

void ScanHistory::clear() {
  keyframes_.clear();
  reference_ = ReferenceScan();
}

}  // namespace lmf
