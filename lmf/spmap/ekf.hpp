// Implicit measurements of the EKF (paper eq. 7) shared by the local map and the
// global map, built from chains of relative locations, and chi2 quantiles. The
// estimator that tests and applies them is estimator.hpp.
//
// Notation, defined once here: P state covariance; an implicit measurement h(p)
// with value ĥ = h(0) and Jacobian H = ∂h/∂p (sparse: a few entity blocks);
// R the covariance of noise outside the state as it enters h; S = H P Hᵀ + R the
// innovation covariance; W = P Hᵀ S⁻¹ the gain.
#pragma once

#include <vector>

#include <Eigen/Core>

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

// Upper alpha quantile of chi2 with `dof` degrees of freedom (e.g. alpha = 0.05 → 95 %).
double chi2_threshold(int dof, double alpha);

}  // namespace lmf::spmap
