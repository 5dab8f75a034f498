// GlobalMap: the fusion steps of docs/design.md §5 on constructed local maps.
#include "lmf/fusion/global_map.hpp"

#include <cmath>
#include <limits>
#include <random>

#include <Eigen/Eigenvalues>
#include <gtest/gtest.h>

#include "fusion/synthetic_maps.hpp"
#include "test_support.hpp"

namespace lmf::fusion {
namespace {

using lmf::testing::matrices_near;
using synthetic::Wall;

GlobalMapConfig checked_config() {
  GlobalMapConfig c;
  c.health = HealthCheck::kFullEigen;
  return c;
}

double min_eigenvalue(const GlobalMap& map) {
  const Eigen::MatrixXd P = map.state().full_covariance();
  if (P.rows() == 0) return 0.0;
  return Eigen::SelfAdjointEigenSolver<Eigen::MatrixXd>(P, Eigen::EigenvaluesOnly).eigenvalues().minCoeff();
}

// The map segment matching a true wall: same direction, on its line, overlapping.
const SegmentView* find_segment(const std::vector<SegmentView>& segments, const Wall& wall, double tol_m = 0.05,
                                double tol_rad = 0.02) {
  for (const SegmentView& s : segments) {
    const Pose2 d = between(wall.x_WS, s.x_WS);
    if (std::abs(d.phi) < tol_rad && std::abs(d.y) < tol_m && std::abs(d.x) < 0.5 * wall.length_m) return &s;
  }
  return nullptr;
}

std::vector<Wall> subset(const std::vector<Wall>& walls, std::initializer_list<int> indices) {
  std::vector<Wall> out;
  for (const int i : indices) out.push_back(walls[static_cast<std::size_t>(i)]);
  return out;
}

TEST(GlobalMapTest, FirstLocalMapCreatesASubmapAndMovesTheFrameByTheRobotPose) {
  GlobalMap map(checked_config());
  const std::vector<Wall> walls = synthetic::room(3.0, 0.0, 8.0, 5.0);
  const Pose2 x_LR(2.0, 0.5, 0.3);
  const LocalMapSnapshot s = synthetic::make_snapshot(0, 0, Pose2(), x_LR, walls);
  const std::vector<FusionReport> reports = map.fuse(s);
  ASSERT_EQ(reports.size(), 1u);
  const FusionReport& r = reports[0];
  EXPECT_EQ(r.pairs_considered, 0);
  EXPECT_EQ(r.pairings_accepted, 0);
  EXPECT_EQ(r.new_segments, 4);
  ASSERT_TRUE(r.new_submap.has_value());
  EXPECT_EQ(r.size_after.segments, 4);
  EXPECT_EQ(r.size_after.submaps, 1);
  EXPECT_EQ(r.size_after.robots_joined, 1);
  // Frame L (3) + submap (3) + 4 segments.
  EXPECT_EQ(r.size_after.state_dimension, 3 + 3 + 8);
  for (const SegmentView& seg : map.segments()) EXPECT_EQ(seg.submap, *r.new_submap);

  // docs/design.md §5.6: L_r <- L_r ⊕ x_R; L was exact, so its covariance is the
  // robot's, as the fusion takes it: scaled by local_map_covariance_scale.
  const std::optional<CorrectedFrame> f = map.corrected_frame(0);
  ASSERT_TRUE(f.has_value());
  EXPECT_EQ(f->map_seq, 1);
  EXPECT_TRUE(is_near(f->x_WL, x_LR, 1e-12, 1e-12));
  const double scale = map.config().local_map_covariance_scale;
  EXPECT_EQ(scale, 6.0);
  EXPECT_TRUE(matrices_near(f->covariance, scale * s.covariance.topLeftCorner(3, 3), 1e-12));
  EXPECT_TRUE(r.min_eigenvalue.has_value());
  EXPECT_GE(*r.min_eigenvalue, -1e-12);
  for (const Wall& w : walls) EXPECT_NE(find_segment(map.segments(), w, 1e-9, 1e-9), nullptr);
  EXPECT_FALSE(map.corrected_frame(7).has_value());
}

TEST(GlobalMapTest, ReobservedWallsArePairedAndTheMapDoesNotGrow) {
  GlobalMap map(checked_config());
  const std::vector<Wall> walls = synthetic::room(3.0, 0.0, 8.0, 5.0, 2);
  const Pose2 x_L0R(2.0, 0.5, 0.3);
  map.fuse(synthetic::make_snapshot(0, 0, Pose2(), x_L0R, walls));
  const MapCounts before = map.counts();
  // Second local map from where the first ended, seeing 6 of the 8 walls.
  const std::vector<Wall> seen = subset(walls, {0, 1, 2, 3, 5, 6});
  const std::vector<FusionReport> reports =
      map.fuse(synthetic::make_snapshot(0, 1, x_L0R, Pose2(1.0, -0.5, -0.2), seen));
  ASSERT_EQ(reports.size(), 1u);
  const FusionReport& r = reports[0];
  EXPECT_EQ(r.pairings_accepted, 6);
  EXPECT_EQ(r.jc_rejected, 0);
  EXPECT_EQ(r.new_segments, 0);
  EXPECT_FALSE(r.new_submap.has_value());
  EXPECT_EQ(r.local_segments_removed, 6);
  EXPECT_EQ(r.update_rows, 12);
  EXPECT_EQ(r.size_after.segments, before.segments);
  EXPECT_EQ(r.size_after.submaps, before.submaps);
  EXPECT_EQ(r.size_after.state_dimension, before.state_dimension);
  EXPECT_EQ(r.pairs_considered, 8 * 6);
  EXPECT_EQ(r.gate_rejected + r.chi2_rejected + r.overlap_rejected + r.jc_candidates, r.pairs_considered);
  EXPECT_GE(min_eigenvalue(map), -1e-12);
  // Exact estimates: nothing moves.
  for (const Wall& w : walls) EXPECT_NE(find_segment(map.segments(), w, 1e-9, 1e-9), nullptr);
  EXPECT_TRUE(is_near(map.corrected_frame(0)->x_WL, compose(x_L0R, Pose2(1.0, -0.5, -0.2)), 1e-9, 1e-9));
  // Timing is measured and adds up.
  EXPECT_GT(r.time.total_s, 0.0);
  EXPECT_GE(r.time.total_s + 1e-6, r.time.update_s + r.time.gate_s + r.time.individual_s);
}

// The whole pipeline (augmentation, gather/rank-k update on the lower
// triangle, frame advance, batch removal) against the textbook dense
// computation of docs/design.md §5 on the augmented state.
TEST(GlobalMapTest, FusionEqualsTheDenseAugmentedEkf) {
  GlobalMap map(checked_config());
  const std::vector<Wall> walls = synthetic::room(1.0, 0.5, 7.0, 5.0);
  const Pose2 step(1.5, 0.4, 0.3);
  map.fuse(synthetic::make_snapshot(0, 0, Pose2(), step, walls));
  const LocalMapSnapshot s = synthetic::make_snapshot(0, 1, step, Pose2(0.7, -0.2, 0.4), walls);

  // Dense reference. State order before: L, the 4 segments, their submap F0.
  const GlobalState& state = map.state();
  const Eigen::Index n = state.dimension();
  const EntityId L = state.entities()[0].id;
  std::vector<EntityId> globals;
  for (const Entity& e : state.entities()) {
    if (e.kind == EntityKind::kSegment) globals.push_back(e.id);
  }
  ASSERT_EQ(globals.size(), 4u);
  const Eigen::Index N = n + 3 + 8;
  Eigen::MatrixXd P = Eigen::MatrixXd::Zero(N, N);
  P.topLeftCorner(n, n) = state.full_covariance();  // eq. (4)
  P.bottomRightCorner(11, 11) = map.config().local_map_covariance_scale * s.covariance;
  // H of the 4 pairings (eq. 12), from the same chains in a copy augmented the same way.
  GlobalState augmented = state;
  const EntityId R = augmented.add(EntityKind::kRobot, s.x_LR, L);
  std::vector<EntityId> local;
  for (const SegmentEstimate& seg : s.segments) {
    local.push_back(augmented.add(EntityKind::kSegment, seg.location, L, seg.length_m));
  }
  Eigen::MatrixXd H = Eigen::MatrixXd::Zero(8, N);
  for (int j = 0; j < 4; ++j) {
    const spmap::ImplicitMeasurement m = pairing_measurement(augmented, globals[static_cast<std::size_t>(j)],
                                                             local[static_cast<std::size_t>(j)]);
    for (const spmap::JacobianBlock& b : m.blocks) {
      H.block(2 * j, augmented.entity(b.entity).offset, 2, b.J.cols()) += b.J;
    }
  }
  const Eigen::MatrixXd PHt = P * H.transpose();
  const Eigen::MatrixXd updated = P - PHt * (H * PHt).inverse() * PHt.transpose();  // eq. (9)
  const FrameAdvance adv = advance_frame(state.entity(L).location, s.x_LR);
  Eigen::MatrixXd A = Eigen::MatrixXd::Identity(N, N);
  A.block(0, 0, 3, 3) = adv.J_L;
  A.block(0, augmented.entity(R).offset, 3, 3) = adv.J_R;
  const Eigen::MatrixXd expected = (A * updated * A.transpose()).topLeftCorner(n, n);

  const FusionReport r = map.fuse(s)[0];
  EXPECT_EQ(r.pairings_accepted, 4);
  EXPECT_EQ(r.update_dimension, N);
  EXPECT_EQ(map.state().entities()[1].id, globals[0]);  // order kept
  EXPECT_TRUE(matrices_near(map.state().full_covariance(), expected, 1e-12));
}

TEST(GlobalMapTest, NoisyRevisitsStayConsistentAndShrinkTheUncertainty) {
  GlobalMap map(checked_config());
  std::mt19937 rng(42);
  const std::vector<Wall> walls = synthetic::room(0.0, 0.0, 10.0, 6.0, 2);
  Pose2 x_WL_true;  // where each local map starts, truly
  const Pose2 step(1.0, 0.2, 0.25);
  int paired = 0;
  for (int seq = 0; seq < 8; ++seq) {
    const std::vector<FusionReport> r =
        map.fuse(synthetic::make_snapshot(0, seq, x_WL_true, step, walls, synthetic::Noise{}, &rng));
    ASSERT_EQ(r.size(), 1u);
    paired += r[0].pairings_accepted;
    ASSERT_TRUE(r[0].min_eigenvalue.has_value());
    EXPECT_GE(*r[0].min_eigenvalue, -1e-10) << "seq " << seq;
    x_WL_true = compose(x_WL_true, step);
  }
  // 7 revisits of 8 walls: nearly all pairings found, few duplicates made.
  EXPECT_GE(paired, 7 * 8 - 4);
  EXPECT_LE(map.counts().segments, 8 + 4);
  // The map is close to the truth and the final frame close to the true one.
  for (const Wall& w : walls) EXPECT_NE(find_segment(map.segments(), w, 0.15, 0.05), nullptr);
  const CorrectedFrame f = *map.corrected_frame(0);
  EXPECT_TRUE(is_near(f.x_WL, x_WL_true, 0.5, 0.1));
  // Normalised error of the final frame within a generous chi2(3) bound.
  const Eigen::Vector3d e(f.x_WL.x - x_WL_true.x, f.x_WL.y - x_WL_true.y, wrap_angle(f.x_WL.phi - x_WL_true.phi));
  EXPECT_LT(e.dot(f.covariance.ldlt().solve(e)), 16.3);  // chi2(3) at 0.999
}

TEST(GlobalMapTest, UnpairedSegmentsCreateASubmapLinkedInTheGraph) {
  GlobalMap map(checked_config());
  const std::vector<Wall> room_a = synthetic::room(0.0, 0.0, 6.0, 4.0);
  const std::vector<Wall> room_b = synthetic::room(8.0, 0.0, 6.0, 4.0);
  const Pose2 x_LR(4.0, 0.0, 0.0);
  const FusionReport first = map.fuse(synthetic::make_snapshot(0, 0, Pose2(), x_LR, room_a))[0];
  // The second local map sees the right wall of room A and all of room B.
  std::vector<Wall> seen{room_a[1]};
  seen.insert(seen.end(), room_b.begin(), room_b.end());
  const FusionReport second = map.fuse(synthetic::make_snapshot(0, 1, x_LR, Pose2(3.0, 0.0, 0.0), seen))[0];
  EXPECT_EQ(second.pairings_accepted, 1);
  EXPECT_EQ(second.new_segments, 4);
  ASSERT_TRUE(second.new_submap.has_value());
  EXPECT_EQ(second.size_after.segments, 8);
  EXPECT_EQ(second.size_after.submaps, 2);
  int in_new = 0;
  for (const SegmentView& s : map.segments()) in_new += s.submap == *second.new_submap ? 1 : 0;
  EXPECT_EQ(in_new, 4);
  // The new submap is a copy of L at the start of map 1 (x_WF = x_LR of map 0).
  const std::vector<SubmapView> submaps = map.submaps();
  ASSERT_EQ(submaps.size(), 2u);
  EXPECT_TRUE(is_near(submaps[1].x_WF, x_LR, 1e-9, 1e-9));
  EXPECT_EQ(submaps[1].seq, 1);
  // One graph edge between the two submaps (consecutive and paired).
  const std::vector<GraphEdge> edges = map.graph_edges();
  ASSERT_EQ(edges.size(), 1u);
  EXPECT_EQ(std::min(edges[0].a, edges[0].b), *first.new_submap);
  EXPECT_EQ(std::max(edges[0].a, edges[0].b), *second.new_submap);
  EXPECT_GE(min_eigenvalue(map), -1e-12);
}

TEST(GlobalMapTest, GlobalSegmentsMatchingOneLocalSegmentAreFused) {
  GlobalMap map(checked_config());
  // The first local map sees each wall as two pieces; the second sees whole walls.
  const std::vector<Wall> pieces = synthetic::room(0.0, 0.0, 8.0, 6.0, 2, 0.3);
  const std::vector<Wall> whole = synthetic::room(0.0, 0.0, 8.0, 6.0, 1);
  const Pose2 x_LR(0.5, 0.5, 0.1);
  map.fuse(synthetic::make_snapshot(0, 0, Pose2(), x_LR, pieces));
  ASSERT_EQ(map.counts().segments, 8);
  const FusionReport r = map.fuse(synthetic::make_snapshot(0, 1, x_LR, Pose2(0.2, 0.0, 0.0), whole))[0];
  EXPECT_EQ(r.pairings_accepted, 8);
  EXPECT_EQ(r.global_segments_fused, 4);
  EXPECT_EQ(r.size_after.segments, 4);
  const std::vector<SegmentView> segments = map.segments();
  for (const Wall& w : whole) {
    const SegmentView* s = find_segment(segments, w, 1e-6, 1e-6);
    ASSERT_NE(s, nullptr);
    EXPECT_NEAR(s->length_m, w.length_m, 1e-6);  // extended over the gap and the whole wall
    EXPECT_NEAR(between(w.x_WS, s->x_WS).x, 0.0, 1e-6);
  }
  EXPECT_GE(min_eigenvalue(map), -1e-12);
}

// A snapshot of a robot and two walls whose covariance makes φ1 − φ2 exact (a
// perfect shape constraint, docs/design.md §4.9): both angles follow the robot heading
// and one shared angle error.
LocalMapSnapshot with_exact_relative_angle(const LocalMapSnapshot& base) {
  LocalMapSnapshot s = base;
  Eigen::MatrixXd A = Eigen::MatrixXd::Zero(7, 6);
  A(0, 0) = 0.05;
  A(1, 1) = 0.05;
  A(2, 2) = 0.01;
  A(3, 3) = 0.01;             // lateral of wall 1
  A(5, 4) = 0.01;             // lateral of wall 2
  A(4, 2) = A(6, 2) = 0.005;  // both angles follow the robot heading...
  A(4, 5) = A(6, 5) = 0.004;  // ...and one shared angle error: φ1 − φ2 is exact
  s.covariance = A * A.transpose();
  return s;
}

// Two parallel walls whose relative angle is perfectly known in the local map
// (a perfect shape constraint, docs/design.md §4.9) and therefore also in the global
// map built from it: two pairings repeat that relation, S is singular, and the
// careful inversion must drop one row (paper §III.B).
TEST(GlobalMapTest, CarefulInversionDropsTheRowOfARepeatedPerfectRelation) {
  const std::vector<Wall> walls{{Pose2(3.0, -2.0, 0.0), 6.0}, {Pose2(3.0, 2.0, 0.0), 6.0}};
  const auto constrained = with_exact_relative_angle;
  GlobalMapConfig config = checked_config();
  GlobalMap map(config);
  const Pose2 x_LR(1.0, 0.3, 0.05);
  map.fuse(constrained(synthetic::make_snapshot(0, 0, Pose2(), x_LR, walls)));
  // The global map inherits the perfect relation: Var(φ1 − φ2) = 0.
  const std::vector<SegmentView> segs = map.segments();
  ASSERT_EQ(segs.size(), 2u);
  const Eigen::MatrixXd M = map.state().marginal({segs[0].id, segs[1].id});
  EXPECT_NEAR(M(1, 1) + M(3, 3) - 2 * M(1, 3), 0.0, 1e-15);

  const FusionReport r = map.fuse(constrained(synthetic::make_snapshot(0, 1, x_LR, Pose2(0.5, 0.0, 0.0), walls)))[0];
  EXPECT_EQ(r.pairings_accepted, 2);
  EXPECT_EQ(r.update_rows, 4);
  EXPECT_EQ(r.rows_dropped, 1);
  EXPECT_EQ(r.rows_kept, 3);
  ASSERT_TRUE(r.min_eigenvalue.has_value());
  EXPECT_GE(*r.min_eigenvalue, -1e-12);
  EXPECT_EQ(map.counts().segments, 2);
}

// The same perfect relation, contradicted: the second local map holds the two
// walls 0.05 rad apart, also exactly. Each pairing alone passes (the frame's
// heading is uncertain), but given the first, the second's angle row is
// determined and its innovation is 0.05 rad: the joint test must reject it, not
// drop the row and accept the pairing (which once let a 90° wrong pairing in).
TEST(GlobalMapTest, APairingContradictingAnExactRelationIsRejected) {
  const std::vector<Wall> walls{{Pose2(3.0, -2.0, 0.0), 6.0}, {Pose2(3.0, 2.0, 0.0), 6.0}};
  const auto constrained = with_exact_relative_angle;
  GlobalMap map(checked_config());
  const Pose2 x_LR(1.0, 0.3, 0.05);
  map.fuse(constrained(synthetic::make_snapshot(0, 0, Pose2(), x_LR, walls)));
  std::vector<Wall> skewed = walls;
  skewed[1].x_WS.phi = 0.05;
  const FusionReport r =
      map.fuse(constrained(synthetic::make_snapshot(0, 1, x_LR, Pose2(0.5, 0.0, 0.0), skewed)))[0];
  EXPECT_EQ(r.jc_candidates, 2);  // both pass the individual test
  EXPECT_EQ(r.pairings_accepted, 1);
  EXPECT_EQ(r.jc_rejected, 1);
  ASSERT_TRUE(r.min_eigenvalue.has_value());
  EXPECT_GE(*r.min_eigenvalue, -1e-12);
  EXPECT_LT(r.update_distance2, 20.0);
}

// The health verdict: the eigenvalue decides when the check computed one (a
// rank-deficient PSD block can show a large negative LDLT pivot), else the pivot.
TEST(FusionReportTest, CovarianceVerdictPrefersTheEigenvalue) {
  FusionReport r;
  EXPECT_TRUE(r.covariance_ok());  // nothing checked
  r.min_ldlt_pivot = -1.7e-7;
  EXPECT_FALSE(r.covariance_ok());
  r.min_eigenvalue = -8e-15;
  EXPECT_TRUE(r.covariance_ok());
  r.min_eigenvalue = -2e-9;
  EXPECT_FALSE(r.covariance_ok());
  r.min_ldlt_pivot = 1e-3;
  EXPECT_FALSE(r.covariance_ok());
}

TEST(GlobalMapTest, RobotJoinsBySightingAndItsWaitingMapsAreFusedInOrder) {
  GlobalMap map(checked_config());
  const std::vector<Wall> walls = synthetic::room(0.0, 0.0, 12.0, 8.0, 2);
  // Robot 0 maps from the origin.
  const Pose2 step0(1.0, 0.0, 0.1);
  map.fuse(synthetic::make_snapshot(0, 0, Pose2(), step0, walls));
  // Robot 1 starts elsewhere; two local maps reach the server before anyone sees it.
  const Pose2 x_WL1_0(-3.0, 2.0, -1.0);
  const Pose2 step1(0.8, 0.3, 0.2);
  const Pose2 x_WL1_1 = compose(x_WL1_0, step1);
  const Pose2 x_WL1_2 = compose(x_WL1_1, step1);
  EXPECT_TRUE(map.fuse(synthetic::make_snapshot(1, 0, x_WL1_0, step1, subset(walls, {0, 1, 7})))
                  .empty());
  EXPECT_TRUE(map.fuse(synthetic::make_snapshot(1, 1, x_WL1_1, step1, subset(walls, {0, 6, 7}))).empty());
  EXPECT_FALSE(map.is_joined(1));
  EXPECT_EQ(map.queued_count(), 2);
  EXPECT_FALSE(map.corrected_frame(1).has_value());

  // During its local map 2, robot 1 is seen by robot 0 (in its local map 1).
  RobotSighting s;
  s.observer_id = 0;
  s.observed_id = 1;
  s.observer_seq = 1;
  s.x_LA = Pose2(0.5, 0.0, 0.0);
  s.observed_seq = 2;
  s.x_LB = Pose2(0.3, 0.1, 0.05);
  const Pose2 x_WA = compose(step0, s.x_LA);
  const Pose2 x_WB = compose(x_WL1_2, s.x_LB);
  s.x_AB = between(x_WA, x_WB);
  s.cov_AB = Eigen::Vector3d(0.01, 0.01, 0.001).asDiagonal();
  const SightingResult result = map.add_sighting(s);
  EXPECT_EQ(result.status, SightingStatus::kJoined);
  ASSERT_EQ(result.fused.size(), 2u);
  EXPECT_EQ(result.fused[0].seq, 0);
  EXPECT_EQ(result.fused[1].seq, 1);
  EXPECT_TRUE(result.fused[0].anchored_backward);
  EXPECT_EQ(result.fused[0].pairings_accepted, 3);  // walls 0, 1, 7 are robot 0's
  EXPECT_EQ(result.fused[1].pairings_accepted, 3);
  EXPECT_EQ(map.queued_count(), 0);
  EXPECT_TRUE(map.is_joined(1));
  EXPECT_TRUE(map.has_fused(1, 0));
  EXPECT_TRUE(map.has_fused(1, 1));

  const CorrectedFrame f = *map.corrected_frame(1);
  EXPECT_EQ(f.map_seq, 2);
  EXPECT_TRUE(is_near(f.x_WL, x_WL1_2, 1e-6, 1e-6));
  EXPECT_EQ(map.counts().segments, 8);  // nothing duplicated
  EXPECT_GE(min_eigenvalue(map), -1e-12);

  // The next local map of robot 1 fuses right away, forward.
  const std::vector<FusionReport> next = map.fuse(synthetic::make_snapshot(1, 2, x_WL1_2, step1, walls));
  ASSERT_EQ(next.size(), 1u);
  EXPECT_FALSE(next[0].anchored_backward);
  EXPECT_EQ(next[0].pairings_accepted, 8);
  // A second sighting of a joined robot changes nothing.
  EXPECT_EQ(map.add_sighting(s).status, SightingStatus::kIgnored);
}

TEST(GlobalMapTest, SightingWaitsForItsObserver) {
  GlobalMap map(checked_config());
  const std::vector<Wall> walls = synthetic::room(0.0, 0.0, 8.0, 6.0);
  map.fuse(synthetic::make_snapshot(0, 0, Pose2(), Pose2(1.0, 0.0, 0.0), walls));
  // Robot 2 saw robot 3 before robot 2 joined: pending until robot 2 joins.
  RobotSighting s;
  s.observer_id = 2;
  s.observed_id = 3;
  s.x_AB = Pose2(1.0, 0.0, 0.0);
  EXPECT_EQ(map.add_sighting(s).status, SightingStatus::kPending);
  map.fuse(synthetic::make_snapshot(3, 0, Pose2(2.0, 1.0, 0.0), Pose2(0.5, 0.0, 0.0), walls));
  EXPECT_EQ(map.queued_count(), 1);
  const std::vector<FusionReport> joined = map.join_robot(2, Pose2(1.0, 1.0, 0.0));
  EXPECT_EQ(joined.size(), 1u);  // robot 3's map, unblocked through the pending sighting
  EXPECT_TRUE(map.is_joined(3));
  EXPECT_EQ(map.queued_count(), 0);
  EXPECT_TRUE(is_near(map.corrected_frame(3)->x_WL, Pose2(2.5, 1.0, 0.0), 1e-9, 1e-9));
  EXPECT_THROW(map.join_robot(2, Pose2()), std::invalid_argument);
}

TEST(GlobalMapTest, LateSightingsUseTheSubmapCopyOrTheFrameHistory) {
  GlobalMap map(checked_config());
  const std::vector<Wall> walls = synthetic::room(0.0, 0.0, 8.0, 6.0);
  const Pose2 step(1.0, 0.5, 0.2);
  // Robot 0: map 0 makes a submap (a copy of its frame 0); maps 1 and 2 only
  // re-observe, so frame 1 survives only in the history.
  Pose2 x_WL;
  for (int seq = 0; seq < 3; ++seq) {
    map.fuse(synthetic::make_snapshot(0, seq, x_WL, step, walls));
    x_WL = compose(x_WL, step);
  }
  EXPECT_EQ(map.counts().submaps, 1);
  auto sighting = [&](int observed, std::int64_t observer_seq, const Pose2& x_WLA) {
    RobotSighting s;
    s.observer_id = 0;
    s.observed_id = observed;
    s.observer_seq = observer_seq;
    s.x_LA = Pose2(0.2, 0.0, 0.0);
    s.x_AB = Pose2(1.0, 0.5, 0.3);
    s.cov_AB = Eigen::Vector3d(0.01, 0.01, 0.001).asDiagonal();
    const SightingResult r = map.add_sighting(s);
    const Pose2 expected = compose(compose(x_WLA, s.x_LA), s.x_AB);  // x_LB = 0: B's frame is B
    EXPECT_TRUE(is_near(map.corrected_frame(observed)->x_WL, expected, 1e-9, 1e-9));
    return r.status;
  };
  EXPECT_EQ(sighting(1, 0, Pose2()), SightingStatus::kJoined);                // the submap of map 0
  EXPECT_EQ(sighting(2, 1, step), SightingStatus::kJoinedApproximately);     // history
  EXPECT_EQ(sighting(3, 3, x_WL), SightingStatus::kJoined);                  // the current frame
  EXPECT_GE(min_eigenvalue(map), -1e-12);
  // A sighting of the future (observer not there yet) waits.
  RobotSighting future;
  future.observer_id = 0;
  future.observed_id = 4;
  future.observer_seq = 7;
  EXPECT_EQ(map.add_sighting(future).status, SightingStatus::kPending);
  EXPECT_FALSE(map.is_joined(4));
}

TEST(GlobalMapTest, AnEmptyLocalMapOnlyMovesTheFrame) {
  GlobalMap map(checked_config());
  map.fuse(synthetic::make_snapshot(0, 0, Pose2(), Pose2(1.0, 0.0, 0.1), synthetic::room(0.0, 0.0, 6.0, 4.0)));
  const MapCounts before = map.counts();
  const LocalMapSnapshot empty = synthetic::make_snapshot(0, 1, Pose2(1.0, 0.0, 0.1), Pose2(2.0, 0.0, 0.0), {});
  ASSERT_EQ(empty.covariance.rows(), 3);
  const FusionReport r = map.fuse(empty)[0];
  EXPECT_EQ(r.pairs_considered, 0);
  EXPECT_FALSE(r.new_submap.has_value());
  EXPECT_EQ(r.size_after.state_dimension, before.state_dimension);
  EXPECT_TRUE(is_near(map.corrected_frame(0)->x_WL, compose(Pose2(1.0, 0.0, 0.1), Pose2(2.0, 0.0, 0.0)), 1e-12,
                      1e-12));
}

TEST(GlobalMapTest, LateLocalMapsAreAnchoredBackwards) {
  GlobalMap map(checked_config());
  const std::vector<Wall> walls = synthetic::room(0.0, 0.0, 10.0, 8.0, 2);
  const Pose2 step(1.0, 0.5, 0.3);
  std::vector<Pose2> x_WL{Pose2(-2.0, -1.0, 0.2)};
  for (int i = 0; i < 4; ++i) x_WL.push_back(compose(x_WL.back(), step));
  // The robot joins at its local map 2; maps 2 and 3 arrive first, then 1, then 0.
  map.join_robot(5, x_WL[2], Eigen::Matrix3d::Zero(), 2);
  map.fuse(synthetic::make_snapshot(5, 2, x_WL[2], step, subset(walls, {0, 1, 2})));
  map.fuse(synthetic::make_snapshot(5, 3, x_WL[3], step, subset(walls, {2, 3, 4})));
  const std::vector<FusionReport> late1 =
      map.fuse(synthetic::make_snapshot(5, 1, x_WL[1], step, subset(walls, {4, 5, 6})));
  ASSERT_EQ(late1.size(), 1u);
  EXPECT_TRUE(late1[0].anchored_backward);
  EXPECT_EQ(late1[0].pairings_accepted, 1);
  EXPECT_EQ(late1[0].new_segments, 2);
  const std::vector<FusionReport> late0 =
      map.fuse(synthetic::make_snapshot(5, 0, x_WL[0], step, subset(walls, {6, 7, 0})));
  ASSERT_EQ(late0.size(), 1u);
  EXPECT_EQ(late0[0].pairings_accepted, 2);
  EXPECT_EQ(map.counts().segments, 8);
  for (const Wall& w : walls) EXPECT_NE(find_segment(map.segments(), w, 1e-6, 1e-6), nullptr);
  EXPECT_EQ(map.corrected_frame(5)->map_seq, 4);
  EXPECT_TRUE(is_near(map.corrected_frame(5)->x_WL, x_WL[4], 1e-9, 1e-9));
  EXPECT_THROW(map.fuse(synthetic::make_snapshot(5, 1, x_WL[1], step, walls)), std::invalid_argument);
  EXPECT_GE(min_eigenvalue(map), -1e-12);
  // Frames no longer needed were removed: L (3) + submaps (3 each) + 8 segments.
  EXPECT_EQ(map.state().dimension(), 3 + 3 * map.counts().submaps + 16);
}

TEST(GlobalMapTest, OutOfOrderMapsWaitForTheMissingOne) {
  GlobalMap map(checked_config());
  const std::vector<Wall> walls = synthetic::room(0.0, 0.0, 8.0, 6.0);
  const Pose2 step(1.0, 0.0, 0.0);
  map.fuse(synthetic::make_snapshot(0, 0, Pose2(), step, walls));
  EXPECT_TRUE(map.fuse(synthetic::make_snapshot(0, 2, compose(step, step), step, walls)).empty());
  EXPECT_TRUE(map.is_queued(0, 2));
  const std::vector<FusionReport> both = map.fuse(synthetic::make_snapshot(0, 1, step, step, walls));
  ASSERT_EQ(both.size(), 2u);
  EXPECT_EQ(both[0].seq, 1);
  EXPECT_EQ(both[1].seq, 2);
  EXPECT_EQ(map.corrected_frame(0)->map_seq, 3);
}

TEST(GlobalMapTest, InvalidSnapshotsAreRejectedAndTheMapIsUnchanged) {
  GlobalMap map(checked_config());
  const std::vector<Wall> walls = synthetic::room(0.0, 0.0, 8.0, 6.0);
  const Pose2 step(1.0, 0.0, 0.1);
  map.fuse(synthetic::make_snapshot(0, 0, Pose2(), step, walls));
  const LocalMapSnapshot good = synthetic::make_snapshot(0, 1, step, step, walls);
  const double nan = std::numeric_limits<double>::quiet_NaN();

  using Reason = InvalidInput::Reason;
  struct Bad {
    std::string name;
    Reason reason;
    LocalMapSnapshot snapshot;
  };
  std::vector<Bad> bad;
  auto variant = [&](const std::string& name, Reason reason, auto&& edit) {
    LocalMapSnapshot s = good;
    edit(s);
    bad.push_back({name, reason, s});
  };
  variant("NaN robot pose", Reason::kNonFinite, [&](LocalMapSnapshot& s) { s.x_LR.y = nan; });
  variant("inf segment", Reason::kNonFinite,
          [&](LocalMapSnapshot& s) { s.segments[2].location.x = std::numeric_limits<double>::infinity(); });
  variant("NaN covariance", Reason::kNonFinite, [&](LocalMapSnapshot& s) { s.covariance(4, 4) = nan; });
  variant("far away", Reason::kOutOfRange, [&](LocalMapSnapshot& s) { s.segments[0].location.y = 1e9; });
  variant("zero length", Reason::kOutOfRange, [&](LocalMapSnapshot& s) { s.segments[1].length_m = 0.0; });
  variant("covariance too small", Reason::kMalformed,
          [&](LocalMapSnapshot& s) { s.covariance = s.covariance.topLeftCorner(9, 9).eval(); });
  variant("not square", Reason::kMalformed, [&](LocalMapSnapshot& s) { s.covariance = Eigen::MatrixXd::Zero(11, 10); });
  variant("extra segment", Reason::kMalformed, [&](LocalMapSnapshot& s) { s.segments.push_back(s.segments[0]); });
  variant("asymmetric", Reason::kNotSymmetricPsd, [&](LocalMapSnapshot& s) { s.covariance(3, 5) += 1e-3; });
  variant("indefinite", Reason::kNotSymmetricPsd, [&](LocalMapSnapshot& s) { s.covariance(4, 4) = -0.01; });
  variant("negative eigenvalue", Reason::kNotSymmetricPsd, [&](LocalMapSnapshot& s) {
    s.covariance(3, 5) = s.covariance(5, 3) = 2.0 * std::sqrt(s.covariance(3, 3) * s.covariance(5, 5));
  });
  variant("already fused", Reason::kDuplicate, [&](LocalMapSnapshot& s) { s.seq = 0; });
  variant("negative seq", Reason::kOutOfRange, [&](LocalMapSnapshot& s) { s.seq = -1; });

  const Eigen::MatrixXd P = map.state().full_covariance();
  const std::vector<SegmentView> segments = map.segments();
  const CorrectedFrame frame = *map.corrected_frame(0);
  for (const Bad& b : bad) {
    const std::string& name = b.name;
    EXPECT_THROW(map.fuse(b.snapshot), std::invalid_argument) << name;
    try {
      map.fuse(b.snapshot);
    } catch (const InvalidInput& e) {
      EXPECT_EQ(e.reason(), b.reason) << name << ": " << e.what();
    }
    EXPECT_TRUE(matrices_near(map.state().full_covariance(), P, 0.0)) << name;
    EXPECT_EQ(map.segments().size(), segments.size()) << name;
    EXPECT_TRUE(is_near(map.corrected_frame(0)->x_WL, frame.x_WL, 0.0, 0.0)) << name;
    EXPECT_EQ(map.queued_count(), 0) << name;
    EXPECT_FALSE(map.has_fused(0, 1)) << name;
  }
  // The good one still fuses, once.
  EXPECT_EQ(map.fuse(good).size(), 1u);
  EXPECT_THROW(map.fuse(good), std::invalid_argument);
  // Bad join and sighting inputs.
  EXPECT_THROW(map.join_robot(4, Pose2(nan, 0.0, 0.0)), std::invalid_argument);
  EXPECT_THROW(map.join_robot(4, Pose2(), -Eigen::Matrix3d::Identity()), std::invalid_argument);
  RobotSighting s;
  s.observer_id = s.observed_id = 4;
  EXPECT_THROW(map.add_sighting(s), std::invalid_argument);
  GlobalMapConfig wrong;
  wrong.alpha = 1.5;
  EXPECT_THROW(GlobalMap{wrong}, std::invalid_argument);
  for (const double scale : {0.0, -1.0, nan, std::numeric_limits<double>::infinity()}) {
    GlobalMapConfig bad_scale;
    bad_scale.local_map_covariance_scale = scale;
    EXPECT_THROW(GlobalMap{bad_scale}, std::invalid_argument) << scale;
  }
}

// Robot footprints (GlobalMapConfig::footprint_radius_m): robot 0 maps a room
// and a 0.4 m "wall" that is robot 1's body; robot 1's trajectory passes there.
struct FootprintScene {
  std::vector<Wall> room = synthetic::room(0.0, 0.0, 8.0, 6.0);
  Wall body{Pose2(2.0, 1.0, M_PI / 2), 0.4};         // seen by robot 0 while robot 1 stood at (2.1, 1.0)
  Wall short_wall{Pose2(-2.0, -1.0, 0.0), 0.4};      // a real one, 0.5 m beside robot 1's path
  Pose2 x_WL1{-3.0, -1.5, 0.0};

