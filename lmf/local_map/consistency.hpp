// Filter consistency measures for the local map (paper §III.A, Fig. 4): the
// normalised estimation error squared (NEES) of a pose and the chi-square band
// its Monte Carlo average must fall in. Pure functions; thread-safe.
#pragma once

#include <optional>

#include <Eigen/Core>

#include "lmf/geometry/pose2.hpp"

namespace lmf {

// NEES of an estimate x̂ with covariance P of its perturbation (x = x̂ ⊕ p, p in
// the estimate's own frame, docs/design.md §3) against the true pose: e = ⊖x̂ ⊕ x_true
// as (x, y, phi) with phi wrapped, NEES = eᵀ P⁻¹ e. nullopt when P is not
// positive definite (e.g. at the local map's first scan, where P = 0).
std::optional<double> pose_nees(const Pose2& x_hat, const Eigen::Matrix3d& P, const Pose2& x_true);

// The two-sided band for the average of `samples` independent chi2(dof) values:
// [chi2inv((1 - confidence)/2, dof·N)/N, chi2inv((1 + confidence)/2, dof·N)/N].
// Throws std::invalid_argument for dof or samples < 1 or confidence not in (0, 1).
struct NeesBand {
  double lower = 0.0;
  double upper = 0.0;
};
NeesBand average_nees_band(int dof, int samples, double confidence = 0.95);

}  // namespace lmf
