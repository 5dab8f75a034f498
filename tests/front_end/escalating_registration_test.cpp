// The front end's registration stage (escalating_registration.hpp): a motion
// beyond the search window is found by the escalated search; one inside it
// is the plain match's, and so is one the escalated search agrees with.
#include "lmf/front_end/escalating_registration.hpp"

#include <cmath>
#include <numbers>

#include <gtest/gtest.h>

#include "front_end/room_world.hpp"

namespace lmf {
namespace {

struct Pair {
  ReferenceScan A;
  ScanPoints B;
};

// The reference seen from the origin, the scan from `truth`.
Pair scans(const Pose2& truth, const ScanMatcherConfig& config) {
  return {ReferenceScan::from(testing::make_scan(testing::room_with_pillar(), Pose2(), 361), config),
          scan_points_by_kind(testing::make_scan(testing::room_with_pillar(), truth, 361), config)};
}

// The odometry's covariance of a 0.3 m step, as the default model gives it roughly.
const Eigen::Matrix3d kQ = Eigen::Vector3d(0.03 * 0.03, 0.01 * 0.01, 0.02 * 0.02).asDiagonal();

TEST(EscalatingRegistration, TheEscalatedSearchIsThreeTimesAsWideAndAsCoarse) {
  const ScanMatcherConfig config;
  const ScanMatcherConfig wider = escalated_search(config);
  EXPECT_DOUBLE_EQ(wider.search_window_m, kEscalation * config.search_window_m);
  EXPECT_DOUBLE_EQ(wider.search_window_rad, kEscalation * config.search_window_rad);
  EXPECT_DOUBLE_EQ(wider.search_resolution_m, kEscalation * config.search_resolution_m);
  EXPECT_NO_THROW(wider.validate());
  // Within what a configuration may hold.
  ScanMatcherConfig wide = config;
  wide.search_window_m = 4.0;
  wide.search_window_rad = 1.2;
  wide.search_resolution_m = 0.2;
  const ScanMatcherConfig widest = escalated_search(wide);
  EXPECT_DOUBLE_EQ(widest.search_window_m, 5.0);
  EXPECT_DOUBLE_EQ(widest.search_window_rad, std::numbers::pi);
  EXPECT_NO_THROW(widest.validate());
}

TEST(EscalatingRegistration, AMotionInsideTheWindowIsThePlainMatch) {
  const ScanMatcherConfig config;
  const Pose2 truth(0.3, 0.02, 0.1);
  const Pair p = scans(truth, config);
  const Pose2 odometry(0.32, 0.0, 0.08);
  const Registration r = register_escalating(p.A, p.B, odometry, kQ, config);
  const std::optional<ScanMatch> plain = match_scans(p.A, p.B, odometry, kQ, config);
  ASSERT_TRUE(r.match.has_value());
  ASSERT_TRUE(plain.has_value());
  EXPECT_FALSE(r.search_escalated);
  EXPECT_FALSE(r.match_from_escalation);
  EXPECT_EQ(r.match->x_AB.x, plain->x_AB.x);
  EXPECT_EQ(r.match->x_AB.phi, plain->x_AB.phi);
}

TEST(EscalatingRegistration, AGlitchBeyondTheWindowIsFoundByTheWiderSearch) {
  const ScanMatcherConfig config;
  // The robot turned 0.65 rad (37°) where the odometry says it went straight:
  // the truth lies beyond the window's ± 0.25 rad.
  const Pose2 truth(0.3, 0.0, 0.65);
  const Pose2 odometry(0.3, 0.0, 0.0);
  ASSERT_GT(truth.phi - odometry.phi, config.search_window_rad);
  const Pair p = scans(truth, config);
  // The plain match cannot reach the truth: it fails, or ends elsewhere.
  const std::optional<ScanMatch> plain = match_scans(p.A, p.B, odometry, kQ, config);
  if (plain) {
    EXPECT_GT(std::abs(wrap_angle(plain->x_AB.phi - truth.phi)), 0.05);
  }
  const Registration r = register_escalating(p.A, p.B, odometry, kQ, config);
  EXPECT_TRUE(r.search_escalated);
  EXPECT_TRUE(r.match_from_escalation);
  ASSERT_TRUE(r.match.has_value());
  EXPECT_NEAR(r.match->x_AB.x, truth.x, 0.03);
  EXPECT_NEAR(r.match->x_AB.y, truth.y, 0.03);
  EXPECT_NEAR(r.match->x_AB.phi, truth.phi, 0.01);
  // Its covariance is the laser's: the contradicted prior is down-weighted, not trusted.
  EXPECT_LT(std::sqrt(r.match->covariance(2, 2)), 0.01);
}

TEST(EscalatingRegistration, AMatchExplainingLessThanHalfEscalatesAndStandsWhereTheWiderAgrees) {
  const ScanMatcherConfig config;
  // A curved screen, new since the reference, now fills more than half of the
  // view: the right pose explains less than half of the scan, though more
  // than min_overlap; no pose lays the curve on the room's straight walls.
  const Pose2 truth(0.3, 0.02, 0.05);
  testing::SyntheticWorld with_screen = testing::room_with_pillar();
  constexpr int kPieces = 24;
  const auto on_screen = [&](int k) {
    const double a = truth.phi + (-1.0 + 2.0 * k / kPieces) * 1.0;
    return Eigen::Vector2d(truth.x + 1.2 * std::cos(a), truth.y + 1.2 * std::sin(a));
  };
  for (int k = 0; k < kPieces; ++k) with_screen.walls.push_back({on_screen(k), on_screen(k + 1)});
  const ReferenceScan A = ReferenceScan::from(testing::make_scan(testing::room_with_pillar(), Pose2(), 361), config);
  const ScanPoints B = scan_points_by_kind(testing::make_scan(with_screen, truth, 361), config);
  const Pose2 odometry(0.32, 0.0, 0.07);
  const std::optional<ScanMatch> plain = match_scans(A, B, odometry, kQ, config);
  ASSERT_TRUE(plain.has_value());
  ASSERT_FALSE(plain->search_at_window_edge);
  ASSERT_GE(plain->search_score, config.min_overlap);
  ASSERT_LT(plain->search_score, 0.5);
  const Registration r = register_escalating(A, B, odometry, kQ, config);
  EXPECT_TRUE(r.search_escalated);
  // The wider search finds the same pose: not elsewhere, so the first match stands.
  EXPECT_FALSE(r.match_from_escalation);
  ASSERT_TRUE(r.match.has_value());
  EXPECT_EQ(r.match->x_AB.x, plain->x_AB.x);
  EXPECT_EQ(r.match->x_AB.y, plain->x_AB.y);
  EXPECT_EQ(r.match->x_AB.phi, plain->x_AB.phi);
  EXPECT_NEAR(r.match->x_AB.x, truth.x, 0.03);
  EXPECT_NEAR(r.match->x_AB.phi, truth.phi, 0.01);
}

}  // namespace
}  // namespace lmf