  LocalMapSnapshot robot0_map() const {
    std::vector<Wall> seen = room;
    seen.push_back(body);
    seen.push_back(short_wall);
    return synthetic::make_snapshot(0, 0, Pose2(), Pose2(1.0, 0.0, 0.1), seen);
  }
  // Robot 1 drives from x_WL1 along y = -1.5 to (2.1, -1.5), then up to (2.1, 1.0).
  LocalMapSnapshot robot1_map() const {
    const Pose2 x_LR(5.1, 2.5, M_PI / 2);
    LocalMapSnapshot s = synthetic::make_snapshot(1, 0, x_WL1, x_LR, {});
    s.scan_poses.clear();
    for (int i = 0; i <= 51; ++i) s.scan_poses.push_back({i, Pose2(0.1 * i, 0.0, 0.0)});
    for (int i = 1; i <= 25; ++i) s.scan_poses.push_back({51 + i, Pose2(5.1, 0.1 * i, M_PI / 2)});
    return s;
  }
};

GlobalMapConfig footprint_config(double radius_m) {
  GlobalMapConfig c = checked_config();
  c.footprint_radius_m = radius_m;
  return c;
}

TEST(GlobalMapTest, ASegmentOnAnotherRobotsPathLeavesTheMap) {
  const FootprintScene scene;
  GlobalMap map(footprint_config(0.35));
  ASSERT_EQ(map.fuse(scene.robot0_map()).size(), 1u);
  ASSERT_EQ(map.counts().segments, 6);
  ASSERT_NE(find_segment(map.segments(), scene.body), nullptr);

  map.join_robot(1, scene.x_WL1);
  const std::vector<FusionReport> r = map.fuse(scene.robot1_map());
  ASSERT_EQ(r.size(), 1u);
  EXPECT_EQ(r[0].footprint_segments_removed, 1);
  EXPECT_EQ(map.counts().segments, 5);
  EXPECT_EQ(find_segment(map.segments(), scene.body), nullptr);
  EXPECT_NE(find_segment(map.segments(), scene.short_wall), nullptr);
  for (const Wall& w : scene.room) EXPECT_NE(find_segment(map.segments(), w), nullptr);
  EXPECT_TRUE(r[0].covariance_ok());
  EXPECT_GE(min_eigenvalue(map), -1e-12);
}

TEST(GlobalMapTest, ASegmentArrivingAfterThePathThroughItIsRemovedToo) {
  const FootprintScene scene;
  GlobalMap map(footprint_config(0.35));
  map.join_robot(0, Pose2());
  map.join_robot(1, scene.x_WL1);
  ASSERT_EQ(map.fuse(scene.robot1_map()).size(), 1u);
  const std::vector<FusionReport> r = map.fuse(scene.robot0_map());
  ASSERT_EQ(r.size(), 1u);
  EXPECT_EQ(r[0].new_segments, 6);
  EXPECT_EQ(r[0].footprint_segments_removed, 1);
  EXPECT_EQ(map.counts().segments, 5);
  EXPECT_EQ(find_segment(map.segments(), scene.body), nullptr);
  EXPECT_NE(find_segment(map.segments(), scene.short_wall), nullptr);
  EXPECT_GE(min_eigenvalue(map), -1e-12);
}

TEST(GlobalMapTest, FootprintsAreOffByDefaultAndTheRadiusMatters) {
  const FootprintScene scene;
  for (const double radius : {0.0, 0.2}) {  // off; smaller than the body's half length
    GlobalMap map(footprint_config(radius));
    map.fuse(scene.robot0_map());
    map.join_robot(1, scene.x_WL1);
    const std::vector<FusionReport> r = map.fuse(scene.robot1_map());
    ASSERT_EQ(r.size(), 1u) << radius;
    EXPECT_EQ(r[0].footprint_segments_removed, 0) << radius;
    EXPECT_EQ(map.counts().segments, 6) << radius;
  }
  EXPECT_EQ(GlobalMapConfig{}.footprint_radius_m, 0.0);
  GlobalMapConfig bad;
  bad.footprint_radius_m = -0.1;
  EXPECT_THROW(GlobalMap{bad}, std::invalid_argument);
  bad.footprint_radius_m = std::numeric_limits<double>::infinity();
  EXPECT_THROW(GlobalMap{bad}, std::invalid_argument);
}

// Crossing segments (GlobalMapConfig::crossing_margin_m): a 0.6 m "wall" at 30°
// across the room's bottom wall (y = -3) is a bad fit; of the two, the segment
// whose direction the map knows less well leaves the map.
struct CrossingScene {
  std::vector<Wall> room = synthetic::room(0.0, 0.0, 8.0, 6.0);  // bottom wall first
  Wall ghost{Pose2(1.0, -3.0, M_PI / 6), 0.6};
  Wall across{Pose2(-1.0, -3.0, M_PI / 2), 0.6};  // perpendicular, through the wall
  Pose2 x_LR{1.0, 0.0, 0.1};                      // robot 0's path: L(k+1) = L(k) ⊕ x_LR

