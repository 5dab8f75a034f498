// The fusion's steps run one at a time on a hand-made state (fusion_steps.hpp):
// one submap F with one wall, a local map L_r next to it.
#include "lmf/fusion/fusion_steps.hpp"

#include <algorithm>
#include <cstdint>
#include <utility>

#include <gtest/gtest.h>

namespace lmf::fusion {
namespace {

struct OneWallScene {
  GlobalMapConfig config;
  GlobalState state;
  EntityId F = 0;
  EntityId wall = 0;
  EntityId L = 0;
  LocalMapSnapshot snapshot;

  // The local segment at `location` (in L), 2 m long; L is 5 cm off F along x.
  explicit OneWallScene(const Pose2& location) {
    config.local_map_covariance_scale = 1.0;
    F = state.add(EntityKind::kFrame, Pose2());
    wall = state.add(EntityKind::kSegment, Pose2(1.0, 0.0, 0.0), F, 2.0);
    state.set_block(wall, wall, 1e-4 * Eigen::Matrix2d::Identity());
    L = state.add(EntityKind::kFrame, Pose2(0.05, 0.0, 0.0));
    state.set_block(L, L, 1e-4 * Eigen::Matrix3d::Identity());
    snapshot.robot_id = 1;
    snapshot.seq = 0;
    snapshot.x_LR = Pose2(2.0, 0.5, 0.0);
    snapshot.segments = {{location, 2.0}};
    snapshot.covariance = 1e-4 * Eigen::MatrixXd::Identity(5, 5);
  }
};

TEST(FusionSteps, TheSameWallPassesEveryPairingStep) {
  OneWallScene scene(Pose2(0.95, 0.01, 0.0));
  FusionContext f(scene.state, scene.config, 1, scene.snapshot, {scene.L, std::nullopt});
  const Eigen::Index before = scene.state.dimension();
  augment(f);
  ASSERT_EQ(f.local.size(), 1u);
  EXPECT_EQ(scene.state.dimension(), before + 5);  // robot (3) and one segment (2)
  EXPECT_EQ(scene.state.entity(f.local[0]).parent, scene.L);
  gate(f);
  EXPECT_EQ(f.report.pairs_considered, 1);
  ASSERT_EQ(f.gated.size(), 1u);
  EXPECT_EQ(f.gated[0].first, scene.wall);
  test_individual_compatibility(f);
  ASSERT_EQ(f.candidates.size(), 1u);
  test_joint_compatibility(f);
  ASSERT_EQ(f.accepted.size(), 1u);
  update_with_pairings(f);
  EXPECT_EQ(f.report.pairings_accepted, 1);
  EXPECT_EQ(f.report.rows_kept, 2);
  // After the update the local segment lies on the wall (a perfect constraint).
  const Pose2 x_wall_local = between(scene.state.root_location(scene.wall), scene.state.root_location(f.local[0]));
  EXPECT_NEAR(x_wall_local.y, 0.0, 1e-9);
  EXPECT_NEAR(x_wall_local.phi, 0.0, 1e-9);
  update_geometry(f);
  EXPECT_EQ(f.report.local_segments_removed, 1);
  ASSERT_EQ(f.removals.size(), 1u);
  EXPECT_EQ(f.removals[0], f.local[0]);
}

TEST(FusionSteps, ThePerpendicularSegmentStopsAtTheGate) {
  OneWallScene scene(Pose2(0.95, 0.01, 1.5707963));
  FusionContext f(scene.state, scene.config, 1, scene.snapshot, {scene.L, std::nullopt});
  augment(f);
  gate(f);
  EXPECT_EQ(f.report.pairs_considered, 1);
  EXPECT_EQ(f.report.gate_rejected, 1);
  EXPECT_TRUE(f.gated.empty());
  test_individual_compatibility(f);
  test_joint_compatibility(f);
  EXPECT_TRUE(f.accepted.empty());
}

TEST(FusionSteps, AnUnpairedSegmentMakesASubmapAndTheFrameAdvances) {
  OneWallScene scene(Pose2(0.95, 0.01, 1.5707963));
  FusionContext f(scene.state, scene.config, 1, scene.snapshot, {scene.L, std::nullopt});
  RobotArrivals arrivals(1.0, 8);
  EnvironmentGraph graph;
  arrivals.join(1, scene.L, 0, scene.state);
  for (auto step : {augment, gate, test_individual_compatibility, test_joint_compatibility, update_with_pairings,
                     update_geometry}) {
    step(f);
  }
  make_new_submap(f, graph);
  ASSERT_TRUE(f.report.new_submap.has_value());
  EXPECT_TRUE(graph.is_submap(*f.report.new_submap));
  EXPECT_EQ(scene.state.entity(f.local[0]).parent, *f.report.new_submap);
  advance_robot_frame(f, arrivals, graph);
  EXPECT_EQ(arrivals.current_frame(1), std::make_pair(std::int64_t{1}, scene.L));
  EXPECT_TRUE(is_near(scene.state.root_location(scene.L), Pose2(2.05, 0.5, 0.0), 1e-12, 1e-12));
  EXPECT_TRUE(arrivals.has_fused(1, 0));
  EXPECT_NE(std::find(f.removals.begin(), f.removals.end(), f.R), f.removals.end());
}

}  // namespace
}  // namespace lmf::fusion
