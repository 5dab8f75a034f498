#include "lmf/front_end/range_noise_estimate.hpp"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <utility>
#include <vector>

#include <Eigen/Geometry>

#include "lmf/common/median.hpp"

namespace lmf {

std::optional<double> range_noise_evidence(const ReferenceScan& A, const std::vector<Eigen::Vector2d>& B,
                                           const Pose2& x, const ScanMatcherConfig& config) {
  struct Residual {
    double range2;
    double abs_e;
  };
  std::vector<Residual> residuals;
  residuals.reserve(B.size());
  const Eigen::Matrix2d R = Eigen::Rotation2Dd(x.phi).toRotationMatrix();
  const Eigen::Vector2d t(x.x, x.y);
  for (const Eigen::Vector2d& b : B) {
    const Eigen::Vector2d q = t + R * b;
    const int j = A.nearest(q, config.last_gate_m);
    if (j < 0) continue;
    const std::size_t k = static_cast<std::size_t>(j);
    residuals.push_back({b.squaredNorm(), std::abs(A.normals()[k].dot(q - A.points()[k]))});
  }
  const std::size_t third = residuals.size() / 3;
  if (third < 3 || static_cast<int>(residuals.size()) < config.min_correspondences) return std::nullopt;
  std::sort(residuals.begin(), residuals.end(),
            [](const Residual& a, const Residual& b) { return a.range2 < b.range2; });
  // σ² from the MAD (1.4826 median |e|), and the mean r², of residuals[first, first + third).
  const auto spread = [&](std::size_t first) {
    std::vector<double> abs_e;
    abs_e.reserve(third);
    double range2 = 0.0;
    for (std::size_t i = first; i < first + third; ++i) {
      abs_e.push_back(residuals[i].abs_e);
      range2 += residuals[i].range2;
    }
    const double sigma = 1.4826 * median(std::move(abs_e));
    return std::pair{sigma * sigma, range2 / static_cast<double>(third)};
  };
  const auto [near_sigma2, near_range2] = spread(0);
  const auto [far_sigma2, far_range2] = spread(residuals.size() - third);
  if (far_range2 < 4.0 * near_range2) return std::nullopt;
  return (far_sigma2 - near_sigma2) / (far_range2 - near_range2);
}

void RangeNoiseEstimate::add(const std::optional<double>& slope2) {
  if (!slope2 || !std::isfinite(*slope2)) return;
  slopes2_.push_back(*slope2);
  if (slopes2_.size() > kWindow) slopes2_.pop_front();
  ++matches_;
}

std::optional<double> RangeNoiseEstimate::range_noise_per_m() const {
  if (slopes2_.size() < kMinMatches) return std::nullopt;
  return std::sqrt(std::max(0.0, median({slopes2_.begin(), slopes2_.end()})));
}

std::string describe_point_noise(double point_sigma_m, double range_noise_per_m, std::size_t measured_over_matches) {
  char text[96];
  std::snprintf(text, sizeof text, "%.3f m (+) %.4f x range", point_sigma_m, range_noise_per_m);
  return std::string(text) + (measured_over_matches > 0
                                  ? " (measured over " + std::to_string(measured_over_matches) + " matches)"
                                  : std::string(" (configured)"));
}

}  // namespace lmf
