// The one EKF estimator of lmf (paper eqs. 8–9; docs/design.md §5–6): individual
// and joint compatibility, and the update through the careful inversion. The
// local map (StochasticMap) and the global map (fusion::GlobalState) both call it;
// it is generic over the store of the covariance.
//
// Notation (ekf.hpp): P state covariance; stacked implicit measurements with
// values ĥ, Jacobian H (a few entity blocks each) and noise R; S = H P Hᵀ + R;
// W = P Hᵀ S⁻¹.
//
// A covariance store (CovarianceStore below) exposes its entities and P's lower
// triangle, diagonal included, as an n x n view (lower_view(); the upper
// triangle of the view may be anything), and applies P ← P − U Uᵀ to its own
// storage (subtract_outer_product). Everything here reads the lower triangle
// only, so one implementation serves a store that keeps both triangles and one
// that keeps only the lower.
//
// Pure and synchronous. A Chi2Table caches and is not thread-safe.
#pragma once

#include <concepts>
#include <cstddef>
#include <functional>
#include <span>
#include <vector>

#include <Eigen/Core>

#include "lmf/spmap/careful_inverse.hpp"
#include "lmf/spmap/ekf.hpp"
#include "lmf/spmap/entity.hpp"

namespace lmf::spmap {

// When the careful inversion calls a pivot small: below
// max(relative · max(max |S_ii|, reference scale), absolute_floor). The
// reference scale is the diagonal S would have if the touched entities were
// uncorrelated (Innovation::row_scale); without it, an S that is all rounding
// (a perfect constraint repeated) looks well scaled relative to itself.
struct CarefulTolerance {
  double relative = 1e-9;
  double absolute_floor = 0.0;

  // The scale handed to careful_inverse with `relative`: it applies the floor.
  double scale(double reference_scale) const;
  // The pivot threshold that careful_inverse(S, relative, scale(reference_scale)) applies.
  double pivot_threshold(double max_abs_diagonal, double reference_scale) const;
};

// chi2 thresholds at one significance, computed once per degree of freedom.
class Chi2Table {
 public:
  explicit Chi2Table(double alpha);  // alpha in (0, 1); throws std::invalid_argument otherwise
  double operator()(int dof);        // chi2_threshold(dof, alpha), dof >= 1
  double alpha() const { return alpha_; }

 private:
  double alpha_;
  std::vector<double> cache_;
};

template <class Store>
concept CovarianceStore = requires(const Store& s, Store& w, EntityId id, const Eigen::MatrixXd& U) {
  { s.dimension() } -> std::convertible_to<Eigen::Index>;
  { s.entity(id) } -> std::same_as<const Entity&>;
  { s.entities() } -> std::same_as<const std::vector<Entity>&>;
  s.lower_view();
  { w.mutable_entity(id) } -> std::same_as<Entity&>;
  w.subtract_outer_product(U);
};

// P's lower triangle (n x n; the strict upper triangle is not read).
using LowerCovariance = Eigen::Ref<const Eigen::MatrixXd>;

// Stacked measurements over the entities they touch: H (m x t, one column
// block per touched entity, in order of first appearance), R (block diagonal)
// and ĥ. H is block sparse; `blocks` lists its nonzero blocks.
class StackedMeasurements {
 public:
  using EntityLookup = std::function<const Entity&(EntityId)>;
  // Validates every measurement (sizes, finite values, known entities with
  // Jacobians of their dof); throws std::invalid_argument naming `where`.
  StackedMeasurements(std::span<const ImplicitMeasurement> measurements, const EntityLookup& entity,
                      const char* where);

  struct Block {
    Eigen::Index row;     // first row (the measurement's)
    Eigen::Index rows;    // the measurement's dimension
    std::size_t touched;  // index into touched / column / width / offset
  };
  std::vector<EntityId> touched;
  std::vector<Eigen::Index> column;  // first column of each touched entity in H
  std::vector<Eigen::Index> width;   // its degrees of freedom
  std::vector<Eigen::Index> offset;  // its first row in P
  std::vector<Block> blocks;
  Eigen::MatrixXd H;
  Eigen::MatrixXd R;
  Eigen::VectorXd h;

