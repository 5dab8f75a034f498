// Relative locations between entities and their Jacobians with respect to every
// perturbation involved: the building block of the implicit measurement
// equations h = B(⊖x_AS ⊕ ... ⊕ x_BE) (paper eqs. 5–7, 12; DESIGN §4.3, §5.2).
#pragma once

#include <optional>
#include <vector>

#include <Eigen/Core>

#include "lmf/geometry/pose2.hpp"
#include "lmf/spmap/entity.hpp"
#include "lmf/spmap/stochastic_map.hpp"

namespace lmf::spmap {

// One factor of a chain ⊕-product: (x̂ ⊕ B_kindᵀ p), inverted (⊖) when `inverted`.
// `entity` names the state entity that owns p; nullopt for a perturbation that is
// not in the state (an observation, whose noise enters as R).
struct ChainLink {
  Pose2 location;
  EntityKind kind = EntityKind::kFrame;
  bool inverted = false;
  std::optional<EntityId> entity;
};

struct ChainValue {
  Pose2 value;                                  // the chain evaluated at p = 0
  std::vector<Eigen::MatrixXd> jacobians;       // per link: 3 x dof(kind), ∂value/∂p_link at p = 0
};

ChainValue evaluate_chain(const std::vector<ChainLink>& links);

// The chain x_{root,E} of an entity through its parents: [x_{root,P1}, ..., x_{Pk,E}].
std::vector<ChainLink> chain_from_root(const StochasticMap& map, EntityId id);

// The chain giving x_AB = ⊖x_{root,A} ⊕ x_{root,B}: the inverted chain of A
// followed by the chain of B (shared ancestors are kept; their Jacobians cancel).
std::vector<ChainLink> chain_between(const StochasticMap& map, EntityId a, EntityId b);

}  // namespace lmf::spmap
