#include "lmf/spmap/covariance_check.hpp"

#include <algorithm>
#include <cmath>
#include <limits>
#include <sstream>

#include <Eigen/Eigenvalues>

namespace lmf::spmap {

std::string CovarianceHealth::describe() const {
  std::ostringstream out;
  out << (ok() ? "ok" : "BAD") << ": max|P-P^T|=" << max_asymmetry << (symmetric ? "" : " (not symmetric)")
      << ", min eigenvalue=" << min_eigenvalue << (positive_semidefinite ? "" : " (not PSD)");
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
  // O(n³) eigen-decomposition: fine for local maps (tens of entities) and for
  // occasional supervision of the global map, not for every update of a big one.
  const Eigen::MatrixXd sym = 0.5 * (P + P.transpose());
  const Eigen::SelfAdjointEigenSolver<Eigen::MatrixXd> solver(sym, Eigen::EigenvaluesOnly);
  health.min_eigenvalue = solver.eigenvalues().minCoeff();
  health.positive_semidefinite = health.min_eigenvalue >= -tolerance * scale;
  return health;
}

}  // namespace lmf::spmap
