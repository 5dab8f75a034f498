// Chains of consecutive relative poses, e.g. a local map's matched scan
// increments x_{k−1,k}, composed over n steps and scored against a reference:
// x_{k,k+n} = x_{k,k+1} ⊕ … ⊕ x_{k+n−1,k+n}, with its covariance propagated as
// if the steps' errors were independent. An error that belongs to one scan
// (its own sampling, or the reference's jitter at that scan) enters two
// consecutive steps with opposite signs and cancels in a chain, as it does
// along a local map; an error that accumulates does not. So a chain's NEES
// over many steps says whether a map built from those steps can stay
// consistent, which a single step's NEES against a jittery reference does not.
#pragma once

#include <optional>
#include <vector>

#include <Eigen/Core>

#include "lmf/eval/match_closure.hpp"
#include "lmf/geometry/pose2.hpp"

namespace lmf::eval {

// a ⊕ b with the covariance of the result's right perturbation, a's and b's
// errors taken as independent.
RelativePose compose(const RelativePose& a, const RelativePose& b);

struct ChainError {
  double translation_m = 0.0;  // |(x, y)| of the error p, truth = x ⊕ p
  double rotation_rad = 0.0;   // |φ| of p
  double nees = 0.0;           // pᵀ Σ⁻¹ p: χ²(3) when the covariance is right
  // p_i² / Σ_ii for x, y (along and across the heading of the chain's last
  // pose, the frame of p) and φ:
  // χ²(1) each when that axis's variance is right, so a mean above 1 names
  // the axis the covariance understates.
  Eigen::Vector3d axis_nees = Eigen::Vector3d::Zero();
};

// steps[k] is x_{k−1,k} (steps[0] is not used), std::nullopt where there is
// none (a failed match); reference[k] is scan k's reference pose, std::nullopt
// where there is none. One chain of n >= 1 steps per start k for which all n
// steps and both ends' references exist and whose covariance is positive
// definite, in order of k.
std::vector<ChainError> chain_errors(const std::vector<std::optional<RelativePose>>& steps,
                                     const std::vector<std::optional<Pose2>>& reference, int n);

}  // namespace lmf::eval
