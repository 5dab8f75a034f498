#include "lmf/eval/increment_chain.hpp"

#include <algorithm>
#include <cmath>
#include <cstddef>

#include <Eigen/Cholesky>
#include <Eigen/LU>

namespace lmf::eval {
namespace {

// The covariance of a pose's parameters (x, y, φ) from that of its right
// perturbation p, x_true = x ⊕ p: J P Jᵀ with J = ∂(x ⊕ p)/∂p at p = 0.
Eigen::Matrix3d in_parameters(const RelativePose& r) {
  const Eigen::Matrix3d J = J2compose(r.x, Pose2());
  return J * r.covariance * J.transpose();
}

}  // namespace

RelativePose compose(const RelativePose& a, const RelativePose& b) {
  const Pose2 c = lmf::compose(a.x, b.x);
  const Eigen::Matrix3d J1 = J1compose(a.x, b.x);
  const Eigen::Matrix3d J2 = J2compose(a.x, b.x);
  const Eigen::Matrix3d P = J1 * in_parameters(a) * J1.transpose() + J2 * in_parameters(b) * J2.transpose();
  // Back to the right perturbation of c.
  const Eigen::Matrix3d J_inverse = J2compose(c, Pose2()).inverse();
  const Eigen::Matrix3d C = J_inverse * P * J_inverse.transpose();
  return {c, 0.5 * (C + C.transpose())};
}

std::vector<ChainError> chain_errors(const std::vector<std::optional<RelativePose>>& steps,
                                     const std::vector<std::optional<Pose2>>& reference, int n) {
  std::vector<ChainError> out;
  if (n < 1) return out;
  const auto length = static_cast<std::size_t>(n);
  const std::size_t scans = std::min(steps.size(), reference.size());
  for (std::size_t k = 0; k + length < scans; ++k) {
    if (!reference[k] || !reference[k + length]) continue;
    std::optional<RelativePose> chain;
    bool complete = true;
    for (std::size_t i = k + 1; i <= k + length; ++i) {
      if (!steps[i]) {
        complete = false;
        break;
      }
      chain = chain ? compose(*chain, *steps[i]) : *steps[i];
    }
    if (!complete) continue;
    const Pose2 p = between(chain->x, between(*reference[k], *reference[k + length]));
    const Eigen::Vector3d e(p.x, p.y, wrap_angle(p.phi));
    const Eigen::Matrix3d& C = chain->covariance;
    const Eigen::LLT<Eigen::Matrix3d> llt(C);
    if (llt.info() != Eigen::Success || C.diagonal().minCoeff() <= 0.0) continue;  // no NEES without one
    out.push_back({std::hypot(p.x, p.y), std::abs(e(2)), e.dot(llt.solve(e)),
                   e.cwiseProduct(e).cwiseQuotient(C.diagonal())});
  }
  return out;
}

}  // namespace lmf::eval
