#include "lmf/scan/laser_scan.hpp"

#include <cmath>
#include <numbers>
#include <stdexcept>

namespace lmf {

Eigen::Vector2d LaserScan::beam_point(std::size_t i) const {
  const double a = beam_angle(i);
  return {ranges_m.at(i) * std::cos(a), ranges_m.at(i) * std::sin(a)};
}

namespace {

// v rounded to float. Not inlined: GCC 12.2's SLP vectorizer at -O2 drops the
// rounding of two adjacent fields rounded this way (angle_min_rad and
// angle_increment_rad came back unrounded; -fno-tree-slp-vectorize restores it;
// the test LaserScan.AtMessagePrecisionRoundsEveryFloatField catches it).
[[gnu::noinline]] double as_float(double v) { return static_cast<double>(static_cast<float>(v)); }

}  // namespace

LaserScan at_message_precision(const LaserScan& scan) {
  LaserScan out = scan;
  out.angle_min_rad = as_float(scan.angle_min_rad);
  out.angle_increment_rad = as_float(scan.angle_increment_rad);
  out.max_range_m = as_float(scan.max_range_m);
  for (double& r : out.ranges_m) r = as_float(r);
  return out;
}

double beam_increment_for_180deg(std::size_t num_beams) {
  if (num_beams < 2) throw std::invalid_argument("beam_increment_for_180deg: need at least 2 beams");
  const double n = static_cast<double>(num_beams);
  return num_beams % 2 == 1 ? std::numbers::pi / (n - 1.0) : std::numbers::pi / n;
}

}  // namespace lmf
