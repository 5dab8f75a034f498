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
//  * The EKF update is a gather P Hᵀ over the entities H touches, then
//    P ← P − U Uᵀ with U = P Hᵀ L⁻ᵀ (S = L Lᵀ over the rows the careful
//    inversion keeps): Eigen's symmetric rank-k update of the lower triangle.
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
#include "lmf/spmap/entity.hpp"
#include "lmf/spmap/relative_location.hpp"
#include "lmf/spmap/stochastic_map.hpp"

namespace lmf::fusion {

using spmap::Entity;
using spmap::EntityId;
using spmap::EntityKind;

struct StateUpdateReport {
  int rows = 0;           // rows of the stacked measurement
  int rows_dropped = 0;   // rows the careful inversion found redundant (docs/design.md §6)
  int rows_kept = 0;      // k: the rank of the covariance update
  double distance2 = 0.0; // ĥᵀ S⁻¹ ĥ over the kept rows
  std::vector<EntityId> touched;  // entities with a Jacobian block (for health checks)
};

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

  // P Hᵀ (n x m) as a gather over the entities the measurements touch.
  Eigen::MatrixXd gather_PHt(const std::vector<spmap::ImplicitMeasurement>& measurements) const;

  // S = H P Hᵀ + R (m x m) through the marginal of the touched entities only,
  // and the scale against which the careful inversion judges a pivot small:
  // the largest diagonal of S as if the touched entities were uncorrelated,
  // max_i (Σ_blocks J P_EE Jᵀ + R)_ii (the rule of spmap::innovation_reference_scale).
  // A relation the state already knows has S ≈ 0 (rounding) while this is not small.
  // row_scale holds that diagonal row by row, so a diagonal block of S (one
  // measurement of the stack) carries its own scale: the max over its rows.
  struct Innovation {
    Eigen::MatrixXd S;
    Eigen::VectorXd row_scale;
    double reference_scale = 0.0;
  };
  Innovation innovation(const std::vector<spmap::ImplicitMeasurement>& measurements) const;
  Innovation innovation(const spmap::ImplicitMeasurement& measurement) const;
  Eigen::MatrixXd innovation_covariance(const std::vector<spmap::ImplicitMeasurement>& measurements) const {
    return innovation(measurements).S;
  }
  double reference_scale(const std::vector<spmap::ImplicitMeasurement>& measurements) const {
    return innovation(measurements).reference_scale;
  }

  // One EKF update with all measurements (paper eq. 9) through the careful
  // inversion (docs/design.md §6): rows whose pivot is below
  // max(relative_tolerance · max(max diag S, reference_scale), absolute_floor)
  // are dropped (an all-dropped S changes nothing). p̂ is folded into the
  // locations and reset to 0.
  StateUpdateReport ekf_update(const std::vector<spmap::ImplicitMeasurement>& measurements,
                               double relative_tolerance, double absolute_floor);

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
  void validate_measurement(const spmap::ImplicitMeasurement& m, const char* where) const;
  std::vector<Eigen::Index> rows_of(const std::vector<EntityId>& ids) const;
  // The stacked measurements over the entities they touch: H (m x t, columns
  // in the order of `touched`), R and ĥ. H is block sparse (each measurement
  // touches a few entities); `blocks` lists its nonzero blocks.
  struct Stacked {
    struct Block {
      Eigen::Index row;     // first row (the measurement's)
      Eigen::Index rows;    // the measurement's dimension
      std::size_t touched;  // index into `touched` / `column`
    };
    std::vector<EntityId> touched;
    std::vector<Eigen::Index> column;  // first column of each touched entity in H
    std::vector<Eigen::Index> width;   // its degrees of freedom
    std::vector<Eigen::Index> offset;  // its first row in P
    std::vector<Block> blocks;
    Eigen::MatrixXd H;
    Eigen::MatrixXd R;
    Eigen::VectorXd h;

    // X Hᵀ for X with one column per column of H (X: r x t -> r x m): a sum
    // over H's nonzero blocks only, never the dense H. H Y is times_Ht(Yᵀ)ᵀ.
    Eigen::MatrixXd times_Ht(const Eigen::MatrixXd& X) const;
  };
  Stacked stack(std::span<const spmap::ImplicitMeasurement> measurements, const char* where) const;
  Innovation innovation_of(const Stacked& st) const;
  // P(:, touched) (n x t) and P(touched, touched) (t x t).
  Eigen::MatrixXd touched_columns(const Stacked& st) const;
  Eigen::MatrixXd touched_marginal(const Stacked& st, const Eigen::MatrixXd* columns) const;
  // P(touched, :) Hᵀ (t x m): the touched rows of P Hᵀ, in H's column order.
  static Eigen::MatrixXd touched_rows(const Stacked& st, const Eigen::MatrixXd& PHt);
  static Eigen::VectorXd row_scales(const Stacked& st, const Eigen::MatrixXd& P_tt);
  void write_marginal(const std::vector<EntityId>& ids, const Eigen::MatrixXd& M, bool accumulate);

  std::vector<Entity> entities_;
  std::unordered_map<EntityId, std::size_t> index_;
  Eigen::MatrixXd storage_;  // capacity x capacity; lower triangle of the top-left n_ x n_ is P
  Eigen::Index n_ = 0;
  EntityId next_id_ = 0;
};

}  // namespace lmf::fusion
