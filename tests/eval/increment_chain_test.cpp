#include "lmf/eval/increment_chain.hpp"

#include <random>

#include <Eigen/Cholesky>
#include <gtest/gtest.h>

namespace lmf::eval {
namespace {

Eigen::Matrix3d covariance(double sx, double sy, double sphi, double rho_xphi) {
  Eigen::Matrix3d P = Eigen::Vector3d(sx * sx, sy * sy, sphi * sphi).asDiagonal();
  P(0, 2) = P(2, 0) = rho_xphi * sx * sphi;
  return P;
}

std::mt19937 rng(5);
std::normal_distribution<double> normal;

Pose2 perturbed(const Pose2& x, const Eigen::Matrix3d& P) {
  const Eigen::Matrix3d L = P.llt().matrixL();
  const Eigen::Vector3d p = L * Eigen::Vector3d(normal(rng), normal(rng), normal(rng));
  return lmf::compose(x, Pose2(p(0), p(1), p(2)));
}

// The propagated covariance is that of composed perturbed poses (Monte Carlo,
// 20000 draws: the sample covariance is within ~2 % of the truth).
TEST(IncrementChain, ComposedCovarianceMatchesSampledPoses) {
  const RelativePose a{Pose2(1.0, 0.2, 0.9), covariance(0.03, 0.01, 0.05, 0.5)};
  const RelativePose b{Pose2(2.0, -0.5, 1.2), covariance(0.01, 0.04, 0.02, -0.3)};
  const RelativePose c = compose(a, b);
  EXPECT_TRUE(is_near(c.x, lmf::compose(a.x, b.x), 1e-12, 1e-12));
  constexpr int kDraws = 20000;
  Eigen::Matrix3d sampled = Eigen::Matrix3d::Zero();
  for (int i = 0; i < kDraws; ++i) {
    const Pose2 p = between(c.x, lmf::compose(perturbed(a.x, a.covariance), perturbed(b.x, b.covariance)));
    const Eigen::Vector3d v(p.x, p.y, wrap_angle(p.phi));
    sampled += v * v.transpose() / kDraws;
  }
  for (int r = 0; r < 3; ++r) {
    for (int col = 0; col < 3; ++col) {
      const double scale = std::sqrt(c.covariance(r, r) * c.covariance(col, col));
      EXPECT_NEAR(sampled(r, col), c.covariance(r, col), 0.04 * scale) << r << "," << col;
    }
  }
}

// A reference path of 40 poses, turning as it goes.
std::vector<Pose2> path() {
  std::vector<Pose2> poses = {Pose2()};
  for (int k = 1; k < 40; ++k) poses.push_back(lmf::compose(poses.back(), Pose2(0.5, 0.02, 0.07)));
  return poses;
}

std::vector<std::optional<Pose2>> as_reference(const std::vector<Pose2>& poses) {
  return {poses.begin(), poses.end()};
}

// Steps whose errors are independent with the claimed covariance: chains of
// any length are consistent (mean NEES 3 within the sampling error of 200 runs).
TEST(IncrementChain, IndependentStepErrorsGiveConsistentChains) {
  const std::vector<Pose2> truth = path();
  const Eigen::Matrix3d P = covariance(0.02, 0.01, 0.004, 0.3);
  double sum1 = 0.0, sum10 = 0.0;
  Eigen::Vector3d axis_sum10 = Eigen::Vector3d::Zero();
  int count1 = 0, count10 = 0;
  for (int run = 0; run < 200; ++run) {
    std::vector<std::optional<RelativePose>> steps(truth.size());
    for (std::size_t k = 1; k < truth.size(); ++k) {
      // The true step is the measured one perturbed: truth = x ⊕ p.
      const Pose2 step = between(truth[k - 1], truth[k]);
      const Pose2 measured = lmf::compose(step, inverse(perturbed(Pose2(), P)));
      steps[k] = RelativePose{measured, P};
    }
    for (const ChainError& e : chain_errors(steps, as_reference(truth), 1)) sum1 += e.nees, ++count1;
    for (const ChainError& e : chain_errors(steps, as_reference(truth), 10)) {
      sum10 += e.nees;
      axis_sum10 += e.axis_nees;
      ++count10;
    }
  }
  EXPECT_EQ(count1, 200 * 39);
  EXPECT_EQ(count10, 200 * 30);
  EXPECT_NEAR(sum1 / count1, 3.0, 0.15);
  EXPECT_NEAR(sum10 / count10, 3.0, 0.3);
  // Each axis alone is χ²(1): its mean is 1.
  for (int i = 0; i < 3; ++i) EXPECT_NEAR(axis_sum10(i) / count10, 1.0, 0.15) << i;
}

// A covariance that understates one axis shows in that axis's NEES alone.
TEST(IncrementChain, AnUnderstatedAxisShowsInItsOwnNees) {
  const std::vector<Pose2> truth = path();
  const Eigen::Matrix3d P = covariance(0.02, 0.01, 0.004, 0.0);
  Eigen::Matrix3d claimed = P;
  claimed(2, 2) /= 9.0;  // the heading's σ claimed three times too small
  Eigen::Vector3d axis_sum = Eigen::Vector3d::Zero();
  int count = 0;
  for (int run = 0; run < 200; ++run) {
    std::vector<std::optional<RelativePose>> steps(truth.size());
    for (std::size_t k = 1; k < truth.size(); ++k) {
      const Pose2 measured = lmf::compose(between(truth[k - 1], truth[k]), inverse(perturbed(Pose2(), P)));
      steps[k] = RelativePose{measured, claimed};
    }
    for (const ChainError& e : chain_errors(steps, as_reference(truth), 1)) {
      axis_sum += e.axis_nees;
      ++count;
    }
  }
  EXPECT_NEAR(axis_sum(0) / count, 1.0, 0.1);
  EXPECT_NEAR(axis_sum(1) / count, 1.0, 0.1);
  EXPECT_NEAR(axis_sum(2) / count, 9.0, 0.9);
}

// Steps measured between poses that each carry their own error (x_{k−1,k}
// between x_{k−1} ⊕ ε_{k−1} and x_k ⊕ ε_k) telescope: a chain's error is that
// of its two ends alone, however long it is.
TEST(IncrementChain, AnErrorOfOneScanCancelsAlongTheChain) {
  const std::vector<Pose2> truth = path();
  const Eigen::Matrix3d E = covariance(0.03, 0.03, 0.01, 0.0);
  std::vector<Pose2> seen;
  for (const Pose2& x : truth) seen.push_back(perturbed(x, E));
  std::vector<std::optional<RelativePose>> steps(truth.size());
  for (std::size_t k = 1; k < truth.size(); ++k) {
    steps[k] = RelativePose{between(seen[k - 1], seen[k]), covariance(0.01, 0.01, 0.002, 0.0)};
  }
  const std::vector<ChainError> chains = chain_errors(steps, as_reference(truth), 30);
  ASSERT_EQ(chains.size(), 10u);
  for (std::size_t k = 0; k < chains.size(); ++k) {
    const Pose2 ends_error = between(between(seen[k], seen[k + 30]), between(truth[k], truth[k + 30]));
    EXPECT_NEAR(chains[k].translation_m, std::hypot(ends_error.x, ends_error.y), 1e-9);
    EXPECT_NEAR(chains[k].rotation_rad, std::abs(wrap_angle(ends_error.phi)), 1e-12);
  }
}

// A missing step or reference pose leaves out exactly the chains that need it.
TEST(IncrementChain, GapsLeaveOutTheChainsThatSpanThem) {
  const std::vector<Pose2> truth = path();
  std::vector<std::optional<RelativePose>> steps(truth.size());
  for (std::size_t k = 1; k < truth.size(); ++k) {
    steps[k] = RelativePose{between(truth[k - 1], truth[k]), covariance(0.01, 0.01, 0.002, 0.0)};
  }
  std::vector<std::optional<Pose2>> reference = as_reference(truth);
  EXPECT_EQ(chain_errors(steps, reference, 5).size(), 35u);
  steps[10].reset();  // chains starting at k = 5..9 need step 10
  EXPECT_EQ(chain_errors(steps, reference, 5).size(), 30u);
  reference[20].reset();  // chains from k = 15 and k = 20
  EXPECT_EQ(chain_errors(steps, reference, 5).size(), 28u);
  for (const ChainError& e : chain_errors(steps, reference, 5)) EXPECT_LT(e.nees, 1e-12);
  EXPECT_TRUE(chain_errors(steps, reference, 0).empty());
  EXPECT_TRUE(chain_errors(steps, reference, 40).empty());
}

}  // namespace
}  // namespace lmf::eval
