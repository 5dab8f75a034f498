#include "lmf/spmap/careful_inverse.hpp"

#include <algorithm>
#include <cmath>
#include <limits>
#include <stdexcept>
#include <string>

namespace lmf::spmap {

CarefulInverse careful_inverse(const Eigen::MatrixXd& S, double relative_tolerance) {
  return careful_inverse(S, relative_tolerance, 0.0);
}

CarefulInverse careful_inverse(const Eigen::MatrixXd& S, double relative_tolerance, double reference_scale) {
  if (S.rows() != S.cols()) {
    throw std::invalid_argument("careful_inverse: S is " + std::to_string(S.rows()) + "x" +
                                std::to_string(S.cols()) + ", not square");
  }
  if (!S.allFinite()) throw std::invalid_argument("careful_inverse: S has NaN or inf entries");
  if (!(relative_tolerance >= 0.0) || !(reference_scale >= 0.0) || !std::isfinite(reference_scale)) {
    throw std::invalid_argument("careful_inverse: relative_tolerance and reference_scale must be finite and >= 0");
  }

  const Eigen::Index m = S.rows();
  CarefulInverse result;
  if (m == 0) return result;

  // Symmetric Gauss–Jordan (the "sweep" form): after sweeping the pivot set K,
  // A(K,K) = -S(K,K)⁻¹ and A(R,R) = S(R,R) - S(R,K) S(K,K)⁻¹ S(K,R), so the
  // remaining diagonal holds the Schur-complement pivots the next step chooses
  // from (paper §III.B, docs/design.md §6). Working on (S + Sᵀ)/2 keeps both triangles
  // consistent even if the caller's S is asymmetric by rounding.
  Eigen::MatrixXd A = 0.5 * (S + S.transpose());
  const double largest_initial = A.diagonal().cwiseAbs().maxCoeff();
  const double threshold = relative_tolerance * std::max(largest_initial, reference_scale);

  std::vector<bool> swept(static_cast<std::size_t>(m), false);
  double smallest_kept = std::numeric_limits<double>::infinity();
  Eigen::VectorXd col(m);          // column k before the sweep overwrites it
  Eigen::RowVectorXd col_d(m);     // its transpose over the pivot
  result.kept.reserve(static_cast<std::size_t>(m));
  for (Eigen::Index step = 0; step < m; ++step) {
    // Full symmetric pivoting: the largest remaining diagonal pivot.
    Eigen::Index k = -1;
    double best = -std::numeric_limits<double>::infinity();
    for (Eigen::Index i = 0; i < m; ++i) {
      if (!swept[static_cast<std::size_t>(i)] && A(i, i) > best) {
        best = A(i, i);
        k = i;
      }
    }
    // Stop: every remaining row repeats (within tolerance) what the swept rows
    // already say. `<=` also stops an all-zero S before its first pivot.
    if (k < 0 || best <= threshold) break;

    const double d = A(k, k);
    col = A.col(k);
    col_d = col.transpose() / d;
    A.noalias() -= col * col_d;
    A.col(k) = col / d;
    A.row(k) = col.transpose() / d;
    A(k, k) = -1.0 / d;
    swept[static_cast<std::size_t>(k)] = true;

    if (step == 0) result.largest_pivot = d;
    smallest_kept = std::min(smallest_kept, d);
  }

  for (Eigen::Index i = 0; i < m; ++i) {
    (swept[static_cast<std::size_t>(i)] ? result.kept : result.dropped).push_back(static_cast<int>(i));
  }
  const auto k = static_cast<Eigen::Index>(result.kept.size());
  result.inverse.resize(k, k);
  for (Eigen::Index a = 0; a < k; ++a) {
    for (Eigen::Index b = 0; b < k; ++b) {
      result.inverse(a, b) = -A(result.kept[static_cast<std::size_t>(a)], result.kept[static_cast<std::size_t>(b)]);
    }
  }
  // Symmetric by construction up to rounding; make it exact for the callers.
  result.inverse = 0.5 * (result.inverse + result.inverse.transpose()).eval();
  result.smallest_kept_pivot = k > 0 ? smallest_kept : 0.0;
  return result;
}

}  // namespace lmf::spmap
