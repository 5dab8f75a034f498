#include "lmf/spmap/covariance_check.hpp"

#include <algorithm>
#include <cmath>
#include <limits>
#include <sstream>

#include <Eigen/Cholesky>
#include <Eigen/Eigenvalues>

namespace lmf::spmap {

std::string CovarianceHealth::describe() const {
  std::ostringstream out;
  out << (ok() ? "ok" : "BAD") << ": max|P-P^T|=" << max_asymmetry << (symmetric ? "" : " (not symmetric)");
  if (min_eigenvalue) {
    out << ", min eigenvalue=" << *min_eigenvalue << (positive_semidefinite ? "" : " (not PSD)");
  } else {
    out << ", PSD within tolerance";
  }
  return out.str();
}

CovarianceHealth check_covariance(const Eigen::Ref<const Eigen::MatrixXd>& P, double tolerance) {
  CovarianceHealth health;
  if (P.rows() != P.cols() || !P.allFinite()) {
    health.symmetric = false;
    health.positive_semidefinite = false;
    health.max_asymmetry = std::numeric_limits<double>::infinity();
    health.min_eigenvalue = std::numeric_limits<double>::quiet_NaN();
    return health;
  }
  if (P.size() == 0) return health;

  const double scale = std::max(1.0, P.diagonal().cwiseAbs().maxCoeff());
  health.max_asymmetry = (P - P.transpose()).cwiseAbs().maxCoeff();
  health.symmetric = health.max_asymmetry <= tolerance * scale;
  const double shift = std::max(tolerance * scale, std::numeric_limits<double>::min());
  Eigen::MatrixXd shifted = 0.5 * (P + P.transpose());
  // A factor with NaN or inf fails too: huge entries overflow inside the
  // factorisation and NaN passes LLT's own pivot test.
  shifted.diagonal().array() += shift;
  const Eigen::LLT<Eigen::MatrixXd> llt(shifted);
  if (llt.info() == Eigen::Success && llt.matrixLLT().allFinite()) return health;
  const Eigen::SelfAdjointEigenSolver<Eigen::MatrixXd> solver(0.5 * (P + P.transpose()), Eigen::EigenvaluesOnly);
  health.min_eigenvalue = solver.eigenvalues().minCoeff();
  health.positive_semidefinite = *health.min_eigenvalue >= -tolerance * scale;
  return health;
}

}  // namespace lmf::spmap
