#include "lmf/fusion/wall_directions.hpp"

#include <algorithm>
#include <cmath>
#include <numbers>

namespace lmf::fusion {
namespace {

// The direction's bin in [0, kBins), the direction taken modulo π.
int bin_of(double direction, int bins) {
  double a = std::fmod(direction, std::numbers::pi);
  if (a < 0.0) a += std::numbers::pi;
  return std::min(bins - 1, static_cast<int>(a / std::numbers::pi * bins));
}

}  // namespace

WallDirections::WallDirections(const std::vector<RegistrationSegment>& walls) {
  std::vector<double> length(kBins, 0.0);
  for (const RegistrationSegment& w : walls) {
    if (std::isfinite(w.location.phi) && w.length_m > 0.0) length[static_cast<std::size_t>(bin_of(w.location.phi, kBins))] += w.length_m;
  }
  cumulative_.assign(3 * kBins + 1, 0.0);
  for (int i = 0; i < 3 * kBins; ++i) {
    cumulative_[static_cast<std::size_t>(i) + 1] = cumulative_[static_cast<std::size_t>(i)] + length[static_cast<std::size_t>(i % kBins)];
  }
}

bool WallDirections::any_within(double direction, double tolerance) const {
  if (!(tolerance >= 0.0)) return false;
  const int reach = static_cast<int>(std::ceil(tolerance / std::numbers::pi * kBins));
  if (2 * reach + 1 >= kBins) return cumulative_[kBins] > 0.0;
  // Bins [centre − reach, centre + reach], shifted by one turn so the range stays within the tripled table.
  const int centre = bin_of(direction, kBins) + kBins;
  return cumulative_[static_cast<std::size_t>(centre + reach + 1)] - cumulative_[static_cast<std::size_t>(centre - reach)] > 0.0;
}

double parallel_share(const std::vector<RegistrationSegment>& local, const WallDirections& global, double heading,
                      double angular_step_rad, double resolution_m) {
  double total = 0.0;
  double parallel = 0.0;
  for (const RegistrationSegment& w : local) {
    total += w.length_m;
    const double tolerance = angular_step_rad + resolution_m / std::max(resolution_m, 0.5 * w.length_m);
    if (global.any_within(w.location.phi + heading, tolerance)) parallel += w.length_m;
  }
  return total > 0.0 ? parallel / total : 0.0;
}

}  // namespace lmf::fusion