  Eigen::Index rows() const { return H.rows(); }
  // X Hᵀ for X with one column per column of H (r x t -> r x m): a sum over
  // H's nonzero blocks only. H Y is times_Ht(Yᵀ)ᵀ.
  Eigen::MatrixXd times_Ht(const Eigen::MatrixXd& X) const;
};

template <CovarianceStore Store>
StackedMeasurements stack(const Store& store, std::span<const ImplicitMeasurement> measurements,
                          const char* where) {
  return StackedMeasurements(measurements, [&store](EntityId id) -> const Entity& { return store.entity(id); },
                             where);
}

// S = H P Hᵀ + R through the marginal of the touched entities only, and
// row_scale, the diagonal of S as if the touched entities were uncorrelated,
// (Σ_blocks J P_EE Jᵀ + R)_ii: a diagonal block of S (one measurement of the
// stack) carries its own reference scale, the max of row_scale over its rows.
struct Innovation {
  Eigen::MatrixXd S;
  Eigen::VectorXd row_scale;
  double reference_scale = 0.0;  // max of row_scale (0 for no rows)
};
Innovation innovation(const LowerCovariance& P, const StackedMeasurements& st);

template <CovarianceStore Store>
Innovation innovation(const Store& store, std::span<const ImplicitMeasurement> measurements) {
  return innovation(store.lower_view(), stack(store, measurements, "innovation"));
}

// P Hᵀ (n x m): a gather over the columns of the entities H touches.
Eigen::MatrixXd gather_PHt(const LowerCovariance& P, const StackedMeasurements& st);

template <CovarianceStore Store>
Eigen::MatrixXd gather_PHt(const Store& store, std::span<const ImplicitMeasurement> measurements) {
  return gather_PHt(store.lower_view(), stack(store, measurements, "gather_PHt"));
}

struct CompatibilityTest {
  double distance2 = 0.0;  // ĥᵀ S⁻¹ ĥ over the kept rows
  int dof = 0;             // rows kept by the careful inversion
  bool passed = false;
};

// The rows that the careful inversion `ci` of S dropped are determined by the
// kept ones: given them, their variance is below `pivot_threshold`. Each such
// row's innovation given the kept rows, ν_d − S_dK S_KK⁻¹ ν_K, must then be ≈ 0
// (within what a variance at the threshold allows at the chi2(1) bound).
// Otherwise the measurement contradicts a relation the map already knows
// exactly (a pairing 90° off two segments made perpendicular), and dropping the
// row would accept it silently.
bool dropped_rows_consistent(const Eigen::MatrixXd& S, const Eigen::VectorXd& nu, const CarefulInverse& ci,
                             double pivot_threshold, Chi2Table& chi2);

// Eq. (8): D² = ĥᵀ S⁻¹ ĥ < chi2(dof) over the rows the careful inversion keeps,
// the dropped rows consistent. All rows dropped passes (S ≈ 0 and ĥ ≈ 0).
CompatibilityTest chi2_test(const Eigen::MatrixXd& S, const Eigen::VectorXd& h, double reference_scale,
                            const CarefulTolerance& tolerance, Chi2Table& chi2);

// The test of one measurement on the store's state.
template <CovarianceStore Store>
CompatibilityTest individual_compatibility(const Store& store, const ImplicitMeasurement& m,
                                           const CarefulTolerance& tolerance, Chi2Table& chi2) {
  const Innovation in = innovation(store, {&m, 1});
  return chi2_test(in.S, m.h, in.reference_scale, tolerance, chi2);
}

// Incremental joint compatibility over candidates whose rows are blocks of one
// joint innovation (S, ĥ, row_scale: e.g. innovation() of all candidates
// stacked). The accepted set starts empty; try_add(c) adds candidate c if the
// set stays jointly compatible, growing S_KK⁻¹ by Schur complements, and drops
// the rows of c that the accepted ones already determine (careful inversion,
// with the dropped-row check). Candidates may be tried in any order; one pivot
// threshold over all candidates' rows serves every step. The innovation and
// ĥ must outlive the object.
class JointCompatibility {
 public:
  struct Rows {
    Eigen::Index first = 0;
    Eigen::Index count = 0;
  };
  JointCompatibility(const Eigen::MatrixXd& S, const Eigen::VectorXd& row_scale, const Eigen::VectorXd& h,
                     std::vector<Rows> candidates, const CarefulTolerance& tolerance, Chi2Table& chi2);

  bool try_add(std::size_t candidate);
  double distance2() const { return d2_; }
  int dof() const { return dof_; }

 private:
  void grow(const Rows& rows, const Eigen::MatrixXd& B_Sinv, const CarefulInverse& ci);

