// The global map's stochastic map (SPmap) storage, built for thousands of
// entities (docs/design.md §5.3, paper §II.C: O(m²) per fusion).
//
// Same model and entity type as lmf::spmap::StochasticMap (x_PE = x̂_PE ⊕ B_Eᵀ p_E,
// p̂ = 0, P = Cov(p)), with a storage that keeps the fusion at the cost of one
// rank-k update of P:
//  * P lives in a square buffer with spare capacity (grown by 25 % when full),
//    so adding an entity is O(n·dof) and never reallocates in steady state.
//    On this class of machine a fresh 0.5 GB allocation costs more page faults
//    than the whole covariance update, so reallocation per entity is not an option.
//  * Only the LOWER triangle of P (diagonal included) is stored; the upper
//    triangle of the buffer is garbage. Nothing is ever mirrored: every read
//    goes through the lower triangle (column below the diagonal, row left of it).
//  * remove() takes a batch and compacts P in place in one pass, touching only
//    the columns/rows after the first removed entity.
//  * It is a covariance store of the one estimator (spmap/estimator.hpp):
//    compatibility tests and the EKF update read the lower triangle, and the
//    update's P ← P − U Uᵀ is Eigen's symmetric rank-k update of it.
//
// Ids are never reused. Not thread-safe; all methods are synchronous.
#pragma once

#include <optional>
#include <span>
#include <unordered_map>
#include <vector>

#include <Eigen/Core>

#include "lmf/geometry/pose2.hpp"
#include "lmf/spmap/ekf.hpp"
#include "lmf/spmap/estimator.hpp"
#include "lmf/spmap/entity.hpp"
#include "lmf/spmap/relative_location.hpp"
#include "lmf/spmap/stochastic_map.hpp"

namespace lmf::fusion {

using spmap::Entity;
using spmap::EntityId;
using spmap::EntityKind;


class GlobalState {
 public:
  GlobalState() = default;

  // Makes room for a state of `dimension` rows without reallocating later.
  void reserve(Eigen::Index dimension);
  Eigen::Index capacity() const { return storage_.rows(); }
  Eigen::Index dimension() const { return n_; }

  // Appends an entity with zero covariance (rows/columns of P set to 0).
  // Throws std::invalid_argument for an unknown parent.
  EntityId add(EntityKind kind, const Pose2& location, std::optional<EntityId> parent = std::nullopt,
               double length_m = 0.0);

  // Appends a copy of `source` (kind, location, parent, length) whose
  // perturbation equals the source's: perfectly correlated rows of P.
  EntityId add_copy(EntityId source);

  // Removes the listed entities (duplicates allowed) and their rows/columns
  // of P in one in-place compaction. Throws std::invalid_argument (and
  // changes nothing) if one is unknown or still the parent of a kept entity.
  void remove(const std::vector<EntityId>& ids);

  bool contains(EntityId id) const { return index_.count(id) != 0; }
  const Entity& entity(EntityId id) const;  // throws std::invalid_argument if unknown
  // Location / length / parent edits only: never change id, kind or offset.
  Entity& mutable_entity(EntityId id);
  const std::vector<Entity>& entities() const { return entities_; }  // state order

  // One element of P (either triangle is fine: reads the stored lower one).
  double covariance(Eigen::Index i, Eigen::Index j) const {
    return i >= j ? storage_(i, j) : storage_(j, i);
  }
  // P(a, b): dof(a) x dof(b).
  Eigen::MatrixXd block(EntityId a, EntityId b) const;
  // The joint covariance of the listed entities, in the order given.
  Eigen::MatrixXd marginal(const std::vector<EntityId>& ids) const;
  // P(:, e): n x dof(e).
  Eigen::MatrixXd columns(EntityId e) const;
  // The whole symmetric P (O(n²) memory: for tests, export of small maps, checks).
  Eigen::MatrixXd full_covariance() const;
  // The stored lower triangle (upper part of the view is unspecified).
  Eigen::Block<const Eigen::MatrixXd> lower_view() const { return storage_.topLeftCorner(n_, n_); }

  // Sets P(a, b) = M (and P(b, a) = Mᵀ); for a == b, M is symmetrised.
  void set_block(EntityId a, EntityId b, const Eigen::MatrixXd& M);
  // P(a, a) += M (symmetrised); for adding independent noise to an entity.
  void add_to_block(EntityId a, const Eigen::MatrixXd& M);
  // The joint covariance of the listed entities (in that order) set to /
  // increased by the symmetric M (its lower triangle is read).
  void set_marginal(const std::vector<EntityId>& ids, const Eigen::MatrixXd& M);
  void add_to_marginal(const std::vector<EntityId>& ids, const Eigen::MatrixXd& M);

  // Location relative to the root frame (composed through parents).
  Pose2 root_location(EntityId id) const;
  // [x_{root,P1}, ..., x_{Pk,E}] and ⊖x_{root,A} ⊕ x_{root,B} as chains for
  // spmap::measurement_from_chain (same convention as spmap::chain_between).
  std::vector<spmap::ChainLink> chain_from_root(EntityId id) const;
  std::vector<spmap::ChainLink> chain_between(EntityId a, EntityId b) const;

  // p_target ← Σ_i J_i p_{e_i} with P transformed exactly (P ← A P Aᵀ); terms
  // may include the target itself. Locations are not touched.
  struct LinearTerm {
    EntityId entity;
    Eigen::MatrixXd J;  // dof(target) x dof(entity)
  };
  void replace_perturbation(EntityId target, const std::vector<LinearTerm>& terms);

  // p_e ← J_e p_e for each listed entity (distinct; J_e square, dof(e)), P
  // transformed exactly (P ← A P Aᵀ, A block diagonal) in one sweep over the
  // stored columns: the rows of all listed entities within a column share its
  // memory, where one replace_perturbation per entity would walk each
  // entity's row (a column stride apiece) once per entity.
  void transform_perturbations(const std::vector<LinearTerm>& maps);

  // P ← P − U Uᵀ (U: n x k) as one symmetric rank-k update of the stored
  // lower triangle: the covariance step of spmap::ekf_update (estimator.hpp).
  void subtract_outer_product(const Eigen::MatrixXd& U);

  // Appends several entities at once (zero covariance), touching the rows of
  // P once instead of once per entity. Returns their ids in order.
  struct NewEntity {
    EntityKind kind = EntityKind::kSegment;
    Pose2 location;
    std::optional<EntityId> parent;
    double length_m = 0.0;
  };
  std::vector<EntityId> add_many(const std::vector<NewEntity>& entities);

 private:
  friend class GlobalMapArchive;  // global_map_archive.cpp: exact save/restore
  std::size_t index_of(EntityId id) const;
  std::vector<Eigen::Index> rows_of(const std::vector<EntityId>& ids) const;
  void write_marginal(const std::vector<EntityId>& ids, const Eigen::MatrixXd& M, bool accumulate);

  std::vector<Entity> entities_;
  std::unordered_map<EntityId, std::size_t> index_;
  Eigen::MatrixXd storage_;  // capacity x capacity; lower triangle of the top-left n_ x n_ is P
  Eigen::Index n_ = 0;
  EntityId next_id_ = 0;
};

}  // namespace lmf::fusion
