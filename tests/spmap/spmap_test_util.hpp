// Helpers shared by the spmap tests.
#pragma once

#include <random>

#include <Eigen/Core>

#include "lmf/spmap/stochastic_map.hpp"

namespace lmf::spmap::test {

inline Eigen::MatrixXd random_matrix(Eigen::Index rows, Eigen::Index cols, std::mt19937& rng) {
  std::normal_distribution<double> normal(0.0, 1.0);
  Eigen::MatrixXd A(rows, cols);
  for (Eigen::Index i = 0; i < rows; ++i) {
    for (Eigen::Index j = 0; j < cols; ++j) A(i, j) = normal(rng);
  }
  return A;
}

// A random symmetric positive definite n x n matrix scaled by `scale`.
inline Eigen::MatrixXd random_spd(Eigen::Index n, std::mt19937& rng, double scale = 1.0) {
  const Eigen::MatrixXd A = random_matrix(n, n, rng);
  const Eigen::MatrixXd M = A * A.transpose() / static_cast<double>(n) + 0.1 * Eigen::MatrixXd::Identity(n, n);
  return 0.5 * scale * (M + M.transpose());  // exactly symmetric
}

// Angle-aware difference of (x, y, phi) vectors for numerical Jacobians.
inline Eigen::VectorXd pose_difference(const Eigen::VectorXd& a, const Eigen::VectorXd& b) {
  Eigen::VectorXd d = a - b;
  d(2) = wrap_angle(d(2));
  return d;
}

}  // namespace lmf::spmap::test
