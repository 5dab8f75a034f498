#include "lmf/eval/trajectory_error.hpp"

#include <algorithm>
#include <cmath>
#include <numbers>
#include <stdexcept>

#include <Eigen/Core>

namespace lmf::eval {
namespace {

constexpr double kRadToDeg = 180.0 / std::numbers::pi;

void require_sorted(const std::vector<StampedPose>& poses, const char* what) {
  const bool sorted = std::is_sorted(poses.begin(), poses.end(),
                                     [](const StampedPose& a, const StampedPose& b) { return a.utime < b.utime; });
  if (!sorted) throw std::invalid_argument(std::string("associate_by_time: ") + what + " is not sorted by time");
}

double planar_distance(const Pose2& a, const Pose2& b) { return std::hypot(a.x - b.x, a.y - b.y); }

}  // namespace

std::vector<PosePair> associate_by_time(const std::vector<StampedPose>& estimate,
                                        const std::vector<StampedPose>& reference, int64_t tolerance_us) {
  require_sorted(estimate, "the estimate");
  require_sorted(reference, "the reference");
  std::vector<PosePair> pairs;
  pairs.reserve(estimate.size());
  std::size_t r = 0;
  for (const StampedPose& e : estimate) {
    // Advance to the last reference not after e (nearest is it or the next one).
    while (r + 1 < reference.size() && reference[r + 1].utime <= e.utime) ++r;
    std::optional<std::size_t> best;
    int64_t best_gap = tolerance_us + 1;
    for (std::size_t k = r; k < std::min(r + 2, reference.size()); ++k) {
      const int64_t gap = std::abs(reference[k].utime - e.utime);
      if (gap < best_gap) {
        best_gap = gap;
        best = k;
      }
    }
    if (best) pairs.push_back({e.pose, reference[*best].pose});
  }
  return pairs;
}

Pose2 align_se2(const std::vector<PosePair>& pairs) {
  if (pairs.size() < 2) throw std::invalid_argument("align_se2: need at least 2 pose pairs");
  Eigen::Vector2d mean_est = Eigen::Vector2d::Zero();
  Eigen::Vector2d mean_ref = Eigen::Vector2d::Zero();
  for (const PosePair& p : pairs) {
    mean_est += Eigen::Vector2d(p.estimate.x, p.estimate.y);
    mean_ref += Eigen::Vector2d(p.reference.x, p.reference.y);
  }
  mean_est /= static_cast<double>(pairs.size());
  mean_ref /= static_cast<double>(pairs.size());
  // Rotation maximising Σ ref_iᵀ R est_i over centred points: angle of Σ (est × ref, est · ref).
  double sum_cross = 0.0;
  double sum_dot = 0.0;
  for (const PosePair& p : pairs) {
    const Eigen::Vector2d e = Eigen::Vector2d(p.estimate.x, p.estimate.y) - mean_est;
    const Eigen::Vector2d r = Eigen::Vector2d(p.reference.x, p.reference.y) - mean_ref;
    sum_cross += e.x() * r.y() - e.y() * r.x();
    sum_dot += e.dot(r);
  }
  const double phi = std::atan2(sum_cross, sum_dot);
  const double c = std::cos(phi);
  const double s = std::sin(phi);
  const Eigen::Vector2d t = mean_ref - Eigen::Vector2d(c * mean_est.x() - s * mean_est.y(),
                                                       s * mean_est.x() + c * mean_est.y());
  return {t.x(), t.y(), wrap_angle(phi)};
}

AbsoluteError absolute_trajectory_error(const std::vector<PosePair>& pairs, bool align) {
  AbsoluteError result;
  result.count = pairs.size();
  if (pairs.empty()) return result;
  result.alignment = align && pairs.size() >= 2 ? align_se2(pairs) : Pose2();
  double sum_position2 = 0.0;
  double sum_heading2 = 0.0;
  for (const PosePair& p : pairs) {
    const Pose2 aligned = compose(result.alignment, p.estimate);
    const double d = planar_distance(aligned, p.reference);
    const double dphi = wrap_angle(aligned.phi - p.reference.phi);
    sum_position2 += d * d;
    sum_heading2 += dphi * dphi;
    result.position_max_m = std::max(result.position_max_m, d);
  }
  const double n = static_cast<double>(pairs.size());
  result.position_rmse_m = std::sqrt(sum_position2 / n);
  result.heading_rmse_deg = std::sqrt(sum_heading2 / n) * kRadToDeg;
  return result;
}

RelativeError relative_pose_error(const std::vector<PosePair>& pairs, double distance_m) {
  if (!(distance_m > 0.0)) throw std::invalid_argument("relative_pose_error: distance_m must be > 0");
  RelativeError result;
  result.distance_m = distance_m;
  // Cumulative reference path length at each pair.
  std::vector<double> travelled(pairs.size(), 0.0);
  for (std::size_t i = 1; i < pairs.size(); ++i) {
    travelled[i] = travelled[i - 1] + planar_distance(pairs[i - 1].reference, pairs[i].reference);
  }
  double sum_translation2 = 0.0;
  double sum_rotation2 = 0.0;
  std::size_t j = 0;
  for (std::size_t i = 0; i < pairs.size(); ++i) {
    j = std::max(j, i + 1);
    while (j < pairs.size() && travelled[j] - travelled[i] < distance_m) ++j;
    if (j >= pairs.size()) break;
    const Pose2 delta_est = between(pairs[i].estimate, pairs[j].estimate);
    const Pose2 delta_ref = between(pairs[i].reference, pairs[j].reference);
    const Pose2 error = between(delta_ref, delta_est);
    sum_translation2 += error.x * error.x + error.y * error.y;
    sum_rotation2 += error.phi * error.phi;
    ++result.count;
  }
  if (result.count > 0) {
    const double n = static_cast<double>(result.count);
    result.translation_rmse_m = std::sqrt(sum_translation2 / n);
    result.rotation_rmse_deg = std::sqrt(sum_rotation2 / n) * kRadToDeg;
  }
  return result;
}

double reference_path_length(const std::vector<PosePair>& pairs) {
  double length = 0.0;
  for (std::size_t i = 1; i < pairs.size(); ++i) length += planar_distance(pairs[i - 1].reference, pairs[i].reference);
  return length;
}

}  // namespace lmf::eval
