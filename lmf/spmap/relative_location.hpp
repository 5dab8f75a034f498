// Relative locations between entities and their Jacobians with respect to every
// perturbation involved: the building block of the implicit measurement
// equations h = B(⊖x_AS ⊕ ... ⊕ x_BE) (paper eqs. 5–7, 12; docs/design.md §4.3, §5.2).
#pragma once

#include <concepts>
#include <cstddef>
#include <optional>
#include <vector>

#include <Eigen/Core>

#include "lmf/geometry/pose2.hpp"
#include "lmf/spmap/entity.hpp"

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

// Anything that stores entities with parents: StochasticMap (the agent's local
// map) and fusion::GlobalState (the global map). The walks below serve both.
template <typename Map>
concept EntityStore = requires(const Map& map, EntityId id) {
  { map.entity(id) } -> std::convertible_to<const Entity&>;
  { map.entities().size() } -> std::convertible_to<std::size_t>;
};

namespace detail {
[[noreturn]] void throw_parent_cycle(const char* where, EntityId id);
}  // namespace detail

// Calls visit(e) for the entity `id`, its parent, ..., up to its root.
// Throws std::invalid_argument (naming `where`) on a parent cycle.
template <EntityStore Map, typename Visit>
void for_each_ancestor(const Map& map, EntityId id, const char* where, Visit&& visit) {
  const Entity* e = &map.entity(id);
  for (std::size_t depth = 0;; ++depth) {
    if (depth > map.entities().size()) detail::throw_parent_cycle(where, id);
    visit(*e);
    if (!e->parent) return;
    e = &map.entity(*e->parent);
  }
}

// x_{root,E} = x_{root,P1} ⊕ ... ⊕ x_{Pk,E} at p = 0 (locations only, no Jacobians).
template <EntityStore Map>
Pose2 root_location(const Map& map, EntityId id) {
  Pose2 x;
  bool first = true;
  for_each_ancestor(map, id, "root_location", [&](const Entity& e) {
    x = first ? e.location : compose(e.location, x);
    first = false;
  });
  return x;
}

// The chain x_{root,E} of an entity through its parents: [x_{root,P1}, ..., x_{Pk,E}].
template <EntityStore Map>
std::vector<ChainLink> chain_from_root(const Map& map, EntityId id) {
  std::vector<ChainLink> reversed;
  for_each_ancestor(map, id, "chain_from_root",
                    [&](const Entity& e) { reversed.push_back({e.location, e.kind, false, e.id}); });
  return {reversed.rbegin(), reversed.rend()};
}

// The chain giving x_AB = ⊖x_{root,A} ⊕ x_{root,B}: the inverted chain of A
// followed by the chain of B (shared ancestors are kept; their Jacobians cancel).
template <EntityStore Map>
std::vector<ChainLink> chain_between(const Map& map, EntityId a, EntityId b) {
  // ⊖(x_1 ⊕ ... ⊕ x_k) = ⊖x_k ⊕ ... ⊕ ⊖x_1.
  const std::vector<ChainLink> chain_a = chain_from_root(map, a);
  std::vector<ChainLink> links(chain_a.rbegin(), chain_a.rend());
  for (ChainLink& link : links) link.inverted = !link.inverted;
  const std::vector<ChainLink> chain_b = chain_from_root(map, b);
  links.insert(links.end(), chain_b.begin(), chain_b.end());
  return links;
}

}  // namespace lmf::spmap
