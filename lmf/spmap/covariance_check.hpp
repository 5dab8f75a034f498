// Covariance supervision: symmetry and positive semidefiniteness within tolerance.
#pragma once

#include <string>

#include <Eigen/Core>

namespace lmf::spmap {

struct CovarianceHealth {
  bool symmetric = true;
  bool positive_semidefinite = true;
  double max_asymmetry = 0.0;     // max |P - Pᵀ|
  double min_eigenvalue = 0.0;    // smallest eigenvalue of (P + Pᵀ)/2
  bool ok() const { return symmetric && positive_semidefinite; }
  std::string describe() const;
};

// PSD means min_eigenvalue >= -tolerance * max(1, max |P_ii|).
CovarianceHealth check_covariance(const Eigen::Ref<const Eigen::MatrixXd>& P, double tolerance = 1e-9);

}  // namespace lmf::spmap
