// Every analytic Jacobian of the fusion relations against central differences,
// including angles near ±pi.
#include "lmf/fusion/fusion_equations.hpp"

#include <cmath>
#include <random>

#include <gtest/gtest.h>

#include "test_support.hpp"

namespace lmf::fusion {
namespace {

using lmf::testing::matrices_near;
using lmf::testing::numerical_jacobian;

Pose2 plus(const Pose2& x, EntityKind kind, const Eigen::VectorXd& p) { return spmap::fold(x, kind, p); }

// Difference of two (x, y, phi)-like vectors whose `angle_row` (if >= 0) is wrapped.
auto difference_with_angle(int angle_row) {
  return [angle_row](const Eigen::VectorXd& a, const Eigen::VectorXd& b) {
    Eigen::VectorXd d = a - b;
    if (angle_row >= 0) d(angle_row) = wrap_angle(d(angle_row));
    return d;
  };
}

struct Poses {
  Pose2 x_WF;
  Pose2 x_FSi;
  Pose2 x_WL;
  Pose2 x_LSj;
};

class PairingJacobian : public ::testing::TestWithParam<Poses> {};

TEST_P(PairingJacobian, MatchesFiniteDifferences) {
  const Poses& x = GetParam();
  GlobalState state;
  const EntityId F = state.add(EntityKind::kFrame, x.x_WF);
  const EntityId Si = state.add(EntityKind::kSegment, x.x_FSi, F, 2.0);
  const EntityId L = state.add(EntityKind::kFrame, x.x_WL);
  const EntityId Sj = state.add(EntityKind::kSegment, x.x_LSj, L, 1.0);
  const spmap::ImplicitMeasurement m = pairing_measurement(state, Si, Sj);
  ASSERT_EQ(m.h.size(), 2);
  ASSERT_EQ(m.blocks.size(), 4u);
  EXPECT_TRUE(matrices_near(m.R, Eigen::Matrix2d::Zero(), 0.0));

  // Eq. (12) evaluated directly with perturbations p = (p_Si, p_F, p_L, p_Sj).
  auto h = [&](const Eigen::VectorXd& p) -> Eigen::VectorXd {
    const Pose2 chain = compose(compose(compose(inverse(plus(x.x_FSi, EntityKind::kSegment, p.segment(0, 2))),
                                                inverse(plus(x.x_WF, EntityKind::kFrame, p.segment(2, 3)))),
                                        plus(x.x_WL, EntityKind::kFrame, p.segment(5, 3))),
                                plus(x.x_LSj, EntityKind::kSegment, p.segment(8, 2)));
    return Eigen::Vector2d(chain.y, chain.phi).eval();
  };
  const Eigen::VectorXd zero = Eigen::VectorXd::Zero(10);
  const Eigen::Vector2d h0 = h(zero);
  EXPECT_NEAR(m.h(0), h0(0), 1e-12);
  EXPECT_NEAR(m.h(1), h0(1), 1e-12);

  Eigen::MatrixXd H(2, 10);
  const std::pair<EntityId, int> layout[] = {{Si, 0}, {F, 2}, {L, 5}, {Sj, 8}};
  for (const auto& [id, col] : layout) {
    bool found = false;
    for (const spmap::JacobianBlock& b : m.blocks) {
      if (b.entity == id) {
        H.middleCols(col, b.J.cols()) = b.J;
        found = true;
      }
    }
    ASSERT_TRUE(found) << "no Jacobian block for entity " << id;
  }
  EXPECT_TRUE(matrices_near(H, numerical_jacobian(h, zero, difference_with_angle(1)), 1e-6));
}

INSTANTIATE_TEST_SUITE_P(
    FusionEquations, PairingJacobian,
    ::testing::Values(Poses{Pose2(1.0, -2.0, 0.4), Pose2(3.0, 0.5, -0.7), Pose2(2.0, 1.0, 1.1), Pose2(-1.0, 2.0, 0.3)},
                      // Angles near ±pi, in every link.
                      Poses{Pose2(-4.0, 2.0, 3.1), Pose2(1.0, -0.5, 3.13), Pose2(5.0, 0.0, -3.12),
                            Pose2(0.3, 0.2, -3.1)},
                      Poses{Pose2(0.0, 0.0, 0.0), Pose2(2.0, 0.0, M_PI), Pose2(0.0, 0.0, 0.0),
                            Pose2(2.0, 0.1, -M_PI + 1e-3)}));

TEST(FusionEquationsTest, AdvanceFrameJacobians) {
  for (const auto& [x_WL, x_LR] : {std::pair{Pose2(1.0, 2.0, 0.5), Pose2(3.0, -1.0, 0.8)},
                                   std::pair{Pose2(-2.0, 4.0, 3.1), Pose2(8.0, 2.0, 3.0)},
                                   std::pair{Pose2(), Pose2()}}) {
    const FrameAdvance a = advance_frame(x_WL, x_LR);
    EXPECT_TRUE(is_near(a.x_WL_next, compose(x_WL, x_LR), 1e-12, 1e-12));
    // p_L' = ⊖x̂_WL' ⊕ (x̂_WL ⊕ p_L) ⊕ (x̂_LR ⊕ p_R).
    auto f = [&](const Eigen::VectorXd& p) -> Eigen::VectorXd {
      return compose(inverse(a.x_WL_next), compose(plus(x_WL, EntityKind::kFrame, p.head(3)),
                                                   plus(x_LR, EntityKind::kRobot, p.tail(3))))
          .vector();
    };
    const Eigen::MatrixXd J = numerical_jacobian(f, Eigen::VectorXd::Zero(6), difference_with_angle(2));
    EXPECT_TRUE(matrices_near(a.J_L, J.leftCols(3), 1e-6));
    EXPECT_TRUE(matrices_near(a.J_R, J.rightCols(3), 1e-6));
  }
}

TEST(FusionEquationsTest, PreviousFrameJacobiansAndInverseOfAdvance) {
  for (const auto& [x_next, x_LR] : {std::pair{Pose2(1.0, 2.0, 0.5), Pose2(3.0, -1.0, 0.8)},
                                     std::pair{Pose2(-2.0, 4.0, -3.1), Pose2(8.0, 2.0, 3.0)}}) {
    const PreviousFrame pf = previous_frame(x_next, x_LR);
    EXPECT_TRUE(is_near(compose(pf.x_WL_previous, x_LR), x_next, 1e-12, 1e-12));
    auto f = [&](const Eigen::VectorXd& p) -> Eigen::VectorXd {
      return compose(inverse(pf.x_WL_previous), compose(plus(x_next, EntityKind::kFrame, p.head(3)),
                                                        inverse(plus(x_LR, EntityKind::kRobot, p.tail(3)))))
          .vector();
    };
    const Eigen::MatrixXd J = numerical_jacobian(f, Eigen::VectorXd::Zero(6), difference_with_angle(2));
    EXPECT_TRUE(matrices_near(pf.J_next, J.leftCols(3), 1e-6));
    EXPECT_TRUE(matrices_near(pf.J_R, J.rightCols(3), 1e-6));
    // Advancing the previous frame by the same robot pose gives back the next
    // frame: with p_R only, the two Jacobians compose to the identity map on p_next.
    const FrameAdvance a = advance_frame(pf.x_WL_previous, x_LR);
    EXPECT_TRUE(matrices_near(a.J_L * pf.J_next, Eigen::Matrix3d::Identity(), 1e-9));
    EXPECT_TRUE(matrices_near(a.J_L * pf.J_R + a.J_R, Eigen::Matrix3d::Zero(), 1e-9));
  }
}

TEST(FusionEquationsTest, SightedFrameJacobianAndNoise) {
  RobotSighting s;
  s.x_LA = Pose2(2.0, 1.0, 0.3);
  s.x_AB = Pose2(1.5, -0.5, 2.9);
  s.x_LB = Pose2(0.5, 0.2, -0.4);
  s.cov_LA = Eigen::Vector3d(0.01, 0.02, 0.001).asDiagonal();
  s.cov_AB = Eigen::Vector3d(0.04, 0.03, 0.002).asDiagonal();
  s.cov_AB(0, 1) = s.cov_AB(1, 0) = 0.01;
  s.cov_LB = Eigen::Vector3d(0.005, 0.006, 0.0005).asDiagonal();
  const Pose2 x_WLA(3.0, -1.0, 3.0);
  const SightedFrame sf = sighted_frame(x_WLA, s);
  EXPECT_TRUE(is_near(sf.x_WLB, compose(compose(compose(x_WLA, s.x_LA), s.x_AB), inverse(s.x_LB)), 1e-12, 1e-12));
  auto f = [&](const Eigen::VectorXd& p) -> Eigen::VectorXd {
    const Pose2 chain = compose(compose(compose(plus(x_WLA, EntityKind::kFrame, p.segment(0, 3)),
                                                plus(s.x_LA, EntityKind::kRobot, p.segment(3, 3))),
                                        plus(s.x_AB, EntityKind::kRobot, p.segment(6, 3))),
                                inverse(plus(s.x_LB, EntityKind::kRobot, p.segment(9, 3))));
    return compose(inverse(sf.x_WLB), chain).vector();
  };
  const Eigen::MatrixXd J = numerical_jacobian(f, Eigen::VectorXd::Zero(12), difference_with_angle(2));
  EXPECT_TRUE(matrices_near(sf.J_LA, J.leftCols(3), 1e-6));
  Eigen::MatrixXd noise_cov = Eigen::MatrixXd::Zero(9, 9);
  noise_cov.block(0, 0, 3, 3) = s.cov_LA;
  noise_cov.block(3, 3, 3, 3) = s.cov_AB;
  noise_cov.block(6, 6, 3, 3) = s.cov_LB;
  const Eigen::MatrixXd J_n = J.rightCols(9);
  EXPECT_TRUE(matrices_near(sf.noise, J_n * noise_cov * J_n.transpose(), 1e-8));
}

TEST(FusionEquationsTest, SegmentAndFrameWorldCovariance) {
  GlobalState state;
  const Pose2 x_WF(2.0, 1.0, 2.5);
  const Pose2 x_FS(3.0, -2.0, 0.7);
  const EntityId F = state.add(EntityKind::kFrame, x_WF);
  const EntityId S = state.add(EntityKind::kSegment, x_FS, F, 2.0);
  Eigen::MatrixXd A = Eigen::MatrixXd::Random(5, 5);
  const Eigen::MatrixXd M = 0.01 * A * A.transpose();
  state.set_marginal({F, S}, M);
  const Pose2 x_WS = compose(x_WF, x_FS);
  auto g = [&](const Eigen::VectorXd& p) -> Eigen::VectorXd {
    const Pose2 e = compose(inverse(x_WS), compose(plus(x_WF, EntityKind::kFrame, p.head(3)),
                                                   plus(x_FS, EntityKind::kSegment, p.tail(2))));
    return Eigen::Vector2d(e.y, e.phi).eval();
  };
  const Eigen::MatrixXd J = numerical_jacobian(g, Eigen::VectorXd::Zero(5), difference_with_angle(1));
  EXPECT_TRUE(matrices_near(segment_world_covariance(state, S), J * M * J.transpose(), 1e-8));
  EXPECT_TRUE(matrices_near(frame_world_covariance(state, F), M.topLeftCorner(3, 3), 1e-12));
}

}  // namespace
}  // namespace lmf::fusion
