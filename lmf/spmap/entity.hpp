// SPmap entities (docs/design.md §3; paper eq. 1): every entity E has an estimated location
// x̂_PE relative to its parent frame P and a perturbation p_E in its own frame:
//   x_PE = x̂_PE ⊕ B_Eᵀ p_E,  p̂_E = 0.
// Robots and frames bind all three components (B = I3); a segment binds only its
// lateral and angular error (B = [[0,1,0],[0,0,1]]): its frame sits at the
// midpoint with x along the segment, where position along x is not observable.
#pragma once

#include <cstdint>
#include <optional>

#include <Eigen/Core>

#include "lmf/geometry/pose2.hpp"

namespace lmf::spmap {

enum class EntityKind : std::uint8_t {
  kRobot,    // a robot pose (3 dof)
  kFrame,    // a reference frame: local-map frame L_r or submap frame F_i (3 dof)
  kSegment,  // a wall segment (2 dof: lateral, angular)
};

using EntityId = std::int64_t;  // stable for the life of the map; never reused

struct Entity {
  EntityId id = 0;
  EntityKind kind = EntityKind::kSegment;
  Pose2 location;                   // x̂_PE relative to the parent (or the root)
  double length_m = 0.0;            // segments only
  std::optional<EntityId> parent;   // nullopt: relative to the root frame
  Eigen::Index offset = 0;          // first row of p_E in P
};

// Size of the perturbation p_E: 3 for robots and frames, 2 for segments.
int dof(EntityKind kind);

// B_E: dof(kind) x 3.
Eigen::MatrixXd binding(EntityKind kind);

// x̂ ⊕ B_Eᵀ p: folds an estimated perturbation into a location (after an EKF update).
// Throws std::invalid_argument when p.size() != dof(kind).
Pose2 fold(const Pose2& location, EntityKind kind, const Eigen::VectorXd& p);

// Moving a segment's frame by dx (m) along its own x axis changes the meaning of
// its lateral error: p' = T p with T = [[1, dx], [0, 1]] (docs/design.md §3).
Eigen::Matrix2d segment_frame_shift(double dx_m);

}  // namespace lmf::spmap
