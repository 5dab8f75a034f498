#include "lmf/front_end/range_noise_estimate.hpp"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <vector>

namespace lmf {

void RangeNoiseEstimate::add(const ScanMatch& match) {
  if (!match.range_noise_slope2 || !std::isfinite(*match.range_noise_slope2)) return;
  slopes2_.push_back(*match.range_noise_slope2);
  if (slopes2_.size() > kWindow) slopes2_.pop_front();
  ++matches_;
}

std::optional<double> RangeNoiseEstimate::range_noise_per_m() const {
  if (slopes2_.size() < kMinMatches) return std::nullopt;
  std::vector<double> v(slopes2_.begin(), slopes2_.end());
  const auto mid = v.begin() + static_cast<std::ptrdiff_t>(v.size() / 2);
  std::nth_element(v.begin(), mid, v.end());
  return std::sqrt(std::max(0.0, *mid));
}

std::string describe_point_noise(double point_sigma_m, double range_noise_per_m, std::size_t measured_over_matches) {
  char text[96];
  std::snprintf(text, sizeof text, "%.3f m (+) %.4f x range", point_sigma_m, range_noise_per_m);
  return std::string(text) + (measured_over_matches > 0
                                  ? " (measured over " + std::to_string(measured_over_matches) + " matches)"
                                  : std::string(" (configured)"));
}

}  // namespace lmf
