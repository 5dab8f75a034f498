#include "lmf/spmap/relative_location.hpp"

#include <numbers>

#include <gtest/gtest.h>

#include "lmf/spmap/ekf.hpp"
#include "spmap_test_util.hpp"
#include "test_support.hpp"

namespace lmf::spmap {
namespace {

using lmf::testing::matrices_near;
using lmf::testing::numerical_jacobian;
constexpr double kPi = std::numbers::pi;

// The chain value as a function of all link perturbations stacked in link order.
Eigen::VectorXd chain_at(const std::vector<ChainLink>& links, const Eigen::VectorXd& p) {
  Pose2 value;
  Eigen::Index row = 0;
  for (const ChainLink& link : links) {
    const int d = dof(link.kind);
    Pose2 v = fold(link.location, link.kind, p.segment(row, d));
    if (link.inverted) v = inverse(v);
    value = compose(value, v);
    row += d;
  }
  return value.vector();
}

Eigen::MatrixXd stacked_jacobian(const ChainValue& chain) {
  Eigen::Index cols = 0;
  for (const auto& J : chain.jacobians) cols += J.cols();
  Eigen::MatrixXd out(3, cols);
  Eigen::Index col = 0;
  for (const auto& J : chain.jacobians) {
    out.middleCols(col, J.cols()) = J;
    col += J.cols();
  }
  return out;
}

void expect_chain_jacobians_match(const std::vector<ChainLink>& links) {
  const ChainValue chain = evaluate_chain(links);
  Eigen::Index n = 0;
  for (const ChainLink& link : links) n += dof(link.kind);
  const Eigen::VectorXd zero = Eigen::VectorXd::Zero(n);
  EXPECT_TRUE(is_near(chain.value, Pose2::from_vector(chain_at(links, zero)), 1e-12, 1e-12));
  ASSERT_EQ(chain.jacobians.size(), links.size());
  for (std::size_t l = 0; l < links.size(); ++l) {
    EXPECT_EQ(chain.jacobians[l].rows(), 3);
    EXPECT_EQ(chain.jacobians[l].cols(), dof(links[l].kind));
  }
  const Eigen::MatrixXd numeric = numerical_jacobian(
      [&](const Eigen::VectorXd& p) { return chain_at(links, p); }, zero, test::pose_difference);
  EXPECT_TRUE(matrices_near(stacked_jacobian(chain), numeric, 1e-6));
}

TEST(EvaluateChain, RandomChainsMatchFiniteDifferences) {
  std::mt19937 rng(17);
  std::uniform_real_distribution<double> pos(-5.0, 5.0);
  std::uniform_real_distribution<double> ang(-kPi, kPi);
  std::uniform_int_distribution<int> kind(0, 2);
  std::uniform_int_distribution<int> coin(0, 1);
  std::uniform_int_distribution<int> length(2, 4);
  for (int trial = 0; trial < 200; ++trial) {
    std::vector<ChainLink> links(static_cast<std::size_t>(length(rng)));
    for (ChainLink& link : links) {
      link.location = Pose2(pos(rng), pos(rng), ang(rng));
      link.kind = static_cast<EntityKind>(kind(rng));
      link.inverted = coin(rng) == 1;
    }
    SCOPED_TRACE(trial);
    expect_chain_jacobians_match(links);
  }
}

TEST(EvaluateChain, AnglesNearPi) {
  // Every partial product lands within 1e-4 of ±pi, so finite differences wrap.
  const std::vector<ChainLink> links{
      {Pose2(1.0, -2.0, kPi - 1e-4), EntityKind::kFrame, false, EntityId{1}},
      {Pose2(0.5, 0.7, 2e-4), EntityKind::kSegment, false, EntityId{2}},
      {Pose2(-0.3, 0.2, -kPi + 5e-5), EntityKind::kRobot, true, std::nullopt},
      {Pose2(2.0, 1.0, -kPi + 1e-5), EntityKind::kSegment, true, EntityId{3}},
  };
  expect_chain_jacobians_match(links);
  const std::vector<ChainLink> two{
      {Pose2(0.0, 1.0, kPi), EntityKind::kSegment, true, EntityId{1}},
      {Pose2(3.0, -1.0, -kPi + 1e-6), EntityKind::kRobot, false, EntityId{2}},
  };
  expect_chain_jacobians_match(two);
}

TEST(ChainFromRoot, WalksParentsAndBetweenInverts) {
  StochasticMap map;
  const EntityId F = map.add(EntityKind::kFrame, Pose2(1.0, 2.0, 0.5));
  const EntityId S = map.add(EntityKind::kSegment, Pose2(0.5, 0.0, -0.2), F, 3.0);
  const EntityId L = map.add(EntityKind::kFrame, Pose2(-3.0, 1.0, 2.5));
  const EntityId R = map.add(EntityKind::kRobot, Pose2(1.0, 1.0, 0.3), L);

  const std::vector<ChainLink> chain_s = chain_from_root(map, S);
  ASSERT_EQ(chain_s.size(), 2u);
  EXPECT_EQ(chain_s[0].entity, F);
  EXPECT_EQ(chain_s[1].entity, S);
  EXPECT_FALSE(chain_s[0].inverted);
  EXPECT_TRUE(is_near(evaluate_chain(chain_s).value, map.root_location(S), 1e-12, 1e-12));

  const std::vector<ChainLink> chain_sr = chain_between(map, S, R);
  ASSERT_EQ(chain_sr.size(), 4u);
  EXPECT_EQ(chain_sr[0].entity, S);
  EXPECT_TRUE(chain_sr[0].inverted);
  EXPECT_EQ(chain_sr[1].entity, F);
  EXPECT_TRUE(chain_sr[1].inverted);
  EXPECT_EQ(chain_sr[2].entity, L);
  EXPECT_FALSE(chain_sr[2].inverted);
  const Pose2 x_SR = between(map.root_location(S), map.root_location(R));
  EXPECT_TRUE(is_near(evaluate_chain(chain_sr).value, x_SR, 1e-12, 1e-12));
  expect_chain_jacobians_match(chain_sr);
}

TEST(MeasurementFromChain, RowsTargetBlocksAndNoise) {
  StochasticMap map;
  const EntityId F = map.add(EntityKind::kFrame, Pose2(1.0, 2.0, 3.0));
  const EntityId S1 = map.add(EntityKind::kSegment, Pose2(0.5, 0.0, -0.2), F, 3.0);
  const EntityId S2 = map.add(EntityKind::kSegment, Pose2(2.5, 0.3, 0.1), F, 3.0);
  std::vector<ChainLink> links = chain_between(map, S1, S2);  // F appears twice: its blocks cancel
  // An observation link not in the state, with noise.
  links.push_back({Pose2(0.2, -0.1, kPi - 0.05), EntityKind::kSegment, false, std::nullopt});
  std::mt19937 rng(23);
  const Eigen::MatrixXd R_obs = test::random_spd(2, rng, 0.01);
  std::vector<Eigen::MatrixXd> noise(links.size());
  noise.back() = R_obs;
  const Eigen::Vector2d target(0.05, -kPi + 0.02);

  const ImplicitMeasurement m = measurement_from_chain(links, {1, 2}, noise, target);
  const ChainValue chain = evaluate_chain(links);
  ASSERT_EQ(m.h.size(), 2);
  EXPECT_NEAR(m.h(0), chain.value.y - 0.05, 1e-12);
  EXPECT_NEAR(m.h(1), wrap_angle(chain.value.phi - target(1)), 1e-12);
  EXPECT_LE(std::abs(m.h(1)), kPi);

  ASSERT_EQ(m.blocks.size(), 3u);  // S1, F, S2 once each
  Eigen::MatrixXd B_out(2, 3);
  B_out << 0, 1, 0, 0, 0, 1;
  EXPECT_EQ(m.blocks[0].entity, S1);
  EXPECT_EQ(m.blocks[1].entity, F);
  EXPECT_EQ(m.blocks[2].entity, S2);
  EXPECT_TRUE(matrices_near(m.blocks[1].J, B_out * (chain.jacobians[1] + chain.jacobians[2]), 1e-12));
  EXPECT_TRUE(matrices_near(m.blocks[1].J, Eigen::MatrixXd::Zero(2, 3), 1e-9));  // shared ancestor cancels
  const Eigen::MatrixXd J_obs = B_out * chain.jacobians.back();
  EXPECT_TRUE(matrices_near(m.R, J_obs * R_obs * J_obs.transpose(), 1e-15));

  // No noise given: a perfect constraint.
  EXPECT_TRUE(matrices_near(measurement_from_chain(links, {1, 2}).R, Eigen::MatrixXd::Zero(2, 2), 0.0));
  EXPECT_THROW(measurement_from_chain(links, {3}), std::invalid_argument);
  EXPECT_THROW(measurement_from_chain(links, {1, 2}, {}, Eigen::VectorXd::Zero(3)), std::invalid_argument);
  EXPECT_THROW(measurement_from_chain(links, {1, 2}, {R_obs}), std::invalid_argument);
}

}  // namespace
}  // namespace lmf::spmap
