#include "lmf/geometry/pose2.hpp"

#include <cmath>
#include <limits>
#include <numbers>
#include <vector>

#include <gtest/gtest.h>

#include "test_support.hpp"

namespace lmf {
namespace {

constexpr double kPi = std::numbers::pi;

Eigen::VectorXd pose_difference(const Eigen::VectorXd& a, const Eigen::VectorXd& b) {
  Eigen::VectorXd d = a - b;
  d(2) = wrap_angle(d(2));
  return d;
}

// Poses that exercise every quadrant and angles at and near ±pi.
std::vector<Pose2> sample_poses() {
  return {{0.0, 0.0, 0.0},          {1.0, -2.0, 0.3},       {-3.5, 0.7, -1.2},
          {2.0, 1.0, kPi - 1e-4},   {-1.0, 4.0, -kPi + 1e-4}, {0.5, 0.5, kPi},
          {10.0, -7.0, kPi / 2.0},  {-0.2, 0.1, -kPi / 2.0}};
}

TEST(WrapAngle, MapsIntoHalfOpenInterval) {
  EXPECT_DOUBLE_EQ(wrap_angle(0.0), 0.0);
  EXPECT_DOUBLE_EQ(wrap_angle(kPi), kPi);
  EXPECT_DOUBLE_EQ(wrap_angle(-kPi), kPi);
  EXPECT_NEAR(wrap_angle(3.0 * kPi), kPi, 1e-12);
  EXPECT_NEAR(wrap_angle(2.0 * kPi + 0.1), 0.1, 1e-12);
  EXPECT_NEAR(wrap_angle(-2.0 * kPi - 0.1), -0.1, 1e-12);
  for (double a = -20.0; a < 20.0; a += 0.37) {
    const double w = wrap_angle(a);
    EXPECT_GT(w, -kPi);
    EXPECT_LE(w, kPi);
    EXPECT_NEAR(std::sin(w), std::sin(a), 1e-12);
    EXPECT_NEAR(std::cos(w), std::cos(a), 1e-12);
  }
}

TEST(Pose2, FiniteChecksEveryComponent) {
  EXPECT_TRUE(finite(Pose2(1.0, -2.0, 0.5)));
  const double nan = std::numeric_limits<double>::quiet_NaN();
  const double inf = std::numeric_limits<double>::infinity();
  EXPECT_FALSE(finite(Pose2(nan, 0.0, 0.0)));
  EXPECT_FALSE(finite(Pose2(0.0, inf, 0.0)));
  EXPECT_FALSE(finite(Pose2(0.0, 0.0, -inf)));
}

TEST(Pose2, ComposeMatchesDesignFormula) {
  const Pose2 a(1.0, 2.0, kPi / 2.0);
  const Pose2 b(3.0, 0.5, 0.25);
  const Pose2 c = compose(a, b);
  EXPECT_NEAR(c.x, 1.0 - 0.5, 1e-12);
  EXPECT_NEAR(c.y, 2.0 + 3.0, 1e-12);
  EXPECT_NEAR(c.phi, kPi / 2.0 + 0.25, 1e-12);
}

TEST(Pose2, ComposeWrapsAngle) {
  const Pose2 c = compose({0, 0, 3.0}, {0, 0, 3.0});
  EXPECT_NEAR(c.phi, 6.0 - 2.0 * kPi, 1e-12);
}

TEST(Pose2, InverseUndoesCompose) {
  for (const Pose2& a : sample_poses()) {
    EXPECT_TRUE(is_near(compose(a, inverse(a)), Pose2(), 1e-12, 1e-12));
    EXPECT_TRUE(is_near(compose(inverse(a), a), Pose2(), 1e-12, 1e-12));
    EXPECT_TRUE(is_near(inverse(inverse(a)), a, 1e-12, 1e-12));
  }
}

TEST(Pose2, BetweenGivesRelativeLocation) {
  const Pose2 x_WA(1.0, 1.0, 0.5);
  const Pose2 x_AB(2.0, -1.0, 2.9);
  const Pose2 x_WB = compose(x_WA, x_AB);
  EXPECT_TRUE(is_near(between(x_WA, x_WB), x_AB, 1e-12, 1e-12));
}

TEST(Pose2, TransformPointAgreesWithCompose) {
  const Pose2 a(1.0, -2.0, 0.7);
  const Eigen::Vector2d p(0.3, 4.0);
  const Pose2 c = compose(a, Pose2(p.x(), p.y(), 0.0));
  EXPECT_TRUE(lmf::testing::matrices_near(a.transform_point(p), Eigen::Vector2d(c.x, c.y), 1e-12));
}

TEST(Pose2Jacobians, J1composeMatchesFiniteDifferences) {
  for (const Pose2& a : sample_poses()) {
    for (const Pose2& b : sample_poses()) {
      const auto f = [&](const Eigen::VectorXd& v) -> Eigen::VectorXd {
        return compose(Pose2(v(0), v(1), v(2)), b).vector();
      };
      const Eigen::MatrixXd numeric = lmf::testing::numerical_jacobian(f, a.vector(), pose_difference);
      EXPECT_TRUE(lmf::testing::matrices_near(J1compose(a, b), numeric, 1e-6));
    }
  }
}

TEST(Pose2Jacobians, J2composeMatchesFiniteDifferences) {
  for (const Pose2& a : sample_poses()) {
    for (const Pose2& b : sample_poses()) {
      const auto f = [&](const Eigen::VectorXd& v) -> Eigen::VectorXd {
        return compose(a, Pose2(v(0), v(1), v(2))).vector();
      };
      const Eigen::MatrixXd numeric = lmf::testing::numerical_jacobian(f, b.vector(), pose_difference);
      EXPECT_TRUE(lmf::testing::matrices_near(J2compose(a, b), numeric, 1e-6));
    }
  }
}

TEST(Pose2Jacobians, JinverseMatchesFiniteDifferences) {
  for (const Pose2& a : sample_poses()) {
    const auto f = [](const Eigen::VectorXd& v) -> Eigen::VectorXd {
      return inverse(Pose2(v(0), v(1), v(2))).vector();
    };
    const Eigen::MatrixXd numeric = lmf::testing::numerical_jacobian(f, a.vector(), pose_difference);
    EXPECT_TRUE(lmf::testing::matrices_near(Jinverse(a), numeric, 1e-6));
  }
}

}  // namespace
}  // namespace lmf
