#include "lmf/fusion/crossing_segments.hpp"

#include <cmath>

namespace lmf::fusion {

bool segments_cross(const EndPoints& a, const EndPoints& b, const CrossingRule& rule) {
  const Eigen::Vector2d da = a.end - a.start;
  const Eigen::Vector2d db = b.end - b.start;
  const double la = da.norm();
  const double lb = db.norm();
  if (!(la > 2.0 * rule.margin_m) || !(lb > 2.0 * rule.margin_m)) return false;
  // sin of the angle between the directions; the lines meet where
  // a.start + t da = b.start + u db (t, u as fractions of each length).
  const double cross = da.x() * db.y() - da.y() * db.x();
  const double sin_angle = std::abs(cross) / (la * lb);
  if (sin_angle < 1e-9 || sin_angle > std::sin(rule.max_angle_rad)) return false;
  const Eigen::Vector2d w = b.start - a.start;
  const double t = (w.x() * db.y() - w.y() * db.x()) / cross;
  const double u = (w.x() * da.y() - w.y() * da.x()) / cross;
  const double ma = rule.margin_m / la;
  const double mb = rule.margin_m / lb;
  return t > ma && t < 1.0 - ma && u > mb && u < 1.0 - mb;
}

}  // namespace lmf::fusion
