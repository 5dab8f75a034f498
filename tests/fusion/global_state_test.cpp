// GlobalState: the lower-triangle, spare-capacity SPmap storage behaves like a
// dense symmetric P under add / remove / replace_perturbation / EKF update.
#include "lmf/fusion/global_state.hpp"

#include <random>

#include <Eigen/Cholesky>
#include <Eigen/Eigenvalues>
#include <gtest/gtest.h>

#include "lmf/fusion/fusion_equations.hpp"
#include "test_support.hpp"

namespace lmf::fusion {
namespace {

using lmf::testing::matrices_near;

Eigen::MatrixXd random_spd(Eigen::Index n, std::mt19937& rng) {
  std::normal_distribution<double> normal(0.0, 1.0);
  Eigen::MatrixXd A(n, n);
  for (Eigen::Index i = 0; i < n; ++i) {
    for (Eigen::Index j = 0; j < n; ++j) A(i, j) = 0.1 * normal(rng);
  }
  return A * A.transpose() + 1e-3 * Eigen::MatrixXd::Identity(n, n);
}

// A state with a frame, two segments under it, a second frame and a robot,
// with a random SPD covariance.
struct Fixture {
  GlobalState state;
  std::vector<EntityId> ids;
  Eigen::MatrixXd P;
  explicit Fixture(std::mt19937& rng) {
    const EntityId F = state.add(EntityKind::kFrame, Pose2(1.0, 2.0, 0.3));
    ids = {F, state.add(EntityKind::kSegment, Pose2(0.5, 0.1, 0.2), F, 2.0),
           state.add(EntityKind::kSegment, Pose2(-1.0, 0.4, 1.2), F, 1.0),
           state.add(EntityKind::kFrame, Pose2(-3.0, 1.0, -2.0)), state.add(EntityKind::kRobot, Pose2(1.0, 0.0, 0.1))};
    ids.push_back(state.add(EntityKind::kSegment, Pose2(0.0, 1.0, 3.0), ids[3], 4.0));
    P = random_spd(state.dimension(), rng);
    P = (0.5 * (P + P.transpose())).eval();  // exactly symmetric: comparisons below are exact
    state.set_marginal(ids, P);
  }
};

TEST(GlobalStateTest, MarginalRoundTripAndBlocks) {
  std::mt19937 rng(1);
  Fixture f(rng);
  EXPECT_EQ(f.state.dimension(), 3 + 2 + 2 + 3 + 3 + 2);
  EXPECT_TRUE(matrices_near(f.state.full_covariance(), f.P, 1e-15));
  // block(a, b) in both orders, and columns().
  EXPECT_TRUE(matrices_near(f.state.block(f.ids[1], f.ids[3]), f.P.block(3, 7, 2, 3), 1e-15));
  EXPECT_TRUE(matrices_near(f.state.block(f.ids[3], f.ids[1]), f.P.block(7, 3, 3, 2), 1e-15));
  EXPECT_TRUE(matrices_near(f.state.columns(f.ids[2]), f.P.middleCols(5, 2), 1e-15));
  EXPECT_TRUE(matrices_near(f.state.marginal({f.ids[4], f.ids[0]}),
                            (Eigen::MatrixXd(6, 6) << f.P.block(10, 10, 3, 3), f.P.block(10, 0, 3, 3),
                             f.P.block(0, 10, 3, 3), f.P.block(0, 0, 3, 3))
                                .finished(),
                            1e-15));
}

TEST(GlobalStateTest, AddKeepsValuesAcrossGrowthAndStartsAtZero) {
  std::mt19937 rng(2);
  Fixture f(rng);
  const Eigen::MatrixXd before = f.state.full_covariance();
  // Many additions force several reallocations of the buffer.
  std::vector<EntityId> added;
  for (int i = 0; i < 200; ++i) added.push_back(f.state.add(EntityKind::kSegment, Pose2(i, 0, 0), f.ids[0], 1.0));
  EXPECT_GE(f.state.capacity(), f.state.dimension());
  const Eigen::MatrixXd after = f.state.full_covariance();
  EXPECT_TRUE(matrices_near(after.topLeftCorner(before.rows(), before.cols()), before, 0.0));
  EXPECT_EQ(after.bottomRows(after.rows() - before.rows()).cwiseAbs().maxCoeff(), 0.0);
  EXPECT_THROW(f.state.add(EntityKind::kSegment, Pose2(), EntityId{9999}), std::invalid_argument);
}

TEST(GlobalStateTest, BatchRemoveMatchesDenseDeletion) {
  std::mt19937 rng(3);
  Fixture f(rng);
  // Remove a middle segment, the robot (and keep the rest), in one batch.
  f.state.remove({f.ids[2], f.ids[4], f.ids[2]});
  std::vector<int> keep;
  for (int i = 0; i < 7; ++i) {
    if (i != 5 && i != 6) keep.push_back(i);
  }
  for (int i = 7; i < 10; ++i) keep.push_back(i);
  keep.push_back(13);
  keep.push_back(14);
  Eigen::MatrixXd expected(keep.size(), keep.size());
  for (std::size_t a = 0; a < keep.size(); ++a) {
    for (std::size_t b = 0; b < keep.size(); ++b) expected(a, b) = f.P(keep[a], keep[b]);
  }
  EXPECT_TRUE(matrices_near(f.state.full_covariance(), expected, 0.0));
  EXPECT_FALSE(f.state.contains(f.ids[2]));
  EXPECT_EQ(f.state.entity(f.ids[5]).offset, 8);
  // A parent cannot go while a child stays; nothing changes then.
  EXPECT_THROW(f.state.remove({f.ids[3]}), std::invalid_argument);
  EXPECT_TRUE(matrices_near(f.state.full_covariance(), expected, 0.0));
  f.state.remove({f.ids[3], f.ids[5]});  // together they may go
  EXPECT_EQ(f.state.dimension(), 5);
  EXPECT_TRUE(matrices_near(f.state.full_covariance(), expected.topLeftCorner(5, 5), 0.0));
}

TEST(GlobalStateTest, ReplacePerturbationIsAPAt) {
  std::mt19937 rng(4);
  Fixture f(rng);
  Eigen::MatrixXd J_self = Eigen::MatrixXd::Random(3, 3);
  Eigen::MatrixXd J_seg = Eigen::MatrixXd::Random(3, 2);
  f.state.replace_perturbation(f.ids[3], {{f.ids[3], J_self}, {f.ids[1], J_seg}});
  Eigen::MatrixXd A = Eigen::MatrixXd::Identity(15, 15);
  A.block(7, 7, 3, 3) = J_self;
  A.block(7, 3, 3, 2) = J_seg;
  EXPECT_TRUE(matrices_near(f.state.full_covariance(), A * f.P * A.transpose(), 1e-14));

  const EntityId copy = f.state.add_copy(f.ids[0]);
  const Eigen::MatrixXd P2 = f.state.full_covariance();
  EXPECT_TRUE(matrices_near(P2.middleRows(f.state.entity(copy).offset, 3), P2.middleRows(0, 3), 1e-15));
  EXPECT_EQ(f.state.entity(copy).parent, std::nullopt);
}

TEST(GlobalStateTest, ReplacePerturbationByItselfOnlyIsAPAt) {
  // The self-only form (a segment's frame shift) reads t's row and column in place.
  std::mt19937 rng(14);
  Fixture f(rng);
  const Eigen::MatrixXd J = Eigen::MatrixXd::Random(2, 2);
  f.state.replace_perturbation(f.ids[2], {{f.ids[2], J}});
  Eigen::MatrixXd A = Eigen::MatrixXd::Identity(15, 15);
  A.block(5, 5, 2, 2) = J;
  EXPECT_TRUE(matrices_near(f.state.full_covariance(), A * f.P * A.transpose(), 1e-14));
}

TEST(GlobalStateTest, TransformPerturbationsIsBlockDiagonalAPAt) {
  std::mt19937 rng(15);
  Fixture f(rng);
  // Listed out of state order: a segment, the last segment, a frame in between.
  const Eigen::MatrixXd J1 = Eigen::MatrixXd::Random(2, 2);
  const Eigen::MatrixXd J5 = Eigen::MatrixXd::Random(2, 2);
  const Eigen::MatrixXd J3 = Eigen::MatrixXd::Random(3, 3);
  f.state.transform_perturbations({{f.ids[5], J5}, {f.ids[1], J1}, {f.ids[3], J3}});
  Eigen::MatrixXd A = Eigen::MatrixXd::Identity(15, 15);
  A.block(3, 3, 2, 2) = J1;
  A.block(7, 7, 3, 3) = J3;
  A.block(13, 13, 2, 2) = J5;
  EXPECT_TRUE(matrices_near(f.state.full_covariance(), A * f.P * A.transpose(), 1e-14));

  const Eigen::MatrixXd before = f.state.full_covariance();
  EXPECT_THROW(f.state.transform_perturbations({{f.ids[1], J1}, {f.ids[1], J1}}), std::invalid_argument);
  EXPECT_THROW(f.state.transform_perturbations({{f.ids[3], J1}}), std::invalid_argument);
  EXPECT_TRUE(matrices_near(f.state.full_covariance(), before, 0.0));  // a rejected call changes nothing
  f.state.transform_perturbations({});
  EXPECT_TRUE(matrices_near(f.state.full_covariance(), before, 0.0));
}

TEST(GlobalStateTest, EkfUpdateMatchesDenseFormulaAndDropsRedundantRows) {
  std::mt19937 rng(5);
  Fixture f(rng);
  const Eigen::MatrixXd P = f.state.full_covariance();
  // Two measurements: segment 1 vs segment 5 (a pairing), and the same one
  // again: the repeated rows must be dropped, the result equal to one copy.
  const spmap::ImplicitMeasurement m = pairing_measurement(f.state, f.ids[1], f.ids[5]);
  Eigen::MatrixXd H = Eigen::MatrixXd::Zero(2, P.rows());
  for (const spmap::JacobianBlock& b : m.blocks) {
    H.middleCols(f.state.entity(b.entity).offset, b.J.cols()) = b.J;
  }
  const Eigen::MatrixXd S = H * P * H.transpose();
  const Eigen::MatrixXd W = P * H.transpose() * S.inverse();
  const Eigen::MatrixXd expected = P - W * H * P;

  GlobalState copy = f.state;
  const spmap::UpdateReport once = spmap::ekf_update(copy, {&m, 1}, spmap::CarefulTolerance{1e-9, 0.0});
  EXPECT_EQ(once.rows, 2);
  EXPECT_EQ(once.rows_dropped, 0);
  EXPECT_TRUE(matrices_near(copy.full_covariance(), expected, 1e-12));

  const std::vector<spmap::ImplicitMeasurement> both = {m, m};
  const spmap::UpdateReport twice = spmap::ekf_update(f.state, both, spmap::CarefulTolerance{1e-9, 0.0});
  EXPECT_EQ(twice.rows, 4);
  EXPECT_EQ(twice.rows_dropped, 2);
  EXPECT_EQ(twice.rows_kept, 2);
  EXPECT_TRUE(matrices_near(f.state.full_covariance(), expected, 1e-12));
  // The estimate moved (p̂ = -W ĥ folded into the locations).
  EXPECT_FALSE(is_near(f.state.entity(f.ids[5]).location, copy.entity(f.ids[5]).location, 0.0, 0.0) &&
               is_near(f.state.entity(f.ids[1]).location, Pose2(0.5, 0.1, 0.2), 0.0, 0.0));
  EXPECT_TRUE(is_near(f.state.entity(f.ids[5]).location, copy.entity(f.ids[5]).location, 1e-9, 1e-9));
  EXPECT_TRUE(matrices_near(spmap::gather_PHt(f.state, {&m, 1}), f.state.full_covariance() * H.transpose(), 1e-12));
}

}  // namespace
}  // namespace lmf::fusion
