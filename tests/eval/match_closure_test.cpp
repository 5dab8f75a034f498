#include "lmf/eval/match_closure.hpp"

#include <random>

#include <Eigen/Cholesky>
#include <gtest/gtest.h>

namespace lmf::eval {
namespace {

// C turned by 69° and 2 m from B: the heading's uncertainty moves the
// positions, and the frames' rotation mixes x and y.
const Pose2 kAB(1.0, 0.2, 0.3);
const Pose2 kBC(2.0, -0.5, 1.2);

Eigen::Matrix3d covariance(double sx, double sy, double sphi, double rho_xphi) {
  Eigen::Matrix3d P = Eigen::Vector3d(sx * sx, sy * sy, sphi * sphi).asDiagonal();
  P(0, 2) = P(2, 0) = rho_xphi * sx * sphi;
  return P;
}

TEST(MatchClosure, ThreePosesThatAgreeCloseExactly) {
  const Eigen::Matrix3d P = covariance(0.02, 0.03, 0.01, 0.0);
  const Closure c = closure_of({kAB, P}, {kBC, P}, {compose(kAB, kBC), P});
  EXPECT_LT(c.residual.norm(), 1e-12);
  EXPECT_LT(c.nees, 1e-12);
}

// The residual is x_AC's disagreement seen from the chained pose.
TEST(MatchClosure, AnErrorOfTheDirectPoseIsTheResidual) {
  const Eigen::Matrix3d P = covariance(0.02, 0.03, 0.01, 0.0);
  const Pose2 error(0.1, -0.05, 0.02);
  const Closure c = closure_of({kAB, P}, {kBC, P}, {compose(compose(kAB, kBC), error), P});
  EXPECT_NEAR(c.residual(0), error.x, 1e-12);
  EXPECT_NEAR(c.residual(1), error.y, 1e-12);
  EXPECT_NEAR(c.residual(2), error.phi, 1e-12);
}

// The propagated covariance is that of the residuals of perturbed poses
// (Monte Carlo, 20000 draws: the sample covariance is within ~2 % of the truth).
TEST(MatchClosure, CovarianceMatchesSampledResiduals) {
  const Eigen::Matrix3d P_ab = covariance(0.03, 0.01, 0.05, 0.5);
  const Eigen::Matrix3d P_bc = covariance(0.01, 0.04, 0.02, -0.3);
  const Eigen::Matrix3d P_ac = covariance(0.05, 0.02, 0.015, 0.2);
  const Pose2 ac = compose(kAB, kBC);
  const Closure c = closure_of({kAB, P_ab}, {kBC, P_bc}, {ac, P_ac});

  std::mt19937 rng(11);
  std::normal_distribution<double> normal;
  const auto draw = [&](const Pose2& x, const Eigen::Matrix3d& P) {
    const Eigen::Matrix3d L = P.llt().matrixL();
    const Eigen::Vector3d p = L * Eigen::Vector3d(normal(rng), normal(rng), normal(rng));
    return compose(x, Pose2(p(0), p(1), p(2)));
  };
  constexpr int kDraws = 20000;
  Eigen::Matrix3d sampled = Eigen::Matrix3d::Zero();
  double nees_sum = 0.0;
  for (int i = 0; i < kDraws; ++i) {
    const Pose2 r = between(compose(draw(kAB, P_ab), draw(kBC, P_bc)), draw(ac, P_ac));
    const Eigen::Vector3d v(r.x, r.y, wrap_angle(r.phi));
    sampled += v * v.transpose() / kDraws;
    nees_sum += v.dot(c.covariance.ldlt().solve(v));
  }
  for (int i = 0; i < 3; ++i) {
    EXPECT_NEAR(sampled(i, i), c.covariance(i, i), 0.05 * c.covariance(i, i)) << "axis " << i;
  }
  EXPECT_NEAR(nees_sum / kDraws, 3.0, 0.1);
}

}  // namespace
}  // namespace lmf::eval
