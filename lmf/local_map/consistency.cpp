#include "lmf/local_map/consistency.hpp"

#include <stdexcept>

#include <Eigen/Cholesky>

#include "lmf/spmap/ekf.hpp"

namespace lmf {

std::optional<double> pose_nees(const Pose2& x_hat, const Eigen::Matrix3d& P, const Pose2& x_true) {
  const Eigen::Vector3d e = between(x_hat, x_true).vector();  // angle already wrapped
  const Eigen::Matrix3d symmetric = 0.5 * (P + P.transpose());
  const Eigen::LLT<Eigen::Matrix3d> llt(symmetric);
  if (llt.info() != Eigen::Success || symmetric.diagonal().minCoeff() <= 0.0) return std::nullopt;
  return e.dot(llt.solve(e));
}

NeesBand average_nees_band(int dof, int samples, double confidence) {
  if (dof < 1 || samples < 1 || !(confidence > 0.0 && confidence < 1.0)) {
    throw std::invalid_argument("average_nees_band: need dof >= 1, samples >= 1 and confidence in (0, 1)");
  }
  const int total = dof * samples;
  const double n = static_cast<double>(samples);
  const double tail = 0.5 * (1.0 - confidence);
  // chi2_threshold(k, a) is the upper-a quantile, chi2inv(1 - a, k).
  return {spmap::chi2_threshold(total, 1.0 - tail) / n, spmap::chi2_threshold(total, tail) / n};
}

}  // namespace lmf
