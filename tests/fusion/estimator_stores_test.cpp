// The one estimator (lmf/spmap/estimator.hpp) over both covariance stores: the
// local map's dense StochasticMap and the global map's lower-triangle
// GlobalState, holding the same entities and P, give the same compatibility
// verdicts and the same EKF update. This is what lets both maps share it.
#include <optional>
#include <random>
#include <utility>
#include <vector>

#include <gtest/gtest.h>

#include "lmf/fusion/global_state.hpp"
#include "lmf/spmap/estimator.hpp"
#include "lmf/spmap/relative_location.hpp"
#include "lmf/spmap/stochastic_map.hpp"
#include "test_support.hpp"

namespace lmf {
namespace {

using spmap::EntityId;
using spmap::EntityKind;
using spmap::ImplicitMeasurement;

// A frame with four segments under it and a robot, added in the same order to
// both stores, with one random SPD covariance.
struct TwoStores {
  spmap::StochasticMap local;
  fusion::GlobalState global;
  std::vector<EntityId> local_ids;
  std::vector<EntityId> global_ids;

  explicit TwoStores(std::mt19937& rng) {
    struct Spec {
      EntityKind kind;
      Pose2 location;
      int parent;  // index into the ids, -1 for none
      double length_m;
    };
    const std::vector<Spec> specs = {
        {EntityKind::kFrame, Pose2(0.5, -0.2, 0.1), -1, 0.0},
        {EntityKind::kSegment, Pose2(1.0, 0.0, 0.0), 0, 2.0},
        {EntityKind::kSegment, Pose2(1.05, 0.03, 0.02), 0, 1.5},  // pairs with 1
        {EntityKind::kSegment, Pose2(-1.0, 2.0, 1.57), 0, 3.0},
        {EntityKind::kSegment, Pose2(-0.97, 2.02, 1.56), 0, 2.5},  // pairs with 3
        {EntityKind::kRobot, Pose2(0.2, 0.1, 0.3), -1, 0.0},
    };
    for (const Spec& s : specs) {
      const auto parent = [&](const std::vector<EntityId>& ids) {
        return s.parent < 0 ? std::nullopt : std::optional<EntityId>(ids[static_cast<std::size_t>(s.parent)]);
      };
      local_ids.push_back(local.add(s.kind, s.location, parent(local_ids), s.length_m));
      global_ids.push_back(global.add(s.kind, s.location, parent(global_ids), s.length_m));
    }
    std::normal_distribution<double> normal(0.0, 1.0);
    const Eigen::Index n = local.dimension();
    Eigen::MatrixXd A(n, n);
    for (Eigen::Index i = 0; i < n; ++i) {
      for (Eigen::Index j = 0; j < n; ++j) A(i, j) = 0.02 * normal(rng);
    }
    Eigen::MatrixXd P = A * A.transpose() + 1e-4 * Eigen::MatrixXd::Identity(n, n);
    P = (0.5 * (P + P.transpose())).eval();
    local.mutable_covariance() = P;
    global.set_marginal(global_ids, P);
  }

  // The pairing of segment a with segment b (lateral offset and angle, eq. 5).
  template <class Store>
  static ImplicitMeasurement pairing(const Store& store, const std::vector<EntityId>& ids, int a, int b) {
    return spmap::measurement_from_chain(
        spmap::chain_between(store, ids[static_cast<std::size_t>(a)], ids[static_cast<std::size_t>(b)]), {1, 2});
  }
  std::vector<ImplicitMeasurement> local_pairings(const std::vector<std::pair<int, int>>& pairs) const {
    std::vector<ImplicitMeasurement> out;
    for (const auto& [a, b] : pairs) out.push_back(pairing(local, local_ids, a, b));
    return out;
  }
  std::vector<ImplicitMeasurement> global_pairings(const std::vector<std::pair<int, int>>& pairs) const {
    std::vector<ImplicitMeasurement> out;
    for (const auto& [a, b] : pairs) out.push_back(pairing(global, global_ids, a, b));
    return out;
  }
};

const std::vector<std::pair<int, int>> kPairs = {{1, 2}, {3, 4}, {1, 3}, {2, 4}};  // two right, two wrong

TEST(EstimatorOverStores, CompatibilityVerdictsAgree) {
  std::mt19937 rng(7);
  TwoStores s(rng);
  const auto local = s.local_pairings(kPairs);
  const auto global = s.global_pairings(kPairs);
  const spmap::CarefulTolerance tolerance;
  spmap::Chi2Table chi2(0.05);
  int passed = 0;
  for (std::size_t i = 0; i < kPairs.size(); ++i) {
    const spmap::CompatibilityTest a = spmap::individual_compatibility(s.local, local[i], tolerance, chi2);
    const spmap::CompatibilityTest b = spmap::individual_compatibility(s.global, global[i], tolerance, chi2);
    EXPECT_EQ(a.passed, b.passed) << "pairing " << i;
    EXPECT_EQ(a.dof, b.dof) << "pairing " << i;
    EXPECT_NEAR(a.distance2, b.distance2, 1e-9 * (1.0 + a.distance2)) << "pairing " << i;
    passed += a.passed ? 1 : 0;
  }
  EXPECT_EQ(passed, 2);  // the two right pairings, not the two 2 m off
  const auto kept_local = spmap::incremental_joint_compatibility(s.local, local, tolerance, chi2);
  const auto kept_global = spmap::incremental_joint_compatibility(s.global, global, tolerance, chi2);
  EXPECT_EQ(kept_local, kept_global);
  EXPECT_EQ(kept_local, (std::vector<std::size_t>{0, 1}));
}

TEST(EstimatorOverStores, UpdateAgrees) {
  std::mt19937 rng(11);
  TwoStores s(rng);
  const auto local = s.local_pairings({{1, 2}, {3, 4}});
  const auto global = s.global_pairings({{1, 2}, {3, 4}});
  const spmap::CarefulTolerance tolerance;
  const spmap::UpdateReport a = spmap::ekf_update(s.local, local, tolerance);
  const spmap::UpdateReport b = spmap::ekf_update(s.global, global, tolerance);
  EXPECT_EQ(a.rows, 4);
  EXPECT_EQ(a.rows_kept, b.rows_kept);
  EXPECT_EQ(a.rows_dropped, b.rows_dropped);
  EXPECT_NEAR(a.distance2, b.distance2, 1e-9 * (1.0 + a.distance2));
  EXPECT_TRUE(lmf::testing::matrices_near(Eigen::MatrixXd(s.local.covariance()), s.global.full_covariance(), 1e-12));
  for (std::size_t i = 0; i < s.local_ids.size(); ++i) {
    const Pose2 x_local = s.local.entity(s.local_ids[i]).location;
    const Pose2 x_global = s.global.entity(s.global_ids[i]).location;
    EXPECT_NEAR(x_local.x, x_global.x, 1e-12);
    EXPECT_NEAR(x_local.y, x_global.y, 1e-12);
    EXPECT_NEAR(x_local.phi, x_global.phi, 1e-12);
  }
  // The update pulled the paired segments together (exact but for the linearisation): their ĥ
  // shrank by three orders of magnitude.
  const auto after = s.local_pairings({{1, 2}, {3, 4}});
  for (std::size_t i = 0; i < after.size(); ++i) EXPECT_LT(after[i].h.norm(), 1e-3 * local[i].h.norm());
}

}  // namespace
}  // namespace lmf
