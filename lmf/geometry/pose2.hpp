// SE(2) locations and their composition (docs/design.md §3; Smith, Self & Cheeseman).
//
// A location x_AB = (x, y, phi) is frame B seen from frame A: metres and radians,
// phi wrapped to (-pi, pi]. Names carry their frames (x_WR: robot R in world W),
// so a chain compose(x_WR, x_RE) = x_WE is checked by matching the inner letters.
//
// All functions are pure and thread-safe.
#pragma once

#include <cmath>

#include <Eigen/Core>

namespace lmf {

// Wraps an angle to (-pi, pi].
double wrap_angle(double angle_rad);

struct Pose2 {
  double x = 0.0;    // m
  double y = 0.0;    // m
  double phi = 0.0;  // rad, in (-pi, pi] once built through the functions below

  Pose2() = default;
  Pose2(double x_m, double y_m, double phi_rad) : x(x_m), y(y_m), phi(phi_rad) {}

  // (x, y, phi) as a column vector, and back (the angle is wrapped).
  Eigen::Vector3d vector() const { return {x, y, phi}; }
  static Pose2 from_vector(const Eigen::Vector3d& v) { return {v.x(), v.y(), wrap_angle(v.z())}; }

  // The point p (given in this frame) expressed in the parent frame.
  Eigen::Vector2d transform_point(const Eigen::Vector2d& p) const;
};

// True when x, y and phi are all finite (no NaN, no inf).
inline bool finite(const Pose2& p) { return std::isfinite(p.x) && std::isfinite(p.y) && std::isfinite(p.phi); }

// a ⊕ b: x_AC = compose(x_AB, x_BC).
Pose2 compose(const Pose2& a, const Pose2& b);

// ⊖a: x_BA = inverse(x_AB).
Pose2 inverse(const Pose2& a);

// ⊖a ⊕ b: x_AB = between(x_WA, x_WB).
Pose2 between(const Pose2& x_WA, const Pose2& x_WB);

// Jacobians of compose(a, b) with respect to a (J1⊕) and to b (J2⊕), and of
// inverse(a) with respect to a (J⊖), evaluated at the given values.
Eigen::Matrix3d J1compose(const Pose2& a, const Pose2& b);
Eigen::Matrix3d J2compose(const Pose2& a, const Pose2& b);
Eigen::Matrix3d Jinverse(const Pose2& a);

// Element-wise comparison with an angle-aware difference (for tests and checks).
bool is_near(const Pose2& a, const Pose2& b, double tolerance_m, double tolerance_rad);

}  // namespace lmf
