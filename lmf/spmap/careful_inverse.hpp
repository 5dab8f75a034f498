// Careful inversion of a symmetric positive semidefinite matrix (paper §III.B,
// DESIGN §6): Gauss–Jordan elimination with full (symmetric, diagonal) pivoting
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

// Throws std::invalid_argument if S is not square or not finite. An all-zero S
// keeps nothing.
CarefulInverse careful_inverse(const Eigen::MatrixXd& S, double relative_tolerance = 1e-9);

}  // namespace lmf::spmap