  LocalMapSnapshot map(std::int64_t seq, const std::vector<Wall>& walls, double angle_rad = 0.005) const {
    synthetic::Noise noise;
    noise.angle_rad = angle_rad;
    Pose2 x_WL;
    for (std::int64_t k = 0; k < seq; ++k) x_WL = compose(x_WL, x_LR);
    return synthetic::make_snapshot(0, seq, x_WL, x_LR, walls, noise);
  }
};

TEST(GlobalMapTest, ANewSegmentCrossingAKnownWallLeavesTheMap) {
  const CrossingScene scene;
  GlobalMap map(checked_config());
  ASSERT_EQ(map.fuse(scene.map(0, scene.room)).size(), 1u);
  std::vector<Wall> seen = scene.room;
  seen.push_back(scene.ghost);
  const std::vector<FusionReport> r = map.fuse(scene.map(1, seen));
  ASSERT_EQ(r.size(), 1u);
  EXPECT_EQ(r[0].pairings_accepted, 4);  // the room, seen twice: the walls' directions are known better
  EXPECT_EQ(r[0].new_segments, 1);
  EXPECT_EQ(r[0].crossing_segments_removed, 1);
  EXPECT_EQ(map.counts().segments, 4);
  EXPECT_EQ(find_segment(map.segments(), scene.ghost), nullptr);
  for (const Wall& w : scene.room) EXPECT_NE(find_segment(map.segments(), w), nullptr);
  EXPECT_TRUE(r[0].covariance_ok());
  EXPECT_GE(min_eigenvalue(map), -1e-12);
}

TEST(GlobalMapTest, AKnownSegmentCrossedByABetterNewOneLeavesTheMap) {
  const CrossingScene scene;
  GlobalMap map(checked_config());
  // The bad fit arrives first, with an uncertain direction (0.02 rad); the
  // bottom wall comes next, seen well (0.002 rad): the old segment goes.
  ASSERT_EQ(map.fuse(scene.map(0, subset(scene.room, {1, 2, 3}), 0.002)).size(), 1u);
  ASSERT_EQ(map.fuse(scene.map(1, {scene.ghost}, 0.02)).size(), 1u);
  ASSERT_EQ(map.counts().segments, 4);
  const std::vector<FusionReport> r = map.fuse(scene.map(2, {scene.room[0]}, 0.002));
  ASSERT_EQ(r.size(), 1u);
  EXPECT_EQ(r[0].pairings_accepted, 0);
  EXPECT_EQ(r[0].crossing_segments_removed, 1);
  EXPECT_EQ(map.counts().segments, 4);
  EXPECT_EQ(find_segment(map.segments(), scene.ghost), nullptr);
  EXPECT_NE(find_segment(map.segments(), scene.room[0]), nullptr);
  EXPECT_GE(min_eigenvalue(map), -1e-12);
}

TEST(GlobalMapTest, CrossingsBeyondTheAngleOrWithTheRuleOffStay) {
  const CrossingScene scene;
  std::vector<Wall> seen = scene.room;
  seen.push_back(scene.across);  // 90°: beyond the default 60°
  {
    GlobalMap map(checked_config());
    map.fuse(scene.map(0, scene.room));
    const std::vector<FusionReport> r = map.fuse(scene.map(1, seen));
    ASSERT_EQ(r.size(), 1u);
    EXPECT_EQ(r[0].crossing_segments_removed, 0);
    EXPECT_NE(find_segment(map.segments(), scene.across), nullptr);
  }
  seen.back() = scene.ghost;
  GlobalMapConfig off = checked_config();
  off.crossing_margin_m = 0.0;
  GlobalMap map(off);
  map.fuse(scene.map(0, scene.room));
  const std::vector<FusionReport> r = map.fuse(scene.map(1, seen));
  ASSERT_EQ(r.size(), 1u);
  EXPECT_EQ(r[0].crossing_segments_removed, 0);
  EXPECT_EQ(map.counts().segments, 5);
  for (const double bad_angle : {0.0, 1.6, std::numeric_limits<double>::quiet_NaN()}) {
    GlobalMapConfig bad;
    bad.crossing_max_angle_rad = bad_angle;
    EXPECT_THROW(GlobalMap{bad}, std::invalid_argument) << bad_angle;
  }
  GlobalMapConfig bad;
  bad.crossing_margin_m = -0.1;
  EXPECT_THROW(GlobalMap{bad}, std::invalid_argument);
}

TEST(GlobalMapTest, ASnapshotWithANonFiniteScanPoseIsRejected) {
  const FootprintScene scene;
  GlobalMap map(footprint_config(0.35));
  LocalMapSnapshot s = scene.robot0_map();
  s.scan_poses[1].x_LR.x = std::numeric_limits<double>::quiet_NaN();
  try {
    map.fuse(s);
    FAIL() << "accepted";
  } catch (const InvalidInput& e) {
    EXPECT_EQ(e.reason(), InvalidInput::Reason::kNonFinite);
    EXPECT_NE(std::string(e.what()).find("scan pose 1"), std::string::npos) << e.what();
  }
  EXPECT_EQ(map.counts().segments, 0);
  EXPECT_FALSE(map.has_fused(0, 0));
}

}  // namespace
}  // namespace lmf::fusion
