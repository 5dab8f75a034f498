#include "lmf/spmap/stochastic_map.hpp"

#include <numbers>
#include <random>
#include <stdexcept>

#include <gtest/gtest.h>

#include "spmap_test_util.hpp"
#include "test_support.hpp"

namespace lmf::spmap {
namespace {

using lmf::testing::matrices_near;

// Removes rows/cols [off, off + d) from a dense matrix (reference for remove()).
Eigen::MatrixXd without(const Eigen::MatrixXd& P, Eigen::Index off, Eigen::Index d) {
  const Eigen::Index n = P.rows();
  std::vector<Eigen::Index> keep;
  for (Eigen::Index i = 0; i < n; ++i) {
    if (i < off || i >= off + d) keep.push_back(i);
  }
  Eigen::MatrixXd out(static_cast<Eigen::Index>(keep.size()), static_cast<Eigen::Index>(keep.size()));
  for (std::size_t a = 0; a < keep.size(); ++a) {
    for (std::size_t b = 0; b < keep.size(); ++b) {
      out(static_cast<Eigen::Index>(a), static_cast<Eigen::Index>(b)) = P(keep[a], keep[b]);
    }
  }
  return out;
}

TEST(Entity, DofBindingFold) {
  EXPECT_EQ(dof(EntityKind::kRobot), 3);
  EXPECT_EQ(dof(EntityKind::kFrame), 3);
  EXPECT_EQ(dof(EntityKind::kSegment), 2);
  EXPECT_TRUE(matrices_near(binding(EntityKind::kRobot), Eigen::MatrixXd::Identity(3, 3), 0.0));
  Eigen::MatrixXd B_S(2, 3);
  B_S << 0, 1, 0, 0, 0, 1;
  EXPECT_TRUE(matrices_near(binding(EntityKind::kSegment), B_S, 0.0));

  const Pose2 x(1.0, 2.0, 3.1);
  const Pose2 folded = fold(x, EntityKind::kSegment, Eigen::Vector2d(0.1, 0.2));
  EXPECT_TRUE(is_near(folded, compose(x, Pose2(0.0, 0.1, 0.2)), 1e-12, 1e-12));
  EXPECT_GT(folded.phi, -std::numbers::pi);  // wrapped through +pi
  EXPECT_LE(folded.phi, std::numbers::pi);
  EXPECT_TRUE(is_near(fold(x, EntityKind::kRobot, Eigen::Vector3d(0.1, -0.2, 0.3)),
                      compose(x, Pose2(0.1, -0.2, 0.3)), 1e-12, 1e-12));
  EXPECT_THROW(fold(x, EntityKind::kSegment, Eigen::Vector3d::Zero()), std::invalid_argument);
  EXPECT_TRUE(matrices_near(segment_frame_shift(2.5), (Eigen::Matrix2d() << 1, 2.5, 0, 1).finished(), 0.0));
}

TEST(StochasticMap, AddRemoveChildrenRootLocation) {
  StochasticMap map;
  const EntityId F = map.add(EntityKind::kFrame, Pose2(1.0, 2.0, 0.5));
  const EntityId S1 = map.add(EntityKind::kSegment, Pose2(0.5, 0.0, -0.2), F, 3.0);
  const EntityId R = map.add(EntityKind::kRobot, Pose2(-1.0, 0.3, 2.0));
  const EntityId S2 = map.add(EntityKind::kSegment, Pose2(2.0, 1.0, 1.0), F, 1.5);
  EXPECT_EQ(map.dimension(), 10);
  EXPECT_EQ(map.entity(S1).offset, 3);
  EXPECT_EQ(map.entity(R).offset, 5);
  EXPECT_EQ(map.entity(S2).offset, 8);
  EXPECT_DOUBLE_EQ(map.entity(S1).length_m, 3.0);
  EXPECT_TRUE(matrices_near(map.covariance(), Eigen::MatrixXd::Zero(10, 10), 0.0));
  EXPECT_EQ(map.children(F), (std::vector<EntityId>{S1, S2}));
  EXPECT_EQ(map.children(std::nullopt), (std::vector<EntityId>{F, R}));
  EXPECT_TRUE(is_near(map.root_location(S2), compose(Pose2(1.0, 2.0, 0.5), Pose2(2.0, 1.0, 1.0)), 1e-12, 1e-12));
  EXPECT_THROW(map.add(EntityKind::kSegment, Pose2(), EntityId{999}), std::invalid_argument);
  EXPECT_THROW(map.entity(999), std::invalid_argument);

  std::mt19937 rng(3);
  const Eigen::MatrixXd P0 = test::random_spd(10, rng);
  map.mutable_covariance() = P0;
  EXPECT_TRUE(matrices_near(map.block(S1, R), P0.block(3, 5, 2, 3), 0.0));

  EXPECT_THROW(map.remove(F), std::invalid_argument);  // still a parent
  map.remove(S1);
  EXPECT_FALSE(map.contains(S1));
  EXPECT_EQ(map.dimension(), 8);
  EXPECT_EQ(map.entity(R).offset, 3);
  EXPECT_EQ(map.entity(S2).offset, 6);
  EXPECT_TRUE(matrices_near(map.covariance(), without(P0, 3, 2), 0.0));
  EXPECT_TRUE(matrices_near(map.block(S2, R), P0.block(8, 5, 2, 3), 0.0));

  map.remove(S2);  // last entity: nothing trails it
  EXPECT_EQ(map.dimension(), 6);
  EXPECT_TRUE(matrices_near(map.covariance(), without(without(P0, 3, 2), 6, 2), 0.0));
  map.remove(F);  // first entity, now childless
  EXPECT_EQ(map.entity(R).offset, 0);
  EXPECT_TRUE(matrices_near(map.covariance(), P0.block(5, 5, 3, 3), 0.0));
  EXPECT_THROW(map.remove(F), std::invalid_argument);

  const EntityId again = map.add(EntityKind::kSegment, Pose2());
  EXPECT_GT(again, S2);  // ids are never reused
  map.clear();
  EXPECT_EQ(map.dimension(), 0);
  EXPECT_TRUE(map.entities().empty());
}

TEST(StochasticMap, ReplacePerturbationMatchesDenseTransform) {
  std::mt19937 rng(5);
  StochasticMap map;
  const EntityId L = map.add(EntityKind::kFrame, Pose2(0.1, 0.2, 0.3));
  const EntityId S = map.add(EntityKind::kSegment, Pose2(1, 0, 0), std::nullopt, 2.0);
  const EntityId R = map.add(EntityKind::kRobot, Pose2(2, 1, -1));
  const EntityId S2 = map.add(EntityKind::kSegment, Pose2(3, 1, 2), std::nullopt, 1.0);
  const Eigen::MatrixXd P0 = test::random_spd(map.dimension(), rng);
  map.mutable_covariance() = P0;

  // L ← f(L, R): terms include the target itself and an entity listed twice.
  const Eigen::MatrixXd J_L = test::random_matrix(3, 3, rng);
  const Eigen::MatrixXd J_R = test::random_matrix(3, 3, rng);
  const Eigen::MatrixXd J_S2 = test::random_matrix(3, 2, rng);
  map.replace_perturbation(L, {{L, J_L}, {R, J_R}, {S2, J_S2}, {R, J_R}});

  Eigen::MatrixXd A = Eigen::MatrixXd::Identity(10, 10);
  A.block(0, 0, 3, 3) = J_L;
  A.block(0, 5, 3, 3) = 2.0 * J_R;
  A.block(0, 8, 3, 2) = J_S2;
  const Eigen::MatrixXd expected = A * P0 * A.transpose();
  EXPECT_TRUE(matrices_near(map.covariance(), expected, 1e-12));
  EXPECT_TRUE(matrices_near(map.covariance(), map.covariance().transpose(), 0.0));

  EXPECT_THROW(map.replace_perturbation(S, {{R, J_R}}), std::invalid_argument);  // 3x3 for a 2-dof target
  EXPECT_THROW(map.replace_perturbation(S, {{EntityId{77}, Eigen::Matrix2d::Identity()}}), std::invalid_argument);
}

TEST(StochasticMap, AddCopyIsPerfectlyCorrelated) {
  std::mt19937 rng(7);
  StochasticMap map;
  const EntityId F = map.add(EntityKind::kFrame, Pose2(0.1, 0.2, 0.3));
  const EntityId L = map.add(EntityKind::kFrame, Pose2(4, 5, 1));
  const EntityId S = map.add(EntityKind::kSegment, Pose2(1, 0, 0), L, 2.0);
  map.mutable_covariance() = test::random_spd(map.dimension(), rng);
  const Eigen::MatrixXd P0 = map.covariance();

  const EntityId C = map.add_copy(L);
  const Entity& c = map.entity(C);
  EXPECT_EQ(c.kind, EntityKind::kFrame);
  EXPECT_EQ(c.parent, std::nullopt);
  EXPECT_TRUE(is_near(c.location, Pose2(4, 5, 1), 0.0, 0.0));
  EXPECT_EQ(map.dimension(), 11);
  EXPECT_TRUE(matrices_near(map.covariance().topLeftCorner(8, 8), P0, 0.0));
  EXPECT_TRUE(matrices_near(map.block(C, C), map.block(L, L), 1e-15));
  EXPECT_TRUE(matrices_near(map.block(C, L), map.block(L, L), 1e-15));
  EXPECT_TRUE(matrices_near(map.block(C, F), map.block(L, F), 0.0));
  EXPECT_TRUE(matrices_near(map.block(S, C), map.block(S, L), 0.0));

  const EntityId S_copy = map.add_copy(S);
  EXPECT_EQ(map.entity(S_copy).parent, L);
  EXPECT_DOUBLE_EQ(map.entity(S_copy).length_m, 2.0);
}

// The spare-capacity buffer must be invisible: after every addition (zero
// rows), covariance edit and removal (at the front, middle and end), across
// several reallocations, P equals a dense reference built by plain resizing;
// stale values left in the spare part by removals never reappear.
TEST(StochasticMap, SpareCapacityMatchesADenseReference) {
  std::mt19937 rng(11);
  std::uniform_int_distribution<int> coin(0, 2);
  StochasticMap map;
  Eigen::MatrixXd reference(0, 0);
  std::vector<EntityId> ids;
  Eigen::Index reallocations = 0;
  for (int step = 0; step < 120; ++step) {
    const bool remove_one = !ids.empty() && coin(rng) == 0;
    if (remove_one) {
      std::uniform_int_distribution<std::size_t> pick(0, ids.size() - 1);
      const std::size_t k = step % 7 == 0 ? 0 : (step % 5 == 0 ? ids.size() - 1 : pick(rng));
      const Entity e = map.entity(ids[k]);
      map.remove(ids[k]);
      reference = without(reference, e.offset, dof(e.kind));
      ids.erase(ids.begin() + static_cast<std::ptrdiff_t>(k));
    } else {
      const EntityKind kind = coin(rng) == 0 ? EntityKind::kRobot : EntityKind::kSegment;
      const Eigen::Index capacity_before = map.capacity();
      ids.push_back(map.add(kind, Pose2(0.1 * step, 0.0, 0.0)));
      if (map.capacity() != capacity_before) ++reallocations;
      const Eigen::Index n = reference.rows();
      reference.conservativeResize(map.dimension(), map.dimension());
      reference.rightCols(map.dimension() - n).setZero();
      reference.bottomRows(map.dimension() - n).setZero();
      ASSERT_TRUE(matrices_near(map.covariance(), reference, 0.0)) << "new rows not zero at step " << step;
      // Fill P with new values so removals leave non-zero stale data behind.
      const Eigen::MatrixXd P = test::random_spd(map.dimension(), rng);
      map.mutable_covariance() = P;
      reference = P;
    }
    ASSERT_EQ(map.dimension(), reference.rows());
    ASSERT_GE(map.capacity(), map.dimension());
    ASSERT_TRUE(matrices_near(map.covariance(), reference, 0.0)) << "step " << step;
    Eigen::Index offset = 0;
    for (const Entity& e : map.entities()) {
      ASSERT_EQ(e.offset, offset);
      offset += dof(e.kind);
    }
  }
  EXPECT_GE(reallocations, 2);  // the test crossed several growth boundaries

  // An addition after removals sees zero rows, not the stale spare values.
  map.remove(ids.back());
  const EntityId fresh = map.add(EntityKind::kRobot, Pose2());
  EXPECT_TRUE(matrices_near(map.block(fresh, fresh), Eigen::Matrix3d::Zero(), 0.0));
  EXPECT_TRUE(map.covariance().bottomRows(3).isZero(0.0));
  EXPECT_TRUE(map.covariance().rightCols(3).isZero(0.0));

  // A copy is independent and equal; clear keeps the buffer and starts empty.
  const StochasticMap copy = map;
  EXPECT_TRUE(matrices_near(copy.covariance(), map.covariance(), 0.0));
  const Eigen::Index capacity = map.capacity();
  map.clear();
  EXPECT_EQ(map.dimension(), 0);
  EXPECT_EQ(map.capacity(), capacity);
  const EntityId first = map.add(EntityKind::kSegment, Pose2());
  EXPECT_TRUE(matrices_near(map.block(first, first), Eigen::Matrix2d::Zero(), 0.0));
  EXPECT_EQ(copy.dimension(), copy.covariance().rows());
  map.reserve(capacity + 10);
  EXPECT_EQ(map.capacity(), capacity + 10);
  EXPECT_TRUE(matrices_near(map.block(first, first), Eigen::Matrix2d::Zero(), 0.0));
}

}  // namespace
}  // namespace lmf::spmap
