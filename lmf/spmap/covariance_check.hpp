// Covariance supervision: symmetry and positive semidefiniteness within tolerance.
#pragma once

#include <optional>
#include <string>

#include <Eigen/Core>

namespace lmf::spmap {

struct CovarianceHealth {
  bool symmetric = true;
  bool positive_semidefinite = true;
  double max_asymmetry = 0.0;  // max |P - Pᵀ|
  // Smallest eigenvalue of (P + Pᵀ)/2: computed only when the Cholesky
  // certificate below fails (or P is not finite: NaN), absent otherwise.
  std::optional<double> min_eigenvalue;
  bool ok() const { return symmetric && positive_semidefinite; }
  std::string describe() const;
};

// PSD means min eigenvalue >= -tolerance * max(1, max |P_ii|). Certified by one
// Cholesky of (P + Pᵀ)/2 + tolerance * max(1, max |P_ii|) * I (n³/3 flops,
// several times cheaper than an eigen-decomposition); the eigen-decomposition
// runs only when that fails, to say by how much (and to decide the borderline
// case the factorisation's own rounding can fail).
CovarianceHealth check_covariance(const Eigen::Ref<const Eigen::MatrixXd>& P, double tolerance = 1e-9);

}  // namespace lmf::spmap
