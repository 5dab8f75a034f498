// Careful inversion of a symmetric positive semidefinite matrix (paper §III.B,
// docs/design.md §6): Gauss–Jordan elimination with full (symmetric, diagonal) pivoting
// that stops when the best remaining pivot falls below `relative_tolerance`
// times the largest initial diagonal. The rows whose pivots were used carry the
// independent information; the others repeat what those rows already say.
#pragma once

#include <vector>

#include <Eigen/Core>

namespace lmf::spmap {

struct CarefulInverse {
  std::vector<int> kept;    // indices of the independent rows, ascending
  std::vector<int> dropped; // the other rows, ascending
  Eigen::MatrixXd inverse;  // inverse of S(kept, kept), in the order of `kept`
  double largest_pivot = 0.0;
  double smallest_kept_pivot = 0.0;
};

// Elimination stops when the best remaining pivot is <= relative_tolerance *
// max(largest initial |S_ii|, reference_scale). Throws std::invalid_argument if S
// is not square or not finite, or a tolerance is negative. An all-zero S keeps nothing.
CarefulInverse careful_inverse(const Eigen::MatrixXd& S, double relative_tolerance = 1e-9);

// Same, with an absolute scale for "small": the size S would have without the
// cancellations that make it (nearly) singular. Without it a matrix that is all
// rounding noise (a constraint repeated once more) looks well scaled relative to
// itself and its noise would be inverted. estimator.hpp passes the variance of the
// rows as if the entities were uncorrelated.
CarefulInverse careful_inverse(const Eigen::MatrixXd& S, double relative_tolerance, double reference_scale);

}  // namespace lmf::spmap
