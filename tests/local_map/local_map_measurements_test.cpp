// The local map's equations against finite differences (docs/design.md §3: every
// analytic Jacobian is tested numerically), including angles near ±pi.
#include "lmf/local_map/local_map_measurements.hpp"

#include <cmath>
#include <numbers>
#include <vector>

#include <gtest/gtest.h>

#include "lmf/spmap/entity.hpp"
#include "test_support.hpp"

namespace lmf {
namespace {

using spmap::EntityId;
using spmap::EntityKind;
using testing::matrices_near;
using testing::numerical_jacobian;

constexpr double kPi = std::numbers::pi;

// Difference of two vectors whose entries at `angle_rows` are angles.
auto angle_difference(std::vector<Eigen::Index> angle_rows) {
  return [angle_rows](const Eigen::VectorXd& a, const Eigen::VectorXd& b) {
    Eigen::VectorXd d = a - b;
    for (Eigen::Index r : angle_rows) d(r) = wrap_angle(d(r));
    return Eigen::VectorXd(d);
  };
}

Pose2 plus_segment(const Pose2& x, double dy, double dphi) { return compose(x, Pose2(0.0, dy, dphi)); }
Pose2 plus_full(const Pose2& x, const Eigen::Vector3d& p) { return compose(x, Pose2(p.x(), p.y(), p.z())); }

struct Case {
  Pose2 x_LS;
  Pose2 x_LR;
  Pose2 x_RE;
};

std::vector<Case> cases() {
  return {
      {{1.0, 2.0, 0.3}, {0.5, -0.2, 0.1}, {0.4, 1.6, 0.25}},
      {{-3.0, 1.0, kPi - 1e-3}, {2.0, 4.0, -kPi + 2e-3}, {1.0, -0.5, 0.01}},
      {{0.0, 0.0, kPi / 2.0}, {5.0, -1.0, kPi}, {-2.0, 3.0, -kPi + 1e-4}},
      {{10.0, -7.0, -2.0}, {8.0, -6.0, 1.0}, {3.0, 0.2, kPi - 1e-4}},
  };
}

TEST(PairingMeasurement, ValueAndJacobiansMatchFiniteDifferences) {
  for (const Case& c : cases()) {
    spmap::StochasticMap map;
    const EntityId robot = map.add(EntityKind::kRobot, c.x_LR);
    const EntityId segment = map.add(EntityKind::kSegment, c.x_LS, std::nullopt, 2.0);
    ObservedSegment e;
    e.location = c.x_RE;
    e.length_m = 1.5;
    e.covariance << 4e-4, 1e-5, 1e-5, 9e-5;

    const spmap::ImplicitMeasurement m = local_map::pairing_measurement(map, segment, robot, e);

    // h(p_S, p_R, p_E) = B_S(⊖(x_LS ⊕ Bᵀp_S) ⊕ (x_LR ⊕ p_R) ⊕ (x_RE ⊕ Bᵀp_E)).
    const auto h = [&](const Eigen::VectorXd& p) {
      const Pose2 s = plus_segment(c.x_LS, p(0), p(1));
      const Pose2 r = plus_full(c.x_LR, p.segment<3>(2));
      const Pose2 o = plus_segment(c.x_RE, p(5), p(6));
      const Pose2 v = compose(compose(inverse(s), r), o);
      return Eigen::VectorXd(Eigen::Vector2d(v.y, v.phi));
    };
    const Eigen::VectorXd zero = Eigen::VectorXd::Zero(7);
    ASSERT_TRUE(matrices_near(m.h, h(zero), 1e-12));
    const Eigen::MatrixXd J = numerical_jacobian(h, zero, angle_difference({1}));

    ASSERT_EQ(m.blocks.size(), 2u);
    for (const spmap::JacobianBlock& b : m.blocks) {
      if (b.entity == segment) {
        EXPECT_TRUE(matrices_near(b.J, J.leftCols(2), 1e-6));
      } else {
        ASSERT_EQ(b.entity, robot);
        EXPECT_TRUE(matrices_near(b.J, J.middleCols(2, 3), 1e-6));
      }
    }
    const Eigen::MatrixXd J_E = J.rightCols(2);
    EXPECT_TRUE(matrices_near(m.R, J_E * e.covariance * J_E.transpose(), 1e-9));
  }
}

TEST(PairingMeasurement, FixedSizeFormEqualsTheChainForm) {
  for (const Case& c : cases()) {
    spmap::StochasticMap map;
    const EntityId robot = map.add(EntityKind::kRobot, c.x_LR);
    const EntityId segment = map.add(EntityKind::kSegment, c.x_LS, std::nullopt, 2.0);
    ObservedSegment e;
    e.location = c.x_RE;
    e.length_m = 1.5;
    e.covariance << 4e-4, 1e-5, 1e-5, 9e-5;
    const spmap::ImplicitMeasurement m = local_map::pairing_measurement(map, segment, robot, e);
    const local_map::PairingJacobians pj = local_map::pairing_jacobians(c.x_LS, c.x_LR, c.x_RE);
    EXPECT_TRUE(matrices_near(pj.h, m.h, 1e-12));
    for (const spmap::JacobianBlock& b : m.blocks) {
      EXPECT_TRUE(matrices_near(b.entity == segment ? Eigen::MatrixXd(pj.H_S) : Eigen::MatrixXd(pj.H_R), b.J, 1e-12));
    }
    EXPECT_TRUE(matrices_near(pj.J_E * e.covariance * pj.J_E.transpose(), m.R, 1e-15));
    const Pose2 x_SE = compose(inverse(c.x_LS), compose(c.x_LR, c.x_RE));
    EXPECT_TRUE(is_near(pj.x_SE, x_SE, 1e-12, 1e-12));
    EXPECT_NEAR(pj.cos_SE, std::cos(x_SE.phi), 1e-12);
  }
}

TEST(PairingMeasurement, RejectsWrongEntityKinds) {
  spmap::StochasticMap map;
  const EntityId robot = map.add(EntityKind::kRobot, Pose2());
  const EntityId segment = map.add(EntityKind::kSegment, Pose2(), std::nullopt, 1.0);
  ObservedSegment e;
  e.length_m = 1.0;
  EXPECT_THROW(local_map::pairing_measurement(map, robot, robot, e), std::invalid_argument);
  EXPECT_THROW(local_map::pairing_measurement(map, segment, segment, e), std::invalid_argument);
  EXPECT_THROW(local_map::pairing_measurement(map, segment, 99, e), std::invalid_argument);
}

TEST(PredictionJacobians, MatchFiniteDifferences) {
  const std::vector<std::pair<Pose2, Pose2>> samples = {
      {{0.0, 0.0, 0.0}, {0.5, 0.0, 0.0}},
      {{1.0, -2.0, 0.7}, {0.4, 0.1, -0.3}},
      {{3.0, 2.0, kPi - 1e-3}, {0.6, -0.05, 0.02}},
      {{-1.0, 5.0, -kPi + 1e-3}, {0.0, 0.0, 1.2}},
  };
  for (const auto& [x_LR, u] : samples) {
    const local_map::PredictionJacobians pj = local_map::prediction_jacobians(x_LR, u);
    EXPECT_TRUE(is_near(pj.x_LR, compose(x_LR, u), 1e-12, 1e-12));
    // p_R' = ⊖x̂_LR' ⊕ (x̂_LR ⊕ p_R) ⊕ (û ⊕ p_u).
    const auto f = [&](const Eigen::VectorXd& p) {
      const Pose2 v = compose(inverse(pj.x_LR), compose(plus_full(x_LR, p.head<3>()), plus_full(u, p.tail<3>())));
      return Eigen::VectorXd(v.vector());
    };
    const Eigen::MatrixXd J = numerical_jacobian(f, Eigen::VectorXd::Zero(6), angle_difference({2}));
    EXPECT_TRUE(matrices_near(pj.J_R, J.leftCols(3), 1e-6));
    EXPECT_TRUE(matrices_near(pj.J_u, J.rightCols(3), 1e-6));
  }
}

TEST(AdditionJacobians, MatchFiniteDifferences) {
  for (const Case& c : cases()) {
    const local_map::AdditionJacobians aj = local_map::addition_jacobians(c.x_LR, c.x_RE);
    EXPECT_TRUE(is_near(aj.x_LS, compose(c.x_LR, c.x_RE), 1e-12, 1e-12));
    // p_S = B_S(⊖x̂_LS ⊕ (x̂_LR ⊕ p_R) ⊕ (x_RE ⊕ Bᵀp_E)).
    const auto f = [&](const Eigen::VectorXd& p) {
      const Pose2 v = compose(inverse(aj.x_LS),
                              compose(plus_full(c.x_LR, p.head<3>()), plus_segment(c.x_RE, p(3), p(4))));
      return Eigen::VectorXd(Eigen::Vector2d(v.y, v.phi));
    };
    const Eigen::MatrixXd J = numerical_jacobian(f, Eigen::VectorXd::Zero(5), angle_difference({1}));
    EXPECT_TRUE(matrices_near(aj.J_R, J.leftCols(3), 1e-6));
    EXPECT_TRUE(matrices_near(aj.J_E, J.rightCols(2), 1e-6));
  }
}

TEST(AngularConstraint, ValueAndJacobiansMatchFiniteDifferences) {
  const std::vector<std::tuple<Pose2, Pose2, double>> samples = {
      {{1.0, 2.0, 0.3}, {4.0, 0.0, 0.3 + kPi / 2.0 + 0.01}, kPi / 2.0},
      {{0.0, 0.0, kPi - 1e-3}, {2.0, 1.0, -kPi + 2e-3}, 0.0},
      {{0.0, 0.0, 0.1}, {2.0, 1.0, 0.1 + kPi - 0.02}, kPi},
      {{-3.0, 1.0, -kPi / 2.0}, {0.0, 5.0, -kPi + 0.03}, -kPi / 2.0},
  };
  for (const auto& [x_La, x_Lb, target] : samples) {
    spmap::StochasticMap map;
    const EntityId a = map.add(EntityKind::kSegment, x_La, std::nullopt, 1.0);
    const EntityId b = map.add(EntityKind::kSegment, x_Lb, std::nullopt, 1.0);
    const spmap::ImplicitMeasurement m = local_map::angular_constraint(map, a, b, target);
    const auto f = [&](const Eigen::VectorXd& p) {
      const Pose2 v = compose(inverse(plus_segment(x_La, p(0), p(1))), plus_segment(x_Lb, p(2), p(3)));
      Eigen::VectorXd out(1);
      out(0) = wrap_angle(v.phi - target);
      return out;
    };
    const Eigen::VectorXd zero = Eigen::VectorXd::Zero(4);
    ASSERT_EQ(m.h.size(), 1);
    EXPECT_NEAR(m.h(0), f(zero)(0), 1e-12);
    EXPECT_LT(std::abs(m.h(0)), 0.05);  // wrapped, never a 2pi jump
    EXPECT_TRUE(matrices_near(m.R, Eigen::MatrixXd::Zero(1, 1), 0.0));
    const Eigen::MatrixXd J = numerical_jacobian(f, zero, angle_difference({0}));
    ASSERT_EQ(m.blocks.size(), 2u);
    EXPECT_TRUE(matrices_near(m.blocks[0].entity == a ? m.blocks[0].J : m.blocks[1].J, J.leftCols(2), 1e-6));
    EXPECT_TRUE(matrices_near(m.blocks[0].entity == b ? m.blocks[0].J : m.blocks[1].J, J.rightCols(2), 1e-6));
  }
}

TEST(NearestRightAngle, PicksTheClosestMultipleOfHalfPi) {
  EXPECT_DOUBLE_EQ(local_map::nearest_right_angle(0.1), 0.0);
  EXPECT_DOUBLE_EQ(local_map::nearest_right_angle(-0.1), 0.0);
  EXPECT_DOUBLE_EQ(local_map::nearest_right_angle(kPi / 2.0 - 0.2), kPi / 2.0);
  EXPECT_DOUBLE_EQ(local_map::nearest_right_angle(-kPi / 2.0 + 0.2), -kPi / 2.0);
  EXPECT_DOUBLE_EQ(local_map::nearest_right_angle(kPi - 0.1), kPi);
  EXPECT_DOUBLE_EQ(local_map::nearest_right_angle(-kPi + 0.1), kPi);
  EXPECT_DOUBLE_EQ(local_map::nearest_right_angle(3.0 * kPi / 2.0 + 0.1), -kPi / 2.0);
}

TEST(OdometryNoise, IsProportionalToTheMotionPlusAFloor) {
  LocalMapConfig config;
  config.odom_translation_noise_ratio = 0.08;
  config.odom_rotation_noise_ratio = 0.05;
  config.odom_drift_rad_per_m = 0.01;
  config.odom_noise_floor_m = 0.001;
  config.odom_noise_floor_rad = 0.0005;
  const Eigen::Matrix3d Q = local_map::odometry_noise(Pose2(0.3, 0.4, -0.5), config);
  const double d = 0.5;
  EXPECT_NEAR(Q(0, 0), std::pow(0.08 * d, 2) + 1e-6, 1e-15);
  EXPECT_NEAR(Q(1, 1), std::pow(0.08 * d, 2) + 1e-6, 1e-15);
  EXPECT_NEAR(Q(2, 2), std::pow(0.05 * 0.5 + 0.01 * d, 2) + 0.25e-6, 1e-15);
  EXPECT_EQ(Q(0, 1), 0.0);
  const Eigen::Matrix3d Q0 = local_map::odometry_noise(Pose2(), config);
  EXPECT_NEAR(Q0(0, 0), 1e-6, 1e-18);
  EXPECT_NEAR(Q0(2, 2), 0.25e-6, 1e-18);
}

}  // namespace
}  // namespace lmf
