#include "lmf/bag/planar_pose.hpp"

#include <cmath>

namespace lmf::bag {

Eigen::Isometry3d isometry(const RosPose3& p) {
  Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
  T.linear() = p.rotation.normalized().toRotationMatrix();
  T.translation() = p.translation;
  return T;
}

Pose2 planar_pose(const Eigen::Isometry3d& T) {
  const Eigen::Matrix3d R = T.rotation();
  return Pose2::from_vector({T.translation().x(), T.translation().y(), std::atan2(R(1, 0), R(0, 0))});
}

// The rotated x axis is (w² + x² − y² − z², 2(xy + wz)) times |q|², so its
// heading needs no normalisation and has no 1 − 2z² cancellation.
Pose2 planar_pose(const RosPose3& p) {
  const Eigen::Quaterniond& q = p.rotation;
  const double heading =
      std::atan2(2.0 * (q.x() * q.y() + q.w() * q.z()), q.w() * q.w() + q.x() * q.x() - q.y() * q.y() - q.z() * q.z());
  return Pose2::from_vector({p.translation.x(), p.translation.y(), heading});
}

namespace {

double ulps_away(double v, int steps) {
  for (int k = 0; k < std::abs(steps); ++k) v = std::nextafter(v, steps > 0 ? INFINITY : -INFINITY);
  return v;
}

}  // namespace

RosPose3 ros_pose(const Pose2& x) {
  RosPose3 p;
  p.translation = {x.x, x.y, 0.0};
  // q = (cos φ/2, 0, 0, sin φ/2); search its neighbours, nearest first.
  const double w = std::cos(x.phi / 2.0);
  const double z = std::sin(x.phi / 2.0);
  p.rotation = Eigen::Quaterniond(w, 0.0, 0.0, z);
  for (int radius = 0; radius <= kHeadingSearchUlps; ++radius) {
    for (int dw = -radius; dw <= radius; ++dw) {
      for (int dz = -radius; dz <= radius; ++dz) {
        if (std::max(std::abs(dw), std::abs(dz)) != radius) continue;
        RosPose3 candidate = p;
        candidate.rotation = Eigen::Quaterniond(ulps_away(w, dw), 0.0, 0.0, ulps_away(z, dz));
        if (planar_pose(candidate).phi == x.phi) return candidate;
      }
    }
  }
  return p;
}

}  // namespace lmf::bag
