#include "lmf/eval/map_error.hpp"

#include <algorithm>
#include <cmath>
#include <limits>
#include <numbers>
#include <stdexcept>

namespace lmf::eval {
namespace {

double point_to_segment(const Eigen::Vector2d& p, const LineSegment& s) {
  const Eigen::Vector2d d = s.b - s.a;
  const double len2 = d.squaredNorm();
  const double t = len2 > 0.0 ? std::clamp((p - s.a).dot(d) / len2, 0.0, 1.0) : 0.0;
  return (p - (s.a + t * d)).norm();
}

// Angle between the two lines, ignoring their orientation, in [0, pi/2].
double line_angle(const LineSegment& u, const LineSegment& v) {
  const Eigen::Vector2d du = u.b - u.a;
  const Eigen::Vector2d dv = v.b - v.a;
  double a = std::abs(wrap_angle(std::atan2(du.y(), du.x()) - std::atan2(dv.y(), dv.x())));
  if (a > std::numbers::pi / 2.0) a = std::numbers::pi - a;
  return a;
}

}  // namespace

MapError map_error(const std::vector<LineSegment>& mapped_in_W, const std::vector<LineSegment>& walls,
                   const Pose2& x_TW, double step_m, double max_distance_m, double max_angle_rad) {
  if (!(step_m > 0.0)) throw std::invalid_argument("map_error: step_m must be > 0");
  MapError result;
  double sum2 = 0.0;
  for (const LineSegment& m : mapped_in_W) {
    const LineSegment s{x_TW.transform_point(m.a), x_TW.transform_point(m.b)};
    const double length = (s.b - s.a).norm();
    const int n = std::max(2, static_cast<int>(std::ceil(length / step_m)) + 1);
    std::vector<Eigen::Vector2d> samples;
    for (int i = 0; i < n; ++i) samples.push_back(s.a + (s.b - s.a) * (static_cast<double>(i) / (n - 1)));
    ++result.segments;
    // A wall mapped as one segment may be several faces in the truth (a
    // corridor wall interrupted by doors, two rooms' walls in line): each
    // sample is scored against the nearest face of the same direction.
    std::vector<const LineSegment*> parallel;
    for (const LineSegment& w : walls) {
      if (line_angle(s, w) <= max_angle_rad) parallel.push_back(&w);
    }
    std::vector<double> distances;
    distances.reserve(samples.size());
    double mean = 0.0;
    for (const auto& p : samples) {
      double d = std::numeric_limits<double>::infinity();
      for (const LineSegment* w : parallel) d = std::min(d, point_to_segment(p, *w));
      distances.push_back(d);
      mean += d;
    }
    mean /= static_cast<double>(samples.size());
    if (parallel.empty() || mean > max_distance_m) {
      ++result.unmatched_segments;
      continue;
    }
    for (const double d : distances) {
      sum2 += d * d;
      result.max_m = std::max(result.max_m, d);
      ++result.points;
    }
  }
  if (result.points > 0) result.rms_m = std::sqrt(sum2 / static_cast<double>(result.points));
  return result;
}

}  // namespace lmf::eval
