#include "lmf/scan/foreground_objects.hpp"

#include <cmath>
#include <cstddef>
#include <stdexcept>

namespace lmf {

std::vector<bool> small_foreground_objects(const LaserScan& scan, const std::vector<bool>& usable,
                                           double max_extent_m, double min_range_jump_m) {
  const std::size_t n = scan.ranges_m.size();
  if (usable.size() != n) {
    throw std::invalid_argument("small_foreground_objects: one usable flag per beam needed");
  }
  if (!(min_range_jump_m > 0.0) || !std::isfinite(min_range_jump_m)) {
    throw std::invalid_argument("small_foreground_objects: min_range_jump_m must be finite and > 0");
  }
  std::vector<bool> object(n, false);
  if (!(max_extent_m > 0.0)) return object;
  const auto& r = scan.ranges_m;
  // Beam `neighbour` lies behind a run whose end beam reads `end_range`
  // (`neighbour` is the beam just outside the run, or out of the scan).
  const auto farther = [&](std::ptrdiff_t neighbour, double end_range) {
    if (neighbour < 0 || neighbour >= static_cast<std::ptrdiff_t>(n)) return true;
    const auto k = static_cast<std::size_t>(neighbour);
    return !usable[k] || r[k] > end_range;
  };
  std::size_t first = 0;
  while (first < n) {
    if (!usable[first]) {
      ++first;
      continue;
    }
    std::size_t last = first;
    while (last + 1 < n && usable[last + 1] && std::abs(r[last + 1] - r[last]) <= min_range_jump_m) ++last;
    const Eigen::Vector2d start = scan.beam_point(first);
    bool small = true;
    for (std::size_t i = first + 1; i <= last && small; ++i) {
      small = (scan.beam_point(i) - start).norm() <= max_extent_m;
    }
    if (small && farther(static_cast<std::ptrdiff_t>(first) - 1, r[first]) &&
        farther(static_cast<std::ptrdiff_t>(last) + 1, r[last])) {
      for (std::size_t i = first; i <= last; ++i) object[i] = true;
    }
    first = last + 1;
  }
  return object;
}

}  // namespace lmf
