#include "lmf/eval/trajectory_error.hpp"

#include <cmath>
#include <numbers>
#include <vector>

#include <gtest/gtest.h>

namespace lmf::eval {
namespace {

constexpr double kDegToRad = std::numbers::pi / 180.0;

std::vector<PosePair> zigzag_pairs() {
  // Reference along x; the estimate is off by ±0.1 m laterally and ±2° in heading,
  // arranged so the best rigid alignment is the identity.
  return {{{0.0, 0.1, 2.0 * kDegToRad}, {0.0, 0.0, 0.0}},
          {{1.0, -0.1, -2.0 * kDegToRad}, {1.0, 0.0, 0.0}},
          {{2.0, -0.1, 2.0 * kDegToRad}, {2.0, 0.0, 0.0}},
          {{3.0, 0.1, -2.0 * kDegToRad}, {3.0, 0.0, 0.0}}};
}

TEST(TrajectoryError, HandMadeZigzagGivesKnownAte) {
  const AbsoluteError ate = absolute_trajectory_error(zigzag_pairs());
  EXPECT_EQ(ate.count, 4u);
  EXPECT_NEAR(ate.position_rmse_m, 0.1, 1e-12);
  EXPECT_NEAR(ate.heading_rmse_deg, 2.0, 1e-9);
  EXPECT_NEAR(ate.position_max_m, 0.1, 1e-12);
  EXPECT_TRUE(is_near(ate.alignment, Pose2(), 1e-12, 1e-12));
}

TEST(TrajectoryError, RigidlyMovedCopyHasZeroErrorAfterAlignment) {
  const Pose2 x_ER(5.0, -3.0, 2.5);  // an arbitrary rigid offset of the estimate frame
  std::vector<PosePair> pairs;
  for (int i = 0; i < 20; ++i) {
    const double t = 0.3 * i;
    const Pose2 reference(4.0 * std::cos(t), 2.0 * std::sin(t), wrap_angle(t + 1.0));
    pairs.push_back({compose(x_ER, reference), reference});
  }
  const AbsoluteError aligned = absolute_trajectory_error(pairs);
  EXPECT_LT(aligned.position_rmse_m, 1e-9);
  EXPECT_LT(aligned.heading_rmse_deg, 1e-7);
  EXPECT_TRUE(is_near(aligned.alignment, inverse(x_ER), 1e-9, 1e-9));
  const AbsoluteError unaligned = absolute_trajectory_error(pairs, /*align=*/false);
  EXPECT_GT(unaligned.position_rmse_m, 1.0);
}

TEST(TrajectoryError, RelativeErrorOfAScaledPath) {
  // Reference every 0.5 m along x; the estimate overstates every step by 10 %.
  std::vector<PosePair> pairs;
  for (int i = 0; i <= 40; ++i) pairs.push_back({{0.55 * i, 0.0, 0.0}, {0.5 * i, 0.0, 0.0}});
  const RelativeError rpe1 = relative_pose_error(pairs, 1.0);
  EXPECT_EQ(rpe1.count, 39u);  // (i, i + 2) for i = 0..38
  EXPECT_NEAR(rpe1.translation_rmse_m, 0.1, 1e-9);
  EXPECT_NEAR(rpe1.rotation_rmse_deg, 0.0, 1e-12);
  const RelativeError rpe10 = relative_pose_error(pairs, 10.0);
  EXPECT_EQ(rpe10.count, 21u);
  EXPECT_NEAR(rpe10.translation_rmse_m, 1.0, 1e-9);
  EXPECT_EQ(relative_pose_error(pairs, 100.0).count, 0u);
  EXPECT_NEAR(reference_path_length(pairs), 20.0, 1e-12);
  EXPECT_THROW(relative_pose_error(pairs, 0.0), std::invalid_argument);
}

TEST(TrajectoryError, AssociationByNearestTimestampWithinTolerance) {
  const std::vector<StampedPose> estimate = {{1000, {1, 0, 0}}, {2600, {2, 0, 0}}, {5000, {3, 0, 0}}};
  const std::vector<StampedPose> reference = {{1000, {10, 0, 0}}, {2000, {20, 0, 0}}, {3000, {30, 0, 0}}};
  const std::vector<PosePair> pairs = associate_by_time(estimate, reference, 500);
  ASSERT_EQ(pairs.size(), 2u);  // 5000 has no reference within 500 us
  EXPECT_DOUBLE_EQ(pairs[0].reference.x, 10.0);
  EXPECT_DOUBLE_EQ(pairs[1].reference.x, 30.0);  // 2600 is nearer to 3000 than to 2000
  const std::vector<StampedPose> unsorted = {{2000, {}}, {1000, {}}};
  EXPECT_THROW(associate_by_time(unsorted, reference), std::invalid_argument);
  EXPECT_THROW(align_se2({}), std::invalid_argument);
}

}  // namespace
}  // namespace lmf::eval

#include "lmf/eval/map_error.hpp"

namespace lmf::eval {
namespace {

TEST(MapError, OffsetSegmentAndAGhost) {
  const std::vector<LineSegment> walls = {{{0, 0}, {10, 0}}, {{10, 0}, {10, 5}}};
  // One segment 3 cm off the first wall, reversed; one nowhere near a wall; both in a
  // map frame W that is the truth's frame shifted by 1 m in x.
  const std::vector<LineSegment> mapped = {{{8.0, 0.03}, {1.0, 0.03}}, {{3.0, 3.0}, {5.0, 3.0}}};
  const MapError e = map_error(mapped, walls, Pose2(1.0, 0.0, 0.0));
  EXPECT_EQ(e.segments, 2u);
  EXPECT_EQ(e.unmatched_segments, 1u);
  EXPECT_NEAR(e.rms_m, 0.03, 1e-12);
  EXPECT_NEAR(e.max_m, 0.03, 1e-12);
  EXPECT_THROW(map_error(mapped, walls, Pose2(), 0.0), std::invalid_argument);
}

TEST(MapError, OneSegmentAlongCollinearFacesIsScoredAgainstEach) {
  // A corridor wall with a 1 m door: two faces in line. A mapped segment along
  // both, 2 cm off, bridging the door: the samples beside the faces are 2 cm
  // off, those over the door up to 0.5 m (the nearest face end).
  const std::vector<LineSegment> walls = {{{0, 0}, {4, 0}}, {{5, 0}, {9, 0}}};
  const MapError along = map_error({{{0.0, 0.02}, {4.0, 0.02}}, {{5.0, 0.02}, {9.0, 0.02}}}, walls, Pose2());
  EXPECT_EQ(along.unmatched_segments, 0u);
  EXPECT_NEAR(along.rms_m, 0.02, 1e-12);
  const MapError bridged = map_error({{{0.0, 0.02}, {9.0, 0.02}}}, walls, Pose2(), 0.1);
  EXPECT_EQ(bridged.unmatched_segments, 0u);
  EXPECT_NEAR(bridged.max_m, std::hypot(0.5, 0.02), 1e-9);
  EXPECT_GT(bridged.rms_m, 0.05);  // the door part dominates the 2 cm elsewhere
}

}  // namespace
}  // namespace lmf::eval
