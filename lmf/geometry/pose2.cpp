#include "lmf/geometry/pose2.hpp"

#include <cmath>
#include <numbers>

namespace lmf {

double wrap_angle(double angle_rad) {
  constexpr double kPi = std::numbers::pi;
  constexpr double kTwoPi = 2.0 * std::numbers::pi;
  if (angle_rad > -kPi && angle_rad <= kPi) return angle_rad;  // the common case, without fmod
  double a = std::fmod(angle_rad, kTwoPi);  // (-2pi, 2pi)
  if (a <= -kPi) a += kTwoPi;
  if (a > kPi) a -= kTwoPi;
  return a;
}

Eigen::Vector2d Pose2::transform_point(const Eigen::Vector2d& p) const {
  const double c = std::cos(phi);
  const double s = std::sin(phi);
  return {x + c * p.x() - s * p.y(), y + s * p.x() + c * p.y()};
}

Pose2 compose(const Pose2& a, const Pose2& b) {
  const double c = std::cos(a.phi);
  const double s = std::sin(a.phi);
  return {a.x + c * b.x - s * b.y, a.y + s * b.x + c * b.y, wrap_angle(a.phi + b.phi)};
}

Pose2 inverse(const Pose2& a) {
  const double c = std::cos(a.phi);
  const double s = std::sin(a.phi);
  return {-c * a.x - s * a.y, s * a.x - c * a.y, wrap_angle(-a.phi)};
}

Pose2 between(const Pose2& x_WA, const Pose2& x_WB) { return compose(inverse(x_WA), x_WB); }

Eigen::Matrix3d J1compose(const Pose2& a, const Pose2& b) {
  const double c = std::cos(a.phi);
  const double s = std::sin(a.phi);
  Eigen::Matrix3d J;
  J << 1.0, 0.0, -s * b.x - c * b.y,  //
      0.0, 1.0, c * b.x - s * b.y,    //
      0.0, 0.0, 1.0;
  return J;
}

Eigen::Matrix3d J2compose(const Pose2& a, const Pose2& /*b*/) {
  const double c = std::cos(a.phi);
  const double s = std::sin(a.phi);
  Eigen::Matrix3d J;
  J << c, -s, 0.0,  //
      s, c, 0.0,    //
      0.0, 0.0, 1.0;
  return J;
}

Eigen::Matrix3d Jinverse(const Pose2& a) {
  const double c = std::cos(a.phi);
  const double s = std::sin(a.phi);
  const Pose2 inv = inverse(a);
  Eigen::Matrix3d J;
  J << -c, -s, inv.y,  //
      s, -c, -inv.x,   //
      0.0, 0.0, -1.0;
  return J;
}

bool is_near(const Pose2& a, const Pose2& b, double tolerance_m, double tolerance_rad) {
  return std::abs(a.x - b.x) <= tolerance_m && std::abs(a.y - b.y) <= tolerance_m &&
         std::abs(wrap_angle(a.phi - b.phi)) <= tolerance_rad;
}

}  // namespace lmf