  const Eigen::MatrixXd& S_;
  const Eigen::VectorXd& h_;
  std::vector<Rows> candidates_;
  double threshold_ = 0.0;
  double relative_ = 0.0;
  Chi2Table& chi2_;
  std::vector<Eigen::Index> K_;  // kept rows of S
  Eigen::MatrixXd S_K_inv_ = Eigen::MatrixXd(0, 0);
  Eigen::VectorXd h_K_ = Eigen::VectorXd(0);
  double d2_ = 0.0;
  int dof_ = 0;
};

// The candidates in `order` (indices into `measurements`) visited one after
// another; returns those kept, in visiting order.
template <CovarianceStore Store>
std::vector<std::size_t> incremental_joint_compatibility(const Store& store,
                                                         std::span<const ImplicitMeasurement> measurements,
                                                         const CarefulTolerance& tolerance, Chi2Table& chi2);

struct UpdateReport {
  int rows = 0;                   // rows of the stacked measurement
  int rows_dropped = 0;           // removed by the careful inversion (redundant)
  int rows_kept = 0;              // k: the rank of the covariance update
  double distance2 = 0.0;         // ĥᵀ S⁻¹ ĥ over the kept rows
  std::vector<EntityId> touched;  // entities with a Jacobian block
};

// What one EKF update (eq. 9) does to the state, computed from the lower
// triangle: p̂ = −W ĥ over the kept rows, and U with P ← P − U Uᵀ
// (U = P Hᵀ L⁻ᵀ, S_kept = L Lᵀ), n x k.
struct UpdateStep {
  UpdateReport report;
  Eigen::MatrixXd U;
  Eigen::VectorXd p_hat;
};
UpdateStep update_step(const LowerCovariance& P, const StackedMeasurements& st, const CarefulTolerance& tolerance);

// x̂_E ← x̂_E ⊕ B_Eᵀ p̂_E for every entity (docs/design.md §3): p̂ is folded
// into the locations, the perturbation estimate is back at 0.
template <CovarianceStore Store>
void fold_perturbation(Store& store, const Eigen::VectorXd& p_hat) {
  for (const Entity& e : store.entities()) {
    const auto p_E = p_hat.segment(e.offset, dof(e.kind));
    if (p_E.isZero(0.0)) continue;
    Entity& target = store.mutable_entity(e.id);
    target.location = fold(target.location, e.kind, p_E);
  }
}

// One EKF update with all measurements (eq. 9) through the careful inversion
// (docs/design.md §6): rows whose pivot is below the tolerance are dropped (an
// all-dropped S changes nothing); P ← P − U Uᵀ as one symmetric rank-k update;
// p̂ folded into the locations. Cost O(n·t) for the gather, O(m³) for the
// inversion, O(n²·k) for the update; no n x m H is formed. Throws
// std::invalid_argument for unknown entities or inconsistent sizes, before
// changing anything.
template <CovarianceStore Store>
UpdateReport ekf_update(Store& store, std::span<const ImplicitMeasurement> measurements,
                        const CarefulTolerance& tolerance) {
  UpdateStep step = update_step(store.lower_view(), stack(store, measurements, "ekf_update"), tolerance);
  if (step.report.rows_kept > 0) {
    store.subtract_outer_product(step.U);
    fold_perturbation(store, step.p_hat);
  }
  return step.report;
}

// ---------------------------------------------------------------------------

template <CovarianceStore Store>
std::vector<std::size_t> incremental_joint_compatibility(const Store& store,
                                                         std::span<const ImplicitMeasurement> measurements,
                                                         const CarefulTolerance& tolerance, Chi2Table& chi2) {
  const StackedMeasurements st = stack(store, measurements, "incremental_joint_compatibility");
  const Innovation in = innovation(store.lower_view(), st);
  std::vector<JointCompatibility::Rows> rows;
  rows.reserve(measurements.size());
  Eigen::Index first = 0;
  for (const ImplicitMeasurement& m : measurements) {
    rows.push_back({first, m.h.size()});
    first += m.h.size();
  }
  JointCompatibility jc(in.S, in.row_scale, st.h, std::move(rows), tolerance, chi2);
  std::vector<std::size_t> kept;
  for (std::size_t c = 0; c < measurements.size(); ++c) {
    if (jc.try_add(c)) kept.push_back(c);
  }
  return kept;
}

}  // namespace lmf::spmap
