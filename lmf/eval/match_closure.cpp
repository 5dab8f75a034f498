#include "lmf/eval/match_closure.hpp"

#include <array>

#include <Eigen/Cholesky>

namespace lmf::eval {
namespace {

Eigen::Vector3d residual(const std::array<Pose2, 3>& x) {
  const Pose2 c = between(compose(x[0], x[1]), x[2]);
  return {c.x, c.y, wrap_angle(c.phi)};
}

}  // namespace

Closure closure_of(const RelativePose& ab, const RelativePose& bc, const RelativePose& ac) {
  const std::array<const RelativePose*, 3> poses = {&ab, &bc, &ac};
  const std::array<Pose2, 3> x = {ab.x, bc.x, ac.x};
  Closure out{residual(x), Eigen::Matrix3d::Zero(), 0.0};
  constexpr double kStep = 1e-6;
  for (std::size_t i = 0; i < 3; ++i) {
    Eigen::Matrix3d J;
    for (int d = 0; d < 3; ++d) {
      Eigen::Vector3d p = Eigen::Vector3d::Zero();
      p(d) = kStep;
      std::array<Pose2, 3> plus = x;
      std::array<Pose2, 3> minus = x;
      plus[i] = compose(x[i], Pose2(p(0), p(1), p(2)));
      minus[i] = compose(x[i], Pose2(-p(0), -p(1), -p(2)));
      Eigen::Vector3d diff = residual(plus) - residual(minus);
      diff(2) = wrap_angle(diff(2));
      J.col(d) = diff / (2.0 * kStep);
    }
    out.covariance += J * poses[i]->covariance * J.transpose();
  }
  out.covariance = (0.5 * (out.covariance + out.covariance.transpose())).eval();
  out.nees = out.residual.dot(out.covariance.ldlt().solve(out.residual));
  return out;
}

}  // namespace lmf::eval
