// The EKF machinery shared by the local map and the global map (paper eqs. 7–9):
// sparse implicit measurements, individual and joint compatibility, and the
// update through the careful inversion (docs/design.md §6).
//
// Notation, defined once here: P state covariance; an implicit measurement h(p)
// with value ĥ = h(0) and Jacobian H = ∂h/∂p (sparse: a few entity blocks);
// R the covariance of noise outside the state as it enters h; S = H P Hᵀ + R the
// innovation covariance; W = P Hᵀ S⁻¹ the gain.
#pragma once

#include <optional>
#include <vector>

#include <Eigen/Core>

#include "lmf/spmap/careful_inverse.hpp"
#include "lmf/spmap/relative_location.hpp"
#include "lmf/spmap/stochastic_map.hpp"

namespace lmf::spmap {

struct JacobianBlock {
  EntityId entity;
  Eigen::MatrixXd J;  // rows(h) x dof(entity)
};

struct ImplicitMeasurement {
  Eigen::VectorXd h;                  // ĥ: value at the current estimate (angles wrapped)
  std::vector<JacobianBlock> blocks;  // H, one block per state entity it touches (each entity once)
  Eigen::MatrixXd R;                  // rows(h) x rows(h); zero for a perfect constraint
};

// Builds B_out · chain as a measurement: rows of the chain value picked by
// `rows` (e.g. {1, 2} for a segment's lateral and angular error, {2} for an
// angle), minus `target` on those rows (angle row wrapped). Jacobians of links with the
// same entity are summed (one block per entity, in order of first appearance);
// links without an entity contribute R = Jₗ Rₗ Jₗᵀ, with `link_noise[l]` the
// covariance of that link's perturbation (dof x dof). `link_noise` is empty
// (R = 0, a perfect constraint) or has one entry per link; entries of state
// links are ignored and an empty entry means no noise. `target` is empty (0) or
// one entry per row. Throws std::invalid_argument on bad rows or sizes.
ImplicitMeasurement measurement_from_chain(const std::vector<ChainLink>& links,
                                           const std::vector<int>& rows,
                                           const std::vector<Eigen::MatrixXd>& link_noise = {},
                                           const Eigen::VectorXd& target = {});

// P Hᵀ for stacked measurements: a gather over the columns H touches (n x m).
Eigen::MatrixXd gather_PHt(const StochasticMap& map, const std::vector<ImplicitMeasurement>& measurements);

// S = H P Hᵀ + R for stacked measurements, given P Hᵀ (m x m, symmetric).
Eigen::MatrixXd innovation_covariance(const StochasticMap& map,
                                      const std::vector<ImplicitMeasurement>& measurements,
                                      const Eigen::MatrixXd& PHt);

// Stacked ĥ.
Eigen::VectorXd stacked_value(const std::vector<ImplicitMeasurement>& measurements);

// The largest diagonal of S as if the entities were uncorrelated,
// max_i (Σ_blocks J P_EE Jᵀ + R)_ii: the scale against which the careful
// inversion judges a pivot small (docs/design.md §6). A relation the state already
// knows (a repeated perfect constraint) has S ≈ 0 up to rounding although this
// scale is not small, so its rows are dropped instead of inverting noise.
// Every function below passes it to careful_inverse.
double innovation_reference_scale(const StochasticMap& map, const std::vector<ImplicitMeasurement>& measurements);

// Upper alpha quantile of chi2 with `dof` degrees of freedom (e.g. alpha = 0.05 → 95 %).
double chi2_threshold(int dof, double alpha);

struct CompatibilityTest {
  double distance2 = 0.0;  // ĥᵀ S⁻¹ ĥ over the kept rows
  int dof = 0;             // rows kept by the careful inversion
  bool passed = false;     // distance2 < chi2_threshold(dof, alpha); dof 0 passes
};

// Mahalanobis test of one measurement (paper eq. 8), through the careful inversion.
CompatibilityTest individual_compatibility(const StochasticMap& map, const ImplicitMeasurement& m,
                                           double alpha, double relative_tolerance = 1e-9);

// Incremental joint compatibility: visits candidates in the given order and keeps
// each one whose addition leaves the joint set compatible (chi2 at the joint
// dof after the careful inversion). Returns the indices kept, in visiting order.
std::vector<std::size_t> incremental_joint_compatibility(const StochasticMap& map,
                                                         const std::vector<ImplicitMeasurement>& candidates,
                                                         double alpha, double relative_tolerance = 1e-9);

struct UpdateReport {
  int rows = 0;          // rows of the stacked measurement
  int rows_dropped = 0;  // removed by the careful inversion
  double distance2 = 0.0;
};

// Copies the lower triangle of the square matrix P onto its upper triangle
// (cache-blocked; used after a lower-triangle rank-k update). Takes a dense
// matrix or a block of one, e.g. StochasticMap::mutable_covariance().
void mirror_lower_to_upper(Eigen::Ref<Eigen::MatrixXd> P);

// One EKF update with all measurements (eq. 9): p̂ = -W ĥ over the kept rows,
// P ← P - W H P, then p̂ is folded into every location and reset to 0. The
// covariance update is a rank-k update of the lower triangle, mirrored after.
// Cost O(n·m·dof) for P Hᵀ + O(m³) for the careful inversion + O(n²·k) for
// the update (k kept rows); no n x m H is formed. Throws std::invalid_argument
// for unknown entities or inconsistent sizes (before changing anything).
UpdateReport ekf_update(StochasticMap& map, const std::vector<ImplicitMeasurement>& measurements,
                        double relative_tolerance = 1e-9);

}  // namespace lmf::spmap
