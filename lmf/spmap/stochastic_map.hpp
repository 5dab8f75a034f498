// A stochastic map (SPmap): entities with locations relative to a parent entity
// (or to the map's root frame), and the joint covariance P of all perturbations.
//
// The robot local map uses it with root L (robot and segments children of the
// root); the global map with root W (frames children of the root, segments
// children of their submap frame). P is kept symmetric (both triangles valid).
// P lives in the top-left n x n corner of a larger buffer that grows
// geometrically, so adding an entity costs O(n), not a reallocation and a copy
// of P; covariance() is a view of that corner.
// Not thread-safe; all methods are synchronous.
#pragma once

#include <cstdint>
#include <optional>
#include <unordered_map>
#include <vector>

#include <Eigen/Core>

#include "lmf/geometry/pose2.hpp"
#include "lmf/spmap/entity.hpp"

namespace lmf::spmap {

class StochasticMap {
 public:
  // Views of the n x n covariance P (n = dimension()) inside the spare-capacity
  // buffer: column-major with an outer stride of the capacity. Use `auto` or
  // these types to avoid a copy; binding one to `const Eigen::MatrixXd&` or
  // assigning it to a MatrixXd makes an n x n copy.
  using CovarianceView = Eigen::Block<const Eigen::MatrixXd>;
  using MutableCovarianceView = Eigen::Block<Eigen::MatrixXd>;

  // Appends an entity with zero covariance (rows/columns of P set to 0).
  // Amortised O(n): the buffer grows geometrically when it is full.
  // Throws std::invalid_argument for an unknown parent.
  EntityId add(EntityKind kind, const Pose2& location, std::optional<EntityId> parent = std::nullopt,
               double length_m = 0.0);

  // Removes the entity and its rows/columns of P (O(n²) in-place compaction;
  // the offsets of later entities shift; the capacity is kept). Throws std::invalid_argument if unknown
  // or if other entities still have it as parent.
  void remove(EntityId id);

  bool contains(EntityId id) const;
  const Entity& entity(EntityId id) const;  // throws std::invalid_argument if unknown
  // Location / length / parent edits. Never change `id`, `kind` or `offset`:
  // they index P. A new parent must already exist (no cycles).
  Entity& mutable_entity(EntityId id);
  const std::vector<Entity>& entities() const { return entities_; }  // state order
  std::vector<EntityId> children(std::optional<EntityId> parent) const;

  Eigen::Index dimension() const { return n_; }
  // P (n x n). Assigning to mutable_covariance() writes into P: the right-hand
  // side must be n x n.
  CovarianceView covariance() const { return CovarianceView(P_, 0, 0, n_, n_); }
  MutableCovarianceView mutable_covariance() { return MutableCovarianceView(P_, 0, 0, n_, n_); }
  // P as a covariance store of the estimator (estimator.hpp): both triangles
  // are kept, so the lower one is P's own view.
  CovarianceView lower_view() const { return covariance(); }
  // P ← P − U Uᵀ (U: n x k): a rank-k update of the lower triangle, mirrored
  // so both triangles stay valid. Throws std::invalid_argument if U has not n rows.
  void subtract_outer_product(const Eigen::MatrixXd& U);
  // Rows/columns the buffer holds before the next reallocation (>= dimension()).
  Eigen::Index capacity() const { return P_.rows(); }
  // Grows the buffer to at least `dimension` rows/columns (never shrinks).
  void reserve(Eigen::Index dimension);
  // The block of P between two entities (dof(a) x dof(b)).
  Eigen::MatrixXd block(EntityId a, EntityId b) const;

  // Location of the entity relative to the root frame (composed through parents).
  Pose2 root_location(EntityId id) const;

  // Replaces p_target by a linear combination of entity perturbations:
  //   p_target ← Σ_i J_i p_{e_i}   (J_i: dof(target) x dof(e_i)),
  // transforming P exactly (P ← A P Aᵀ with A the identity except target's rows).
  // Used for the segment frame shift and for L_r ← L_r ⊕ x_R. The location of
  // the target is not touched: callers set it to the matching estimate.
  // Terms may include the target itself and may repeat an entity (summed).
  // Cost O(n·dof·terms). Throws std::invalid_argument for an unknown entity or
  // a J of the wrong size.
  struct LinearTerm {
    EntityId entity;
    Eigen::MatrixXd J;
  };
  void replace_perturbation(EntityId target, const std::vector<LinearTerm>& terms);

  // Appends a copy of `source` (same kind, location, parent, length) whose
  // perturbation equals the source's: its rows of P copy the source's (perfect correlation).
  EntityId add_copy(EntityId source);

  // Resets to an empty map (the capacity is kept). Ids keep counting: an id is never reused.
  void clear();

 private:
  std::size_t index_of(EntityId id) const;

  std::vector<Entity> entities_;
  std::unordered_map<EntityId, std::size_t> index_;  // id -> position in entities_
  Eigen::MatrixXd P_;    // capacity x capacity; P is its top-left n_ x n_ corner
  Eigen::Index n_ = 0;   // dimension of P
  EntityId next_id_ = 0;
};

// Copies the lower triangle of the square matrix P onto its upper triangle
// (cache-blocked; used after a lower-triangle rank-k update). Takes a dense
// matrix or a block of one, e.g. StochasticMap::mutable_covariance().
void mirror_lower_to_upper(Eigen::Ref<Eigen::MatrixXd> P);

}  // namespace lmf::spmap
