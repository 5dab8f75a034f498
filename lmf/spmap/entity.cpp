#include "lmf/spmap/entity.hpp"

#include <stdexcept>
#include <string>

namespace lmf::spmap {

int dof(EntityKind kind) {
  switch (kind) {
    case EntityKind::kRobot:
    case EntityKind::kFrame:
      return 3;
    case EntityKind::kSegment:
      return 2;
  }
  throw std::invalid_argument("dof: unknown EntityKind " + std::to_string(static_cast<int>(kind)));
}

Eigen::MatrixXd binding(EntityKind kind) {
  // docs/design.md §3: robots and frames bind all of (x, y, phi); segments only (y, phi).
  if (kind == EntityKind::kSegment) {
    Eigen::MatrixXd B = Eigen::MatrixXd::Zero(2, 3);
    B(0, 1) = 1.0;
    B(1, 2) = 1.0;
    return B;
  }
  dof(kind);  // rejects an out-of-range kind
  return Eigen::MatrixXd::Identity(3, 3);
}

Pose2 fold(const Pose2& location, EntityKind kind, const Eigen::VectorXd& p) {
  if (p.size() != dof(kind)) {
    throw std::invalid_argument("fold: perturbation has " + std::to_string(p.size()) + " entries, entity needs " +
                                std::to_string(dof(kind)));
  }
  // x̂ ← x̂ ⊕ Bᵀ p̂ (docs/design.md §3, paper eq. 1).
  const Eigen::Vector3d d = binding(kind).transpose() * p;
  return compose(location, Pose2(d.x(), d.y(), d.z()));
}

Eigen::Matrix2d segment_frame_shift(double dx_m) {
  // A point at x = dx on the old axis moves laterally by p_y + dx·p_phi (small
  // angles), which is the lateral error seen from the shifted frame (docs/design.md §3).
  Eigen::Matrix2d T;
  T << 1.0, dx_m,  //
      0.0, 1.0;
  return T;
}

}  // namespace lmf::spmap
