// The closure of three relative poses measured independently between three
// scans A, B, C (x_AB, x_BC, x_AC, e.g. pairwise scan matches): the residual
// c = (x_AB ⊕ x_BC)⁻¹ ⊕ x_AC is zero when they agree, and needs no reference
// trajectory. Chained increments telescope, so an error that belongs to one
// scan (its own sampling, or the reference's jitter at that scan) cancels in c,
// as it does along a local map; c measures the error that accumulates. The
// three share scans (A→B and A→C share A, A→B and B→C share B) but are taken
// as independent: the closure's NEES comes out low where per-scan errors
// dominate, and does not by itself show that the covariances are right.
#pragma once

#include <Eigen/Core>

#include "lmf/geometry/pose2.hpp"

namespace lmf::eval {

// A relative pose and the covariance of its right perturbation p,
// x_true = x ⊕ p (as ScanMatch::covariance).
struct RelativePose {
  Pose2 x;
  Eigen::Matrix3d covariance;
};

struct Closure {
  Eigen::Vector3d residual;    // c as (x, y, φ), φ wrapped
  Eigen::Matrix3d covariance;  // Σ_i J_i Σ_i J_iᵀ, the three taken as independent
  double nees = 0.0;           // cᵀ Σ⁻¹ c: χ²(3) when the covariances are right
};

// J_i by central differences in the right perturbation of each pose.
Closure closure_of(const RelativePose& ab, const RelativePose& bc, const RelativePose& ac);

}  // namespace lmf::eval
