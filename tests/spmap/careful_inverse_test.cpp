#include "lmf/spmap/careful_inverse.hpp"

#include <algorithm>
#include <limits>
#include <random>
#include <stdexcept>

#include <Eigen/Dense>
#include <gtest/gtest.h>

#include "test_support.hpp"

namespace lmf::spmap {
namespace {

using lmf::testing::matrices_near;

Eigen::MatrixXd random_matrix(Eigen::Index rows, Eigen::Index cols, unsigned seed) {
  std::mt19937 rng(seed);
  std::normal_distribution<double> normal(0.0, 1.0);
  Eigen::MatrixXd A(rows, cols);
  for (Eigen::Index i = 0; i < rows; ++i) {
    for (Eigen::Index j = 0; j < cols; ++j) A(i, j) = normal(rng);
  }
  return A;
}

Eigen::MatrixXd submatrix(const Eigen::MatrixXd& S, const std::vector<int>& idx) {
  Eigen::MatrixXd out(static_cast<Eigen::Index>(idx.size()), static_cast<Eigen::Index>(idx.size()));
  for (std::size_t a = 0; a < idx.size(); ++a) {
    for (std::size_t b = 0; b < idx.size(); ++b) {
      out(static_cast<Eigen::Index>(a), static_cast<Eigen::Index>(b)) = S(idx[a], idx[b]);
    }
  }
  return out;
}

// Kept rows invertible (their inverse is the returned one), every dropped row of
// A lies in the span of the kept rows of A (S = A Aᵀ), and the count equals the rank.
void expect_consistent_split(const Eigen::MatrixXd& A, const CarefulInverse& ci, int expected_rank) {
  const Eigen::MatrixXd S = A * A.transpose();
  ASSERT_EQ(static_cast<int>(ci.kept.size()), expected_rank);
  ASSERT_EQ(ci.kept.size() + ci.dropped.size(), static_cast<std::size_t>(S.rows()));
  EXPECT_TRUE(std::is_sorted(ci.kept.begin(), ci.kept.end()));
  EXPECT_TRUE(std::is_sorted(ci.dropped.begin(), ci.dropped.end()));
  const Eigen::MatrixXd S_kk = submatrix(S, ci.kept);
  const Eigen::MatrixXd I = Eigen::MatrixXd::Identity(S_kk.rows(), S_kk.cols());
  EXPECT_TRUE(matrices_near(S_kk * ci.inverse, I, 1e-6));
  Eigen::MatrixXd A_kept(static_cast<Eigen::Index>(ci.kept.size()), A.cols());
  for (std::size_t a = 0; a < ci.kept.size(); ++a) A_kept.row(static_cast<Eigen::Index>(a)) = A.row(ci.kept[a]);
  for (const int d : ci.dropped) {
    // Least-squares residual of row d on the kept rows.
    const Eigen::VectorXd coeffs = A_kept.transpose().colPivHouseholderQr().solve(A.row(d).transpose());
    const double residual = (A_kept.transpose() * coeffs - A.row(d).transpose()).norm();
    EXPECT_LT(residual, 1e-6) << "dropped row " << d << " is not in the span of the kept rows";
  }
}

TEST(CarefulInverse, WellConditionedMatchesEigenInverse) {
  for (unsigned seed = 1; seed <= 5; ++seed) {
    const Eigen::MatrixXd A = random_matrix(6, 6, seed);
    const Eigen::MatrixXd S = A * A.transpose() + 0.5 * Eigen::MatrixXd::Identity(6, 6);
    const CarefulInverse ci = careful_inverse(S);
    ASSERT_EQ(ci.kept.size(), 6u);
    EXPECT_TRUE(ci.dropped.empty());
    EXPECT_TRUE(matrices_near(ci.inverse, S.inverse(), 1e-9));
    EXPECT_DOUBLE_EQ(ci.largest_pivot, S.diagonal().maxCoeff());
    EXPECT_GT(ci.smallest_kept_pivot, 0.0);
  }
}

TEST(CarefulInverse, DuplicatedRowIsDropped) {
  Eigen::MatrixXd A = random_matrix(5, 5, 11);
  A.row(3) = A.row(1);  // row 3 says exactly what row 1 says
  const CarefulInverse ci = careful_inverse(A * A.transpose());
  expect_consistent_split(A, ci, 4);
  ASSERT_EQ(ci.dropped.size(), 1u);
  EXPECT_TRUE(ci.dropped[0] == 1 || ci.dropped[0] == 3);
}

TEST(CarefulInverse, LinearCombinationRowIsDropped) {
  Eigen::MatrixXd A = random_matrix(6, 6, 12);
  A.row(4) = 2.0 * A.row(0) - 0.5 * A.row(2);
  A.row(5) = A.row(1) + A.row(3);
  const CarefulInverse ci = careful_inverse(A * A.transpose());
  expect_consistent_split(A, ci, 4);
}

TEST(CarefulInverse, RedundantRowWithRoundingNoiseIsDropped) {
  Eigen::MatrixXd A = random_matrix(5, 5, 13);
  A.row(2) = A.row(0) - A.row(4) + 1e-14 * random_matrix(1, 5, 14);
  Eigen::MatrixXd S = A * A.transpose();
  S += 1e-14 * random_matrix(5, 5, 15).cwiseAbs();  // slightly asymmetric noise too
  const CarefulInverse ci = careful_inverse(S);
  expect_consistent_split(A, ci, 4);
}

TEST(CarefulInverse, KnownRedundantRowOfScaledMatrix) {
  // Rank-1 direction repeated: rows 0 and 2 both measure the same quantity,
  // row 0 with a larger variance so it is the first pivot; row 2 is dropped.
  Eigen::MatrixXd S(3, 3);
  S << 4.0, 0.1, 4.0,  //
      0.1, 1.0, 0.1,   //
      4.0, 0.1, 4.0;
  const CarefulInverse ci = careful_inverse(S);
  EXPECT_EQ(ci.kept, (std::vector<int>{0, 1}));
  EXPECT_EQ(ci.dropped, (std::vector<int>{2}));
  Eigen::Matrix2d S_kk;
  S_kk << 4.0, 0.1, 0.1, 1.0;
  EXPECT_TRUE(matrices_near(ci.inverse, S_kk.inverse(), 1e-12));
}

TEST(CarefulInverse, ReferenceScaleDropsRoundingNoise) {
  // A well-conditioned but tiny S: kept against itself, dropped against a scale.
  Eigen::Matrix2d S;
  S << 3e-18, 1e-18, 1e-18, 2e-18;
  EXPECT_EQ(careful_inverse(S).kept.size(), 2u);
  EXPECT_TRUE(careful_inverse(S, 1e-9, 1e-2).kept.empty());
  // A real measurement stays: the scale only sets what "small" means.
  Eigen::Matrix2d real;
  real << 3e-4, 1e-4, 1e-4, 2e-4;
  const CarefulInverse ci = careful_inverse(real, 1e-9, 1e-2);
  EXPECT_EQ(ci.kept.size(), 2u);
  EXPECT_TRUE(matrices_near(ci.inverse, Eigen::MatrixXd(real.inverse()), 1e-6));
  EXPECT_THROW(careful_inverse(real, 1e-9, -1.0), std::invalid_argument);
}

TEST(CarefulInverse, ZeroMatrixKeepsNothing) {
  const CarefulInverse ci = careful_inverse(Eigen::MatrixXd::Zero(4, 4));
  EXPECT_TRUE(ci.kept.empty());
  EXPECT_EQ(ci.dropped, (std::vector<int>{0, 1, 2, 3}));
  EXPECT_EQ(ci.inverse.rows(), 0);
}

TEST(CarefulInverse, OneByOne) {
  const CarefulInverse ci = careful_inverse(Eigen::MatrixXd::Constant(1, 1, 0.25));
  ASSERT_EQ(ci.kept, std::vector<int>{0});
  EXPECT_DOUBLE_EQ(ci.inverse(0, 0), 4.0);
  const CarefulInverse zero = careful_inverse(Eigen::MatrixXd::Zero(1, 1));
  EXPECT_TRUE(zero.kept.empty());
  EXPECT_EQ(careful_inverse(Eigen::MatrixXd(0, 0)).kept.size(), 0u);
}

TEST(CarefulInverse, RejectsBadInput) {
  EXPECT_THROW(careful_inverse(Eigen::MatrixXd::Zero(2, 3)), std::invalid_argument);
  Eigen::MatrixXd S = Eigen::MatrixXd::Identity(2, 2);
  S(0, 1) = std::numeric_limits<double>::quiet_NaN();
  EXPECT_THROW(careful_inverse(S), std::invalid_argument);
}

}  // namespace
}  // namespace lmf::spmap
