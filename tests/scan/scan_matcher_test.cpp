// The scan matcher of the local map's step 1: Jacobians against finite
// differences, a known increment recovered in a room (also from an odometry
// increment far outside a local refinement's basin), a corridor's unobservable
// direction left to the odometry prior, ambiguous and degenerate scenes
// refused, and bad input.
#include "lmf/scan/scan_matcher.hpp"

#include <cmath>
#include <numbers>
#include <random>
#include <stdexcept>
#include <vector>

#include <Eigen/Cholesky>
#include <Eigen/Eigenvalues>
#include <gtest/gtest.h>

#include "scan/synthetic_scan.hpp"
#include "test_support.hpp"

namespace lmf {
namespace {

using testing::matrices_near;
using testing::numerical_jacobian;

Eigen::VectorXd plain_difference(const Eigen::VectorXd& a, const Eigen::VectorXd& b) { return a - b; }

Eigen::VectorXd pose_difference(const Eigen::VectorXd& a, const Eigen::VectorXd& b) {
  Eigen::VectorXd d = a - b;
  d(2) = wrap_angle(d(2));
  return d;
}

Pose2 compose_vector(const Pose2& x, const Eigen::VectorXd& delta) {
  return compose(x, Pose2(delta(0), delta(1), delta(2)));
}

TEST(ScanMatcherJacobians, PointToLineMatchesFiniteDifferences) {
  const Eigen::Vector2d a(2.0, -0.5);
  const Eigen::Vector2d n = Eigen::Vector2d(0.3, 1.0).normalized();
  for (const Pose2& x : {Pose2(0.4, -0.2, 0.3), Pose2(-1.0, 2.0, std::numbers::pi - 1e-3),
                         Pose2(0.0, 0.0, -std::numbers::pi + 1e-3)}) {
    for (const Eigen::Vector2d& b : {Eigen::Vector2d(3.0, 1.0), Eigen::Vector2d(-0.5, 7.0)}) {
      auto e = [&](const Eigen::VectorXd& delta) {
        const Pose2 y = compose_vector(x, delta);
        return Eigen::VectorXd::Constant(1, n.dot(y.transform_point(b) - a));
      };
      const Eigen::MatrixXd numeric = numerical_jacobian(e, Eigen::VectorXd::Zero(3), plain_difference);
      EXPECT_TRUE(matrices_near(point_to_line_jacobian(x, b, n), numeric, 1e-7));
    }
  }
}

TEST(ScanMatcherJacobians, PriorResidualMatchesFiniteDifferences) {
  for (const Pose2& u : {Pose2(0.5, 0.1, 0.2), Pose2(0.0, 0.0, std::numbers::pi - 0.01)}) {
    for (const Pose2& x : {Pose2(0.55, 0.05, 0.25), Pose2(0.4, -0.1, -std::numbers::pi + 0.02)}) {
      auto r = [&](const Eigen::VectorXd& delta) {
        const Pose2 d = between(u, compose_vector(x, delta));
        return Eigen::Vector3d(d.x, d.y, d.phi).eval();
      };
      auto r_dynamic = [&](const Eigen::VectorXd& delta) { return Eigen::VectorXd(r(delta)); };
      const Eigen::MatrixXd numeric = numerical_jacobian(r_dynamic, Eigen::VectorXd::Zero(3), pose_difference);
      EXPECT_TRUE(matrices_near(prior_residual_jacobian(u, x), numeric, 1e-7));
    }
  }
}

// An L-shaped room with a pillar and a recess: every direction is constrained.
testing::SyntheticWorld room() {
  testing::SyntheticWorld w;
  w.walls = {{{-2.0, -4.0}, {10.0, -4.0}}, {{10.0, -4.0}, {10.0, 1.0}}, {{10.0, 1.0}, {6.0, 1.0}},
             {{6.0, 1.0}, {6.0, 5.0}},     {{6.0, 5.0}, {-2.0, 5.0}},  {{-2.0, 5.0}, {-2.0, -4.0}},
             {{3.0, 4.0}, {3.0, 5.0}}};
  w.discs = {{{4.0, -1.5}, 0.3}};
  return w;
}

// A round room (radius 10 m around `centre`, as 720 straight pieces) with three square pillars
// (0.4 m): the wall says nothing about rotation seen from the centre, the
// pillars (8.5 m away) say it all, and a rotation error of 8° moves them by
// more than the refinement's first gate.
testing::SyntheticWorld round_room(const Eigen::Vector2d& centre) {
  testing::SyntheticWorld w;
  constexpr int kPieces = 720;
  for (int i = 0; i < kPieces; ++i) {
    const double a0 = 2.0 * std::numbers::pi * i / kPieces;
    const double a1 = 2.0 * std::numbers::pi * (i + 1) / kPieces;
    w.walls.push_back({centre + 10.0 * Eigen::Vector2d(std::cos(a0), std::sin(a0)),
                       centre + 10.0 * Eigen::Vector2d(std::cos(a1), std::sin(a1))});
  }
  for (const Eigen::Vector2d& offset : {Eigen::Vector2d(8.5, 1.0), Eigen::Vector2d(6.0, -6.0), Eigen::Vector2d(3.5, 7.8)}) {
    const Eigen::Vector2d c = centre + offset;
    const Eigen::Vector2d a = c + Eigen::Vector2d(-0.2, -0.2);
    const Eigen::Vector2d b = c + Eigen::Vector2d(0.2, -0.2);
    const Eigen::Vector2d d = c + Eigen::Vector2d(0.2, 0.2);
    const Eigen::Vector2d e = c + Eigen::Vector2d(-0.2, 0.2);
    w.walls.insert(w.walls.end(), {{a, b}, {b, d}, {d, e}, {e, a}});
  }
  return w;
}

Eigen::Matrix3d odometry_like_covariance(const Pose2& u) {
  const double d = std::hypot(u.x, u.y);
  const double s_xy = 0.08 * d + 0.001;
  const double s_phi = 0.08 * std::abs(u.phi) + 0.01 * d + 0.0005;
  return Eigen::Vector3d(s_xy * s_xy, s_xy * s_xy, s_phi * s_phi).asDiagonal();
}

bool symmetric_positive_definite(const Eigen::Matrix3d& C) {
  return C.isApprox(C.transpose(), 1e-12) && Eigen::LLT<Eigen::Matrix3d>(C).info() == Eigen::Success;
}

TEST(ScanMatcher, RecoversAKnownIncrementInARoom) {
  std::mt19937 rng(7);
  const Pose2 x_WA(0.0, 0.0, 0.1);
  const Pose2 x_WB(0.8, 0.3, 0.25);
  const LaserScan A = testing::make_scan(room(), x_WA, 361, 80.0, 0.01, &rng);
  const LaserScan B = testing::make_scan(room(), x_WB, 361, 80.0, 0.01, &rng);
  const Pose2 truth = between(x_WA, x_WB);
  const Pose2 u_hat = compose(truth, Pose2(0.12, -0.08, 0.05));  // odometry error: 14 cm, 3°
  const Eigen::Matrix3d Q = odometry_like_covariance(u_hat);
  ScanMatcherConfig config;
  config.enabled = true;
  const std::optional<ScanMatch> m =
      match_scans(ReferenceScan::from(A, config), scan_points(B, config), u_hat, Q, config);
  ASSERT_TRUE(m.has_value());
  // A small fraction of the odometry's error (14 cm, 0.05 rad) remains: the
  // model noise (1 cm, 0.003 rad) keeps the prior's pull on the estimate.
  const Pose2 e = between(m->x_AB, truth);
  EXPECT_LT(std::hypot(e.x, e.y), 0.015);
  EXPECT_LT(std::abs(e.phi), 0.008);
  EXPECT_GT(m->correspondences, 200);
  EXPECT_LT(m->rms_m, 0.03);
  ASSERT_TRUE(symmetric_positive_definite(m->covariance));
  // Far tighter than the odometry, and the error within its 99.9 % bound.
  EXPECT_LT(m->covariance(0, 0), 0.1 * Q(0, 0));
  EXPECT_LT(m->covariance(1, 1), 0.1 * Q(1, 1));
  EXPECT_LT(m->covariance(2, 2), 0.2 * Q(2, 2));
  const Eigen::Vector3d p(e.x, e.y, e.phi);
  EXPECT_LT(p.dot(m->covariance.ldlt().solve(p)), 16.3);
}

// One increment matched under two configurations (the reference and the scan's
// points prepared for each): for tests that compare what an option changes.
struct MatchPair {
  std::optional<ScanMatch> a;
  std::optional<ScanMatch> b;
};
MatchPair match_under_both(const LaserScan& A, const LaserScan& B, const Pose2& u_hat, const Eigen::Matrix3d& Q,
                           const ScanMatcherConfig& config_a, const ScanMatcherConfig& config_b) {
  return {match_scans(ReferenceScan::from(A, config_a), scan_points(B, config_a), u_hat, Q, config_a),
          match_scans(ReferenceScan::from(A, config_b), scan_points(B, config_b), u_hat, Q, config_b)};
}

// residual_sigma: the covariance's laser term takes σ² as the larger of
// point_sigma_m² and the residuals' own variance. Scans noisier than
// point_sigma_m report a wider covariance; scans within it the same as without
// the option. The estimate and the laser information (the weight of the laser
// in it, and what the odometry model learns with) do not change.
TEST(ScanMatcher, ResidualSigmaWidensTheCovarianceOnlyForScansNoisierThanConfigured) {
  const Pose2 x_WA(0.0, 0.0, 0.1);
  const Pose2 x_WB(0.8, 0.3, 0.25);
  const Pose2 u_hat = compose(between(x_WA, x_WB), Pose2(0.05, -0.03, 0.02));
  const Eigen::Matrix3d Q = odometry_like_covariance(u_hat);
  ScanMatcherConfig fixed;
  fixed.residual_sigma = false;
  ScanMatcherConfig calibrated = fixed;
  calibrated.residual_sigma = true;
  for (const double range_noise_m : {0.005, 0.09}) {
    std::mt19937 rng(11);
    const LaserScan A = testing::make_scan(room(), x_WA, 361, 80.0, range_noise_m, &rng);
    const LaserScan B = testing::make_scan(room(), x_WB, 361, 80.0, range_noise_m, &rng);
    const auto [a, b] = match_under_both(A, B, u_hat, Q, fixed, calibrated);
    ASSERT_TRUE(a && b) << range_noise_m;
    ASSERT_TRUE(symmetric_positive_definite(b->covariance));
    EXPECT_TRUE(is_near(a->x_AB, b->x_AB, 1e-12, 1e-12)) << range_noise_m;
    EXPECT_TRUE(a->laser_information.isApprox(b->laser_information, 1e-12)) << range_noise_m;
    const double ratio = b->covariance.trace() / a->covariance.trace();
    if (range_noise_m < fixed.point_sigma_m) {
      EXPECT_NEAR(ratio, 1.0, 1e-12) << "residuals within point_sigma_m change nothing";
    } else {
      // Residuals of about 0.09 m against 0.03 m configured (Huber-weighted, and
      // the model noise's widening and the prior unchanged): clearly wider.
      EXPECT_GT(ratio, 1.5);
      EXPECT_GT(b->covariance(2, 2), a->covariance(2, 2));
    }
  }
}

// range_noise_per_m: the covariance takes each point at σ_i² = point_sigma_m² +
// (range_noise_per_m r)², so far points claim less; the estimate and the laser
// information the odometry model learns with are those of point_sigma_m alone.
TEST(ScanMatcher, APointNoiseGrowingWithRangeWidensTheCovarianceNotTheEstimate) {
  const Pose2 x_WA(0.0, 0.0, 0.1);
  const Pose2 x_WB(0.8, 0.3, 0.25);
  const Pose2 u_hat = compose(between(x_WA, x_WB), Pose2(0.05, -0.03, 0.02));
  const Eigen::Matrix3d Q = odometry_like_covariance(u_hat);
  std::mt19937 rng(5);
  const LaserScan A = testing::make_scan(room(), x_WA, 361, 80.0, 0.01, &rng);
  const LaserScan B = testing::make_scan(room(), x_WB, 361, 80.0, 0.01, &rng);
  ScanMatcherConfig constant;
  ScanMatcherConfig at_range = constant;
  at_range.range_noise_per_m = 0.01;  // 1 % of the range: σ_i 0.03 m at 1 m, 0.10 m at 10 m
  const auto [a, b] = match_under_both(A, B, u_hat, Q, constant, at_range);
  ASSERT_TRUE(a && b);
  ASSERT_TRUE(symmetric_positive_definite(b->covariance));
  EXPECT_TRUE(is_near(a->x_AB, b->x_AB, 1e-12, 1e-12));
  EXPECT_TRUE(a->laser_information.isApprox(b->laser_information, 1e-12));
  // The heading leans most on the far walls (the lever arm): it widens most.
  EXPECT_GT(b->covariance(0, 0), a->covariance(0, 0));
  EXPECT_GT(b->covariance(1, 1), a->covariance(1, 1));
  EXPECT_GT(b->covariance(2, 2), 1.5 * a->covariance(2, 2));
}

// residual_correlation: residuals that follow each other along the scan (a wall
// bent, or seen through a window, over many beams) are fewer independent
// measurements than points. Their lag-1 correlation ρ gives N (1 − ρ)/(1 + ρ)
// (AR(1)), and the laser information shrinks accordingly; white range noise,
// or residuals far inside point_sigma_m, leave ρ near 0 and the information as
// the count alone gives it.
TEST(ScanMatcher, ResidualsCorrelatedAlongTheScanCountAsFewerIndependentPoints) {
  const Pose2 x_WA(0.0, 0.0, 0.1);
  const Pose2 x_WB(0.8, 0.3, 0.25);
  const Pose2 u_hat = compose(between(x_WA, x_WB), Pose2(0.05, -0.03, 0.02));
  const Eigen::Matrix3d Q = odometry_like_covariance(u_hat);
  ScanMatcherConfig counted;
  counted.residual_sigma = false;
  counted.residual_correlation = false;
  // The laser term alone: neither capped by the count nor by the model noise.
  counted.max_independent_points = 1000.0;
  counted.model_noise_m = 0.0;
  counted.model_noise_rad = 0.0;
  ScanMatcherConfig correlated = counted;
  correlated.residual_correlation = true;
  std::mt19937 rng(5);
  const LaserScan A = testing::make_scan(room(), x_WA, 361, 80.0, 0.005, &rng);
  // Range errors of 4 cm RMS (above point_sigma_m's 3 cm), white ...
  const LaserScan white = testing::make_scan(room(), x_WB, 361, 80.0, 0.04, &rng);
  // ... and as a slow ripple over ~40 beams.
  LaserScan ripple = testing::make_scan(room(), x_WB, 361, 80.0, 0.0, &rng);
  for (std::size_t i = 0; i < ripple.ranges_m.size(); ++i) {
    ripple.ranges_m[i] += 0.04 * std::sqrt(2.0) * std::sin(2.0 * std::numbers::pi * static_cast<double>(i) / 40.0);
  }
  const auto information_ratio = [&](const LaserScan& B) {
    const auto [a, b] = match_under_both(A, B, u_hat, Q, counted, correlated);
    EXPECT_TRUE(a && b);
    if (!a || !b) return 0.0;
    EXPECT_TRUE(symmetric_positive_definite(b->covariance));
    return b->laser_information.trace() / a->laser_information.trace();
  };
  EXPECT_GT(information_ratio(white), 0.9);
  EXPECT_LT(information_ratio(ripple), 0.5);
  // A clean scan (1 mm noise): residuals far inside point_sigma_m, the count as it is.
  EXPECT_GT(information_ratio(testing::make_scan(room(), x_WB, 361, 80.0, 0.001, &rng)), 0.9);
}

// field_along_lines: the correlative search's likelihood field stands for the
// reference's walls, not for where its beams hit them. A sparse laser (1°
// between beams, like orebro's) sees the room again from the same place, its beams half a
// beam further round: every point of B falls between two of A's. From the
// points alone the right pose scores as if part of the walls were missing.
TEST(ScanMatcher, TheSearchScoresWallsBetweenSparseBeamsAsWalls) {
  const double beam_step = std::numbers::pi / 180.0;  // 181 beams over 180°
  const Pose2 x_WA(0.5, 0.0, 0.1);
  const Pose2 x_WB(0.5, 0.0, 0.1 + 0.5 * beam_step);
  const LaserScan A = testing::make_scan(room(), x_WA, 181);
  const LaserScan B = testing::make_scan(room(), x_WB, 181);
  const Pose2 u_hat = between(x_WA, x_WB);
  const Eigen::Matrix3d Q = Eigen::Vector3d(1e-4, 1e-4, 1e-4).asDiagonal();
  double score[2] = {0.0, 0.0};
  for (const bool along_lines : {false, true}) {
    ScanMatcherConfig config;
    config.field_along_lines = along_lines;
    config.min_correspondences = 10;
    const std::optional<ScanMatch> m =
        match_scans(ReferenceScan::from(A, config), scan_points(B, config), u_hat, Q, config);
    ASSERT_TRUE(m.has_value()) << along_lines;
    score[along_lines ? 1 : 0] = m->search_score;
    const Pose2 e = between(m->x_AB, u_hat);
    EXPECT_LT(std::hypot(e.x, e.y), 0.02) << along_lines;
  }
  // (The field is sampled at cell centres, so even an exact hit reads less than 1.)
  EXPECT_GT(score[1], 0.8);
  EXPECT_GT(score[1], score[0] + 0.05);
}

TEST(ScanMatcher, InACorridorTheAlongTrackDirectionStaysWithTheOdometry) {
  // Two parallel walls far longer than the laser's reach: x is unobservable.
  testing::SyntheticWorld corridor;
  corridor.walls = {{{-100.0, -1.5}, {100.0, -1.5}}, {{-100.0, 1.5}, {100.0, 1.5}}};
  const Pose2 x_WA(0.0, 0.0, 0.0);
  const Pose2 x_WB(1.0, 0.1, 0.02);
  ScanMatcherConfig config;
  config.enabled = true;
  const LaserScan A = testing::make_scan(corridor, x_WA, 361, 20.0);
  const LaserScan B = testing::make_scan(corridor, x_WB, 361, 20.0);
  const Pose2 truth = between(x_WA, x_WB);
  const Pose2 u_hat = compose(truth, Pose2(0.15, 0.08, 0.1));
  const Eigen::Matrix3d Q = odometry_like_covariance(u_hat);
  const std::optional<ScanMatch> m =
      match_scans(ReferenceScan::from(A, config), scan_points(B, config), u_hat, Q, config);
  ASSERT_TRUE(m.has_value());
  ASSERT_TRUE(symmetric_positive_definite(m->covariance));
  // Lateral offset and heading come from the walls (in A's frame: y and phi) ...
  EXPECT_NEAR(m->x_AB.y, truth.y, 0.01);      // odometry: 8 cm off (and more by its heading)
  // odometry: 0.1 rad off with a std of 0.02: the prior, trusted, pulls the angle a little.
  EXPECT_NEAR(m->x_AB.phi, truth.phi, 0.01);
  // ... the along-track position stays the odometry's, with its uncertainty.
  EXPECT_NEAR(m->x_AB.x, u_hat.x, 0.02);
  const Eigen::Matrix3d C = m->covariance;
  EXPECT_GT(C(0, 0), 0.8 * Q(0, 0));
  EXPECT_LT(C(1, 1), 0.1 * Q(1, 1));
  EXPECT_LT(C(2, 2), 0.2 * Q(2, 2));
  // The laser's own information says so: nothing along the corridor's axis
  // (its direction in B's frame, rotated by the small angle), much across it.
  const Eigen::Vector2d axis(std::cos(m->x_AB.phi), -std::sin(m->x_AB.phi));
  const Eigen::Vector3d along(axis.x(), axis.y(), 0.0);
  EXPECT_LT(along.dot(m->laser_information * along), 1e-3 * m->laser_information(1, 1));
  EXPECT_TRUE(symmetric_positive_definite(m->laser_information + 1e-9 * Eigen::Matrix3d::Identity()));
}

// The old matcher refused an estimate 7 sigma from the odometry (a prior
// test): a wrong odometry increment is what the search window is for, so the
// match is kept now, and its distance to the prior reported.
TEST(ScanMatcher, AMatchFarFromTheOdometryPriorIsKeptAndItsDistanceReported) {
  ScanMatcherConfig config;
  config.enabled = true;
  const LaserScan A = testing::make_scan(room(), Pose2(), 361);
  const ReferenceScan reference = ReferenceScan::from(A, config);
  const Pose2 u(0.5, 0.0, 0.0);
  const Eigen::Matrix3d Q = odometry_like_covariance(u);
  EXPECT_FALSE(match_scans(reference, std::vector<Eigen::Vector2d>{}, u, Q, config).has_value());
  // The true motion is 0.8 m, the odometry says 0.5 m with a 4 cm std.
  const LaserScan B = testing::make_scan(room(), Pose2(0.8, 0.0, 0.0), 361);
  const std::optional<ScanMatch> m = match_scans(reference, scan_points(B, config), u, Q, config);
  ASSERT_TRUE(m.has_value());
  EXPECT_NEAR(m->x_AB.x, 0.8, 0.03);
  EXPECT_GT(m->prior_distance2, 21.1);  // chi2inv(1 - 1e-4, 3): the old refusal
  // The prior residual is between(û, x_AB), and prior_distance2 its Q⁻¹ norm.
  const Pose2 r = between(u, m->x_AB);
  EXPECT_NEAR(m->prior_residual(0), r.x, 1e-12);
  EXPECT_NEAR(m->prior_residual(1), r.y, 1e-12);
  EXPECT_NEAR(m->prior_residual(2), r.phi, 1e-12);
  EXPECT_NEAR(m->prior_distance2, m->prior_residual.dot(Q.ldlt().solve(m->prior_residual)), 1e-9);
}

// The odometry off by 8° and 0.3 m: the correlative search finds the increment,
// the local refinement alone from the odometry increment does not.
TEST(ScanMatcher, TheSearchFindsAnIncrementFarOutsideTheLocalBasin) {
  std::mt19937 rng(11);
  const Pose2 x_WA(0.0, 0.0, 0.1);
  const Pose2 x_WB(0.5, 0.1, 0.2);
  const testing::SyntheticWorld w = round_room(Eigen::Vector2d(x_WB.x, x_WB.y));
  const LaserScan A = testing::make_scan(w, x_WA, 361, 80.0, 0.01, &rng);
  const LaserScan B = testing::make_scan(w, x_WB, 361, 80.0, 0.01, &rng);
  const Pose2 truth = between(x_WA, x_WB);
  const Pose2 u_hat = compose(truth, Pose2(0.21, -0.21, 8.0 * std::numbers::pi / 180.0));
  // A prior wide enough not to decide the outcome (std 0.3 m, 0.15 rad).
  const Eigen::Matrix3d Q = Eigen::Vector3d(0.09, 0.09, 0.0225).asDiagonal();
  ScanMatcherConfig config;
  const ReferenceScan reference = ReferenceScan::from(A, config);
  const std::vector<Eigen::Vector2d> points = scan_points(B, config);
  const std::optional<ScanMatch> m = match_scans(reference, points, u_hat, Q, config);
  ASSERT_TRUE(m.has_value());
  const Pose2 e = between(m->x_AB, truth);
  // (Only the pillars' few points fix the angle: a fraction of the odometry's 0.14 rad error stays.)
  EXPECT_LT(std::hypot(e.x, e.y), 0.02);
  EXPECT_LT(std::abs(e.phi), 0.015);
  ASSERT_TRUE(symmetric_positive_definite(m->covariance));
  const Eigen::Vector3d p(e.x, e.y, e.phi);
  EXPECT_LT(p.dot(m->covariance.ldlt().solve(p)), 16.3);
  // The search's own pose is within half a cell and half an angular step.
  const Pose2 s = between(m->search_pose, truth);
  EXPECT_LT(std::hypot(s.x, s.y), 0.1);
  EXPECT_LT(std::abs(s.phi), 0.02);
  // The refinement alone, started at the odometry increment, keeps most of its
  // angle error (the pillars' points are beyond its gates).
  const std::optional<ScanMatch> local = refine_match(reference, points, u_hat, u_hat, Q, config);
  if (local) {
    const Pose2 l = between(local->x_AB, truth);
    EXPECT_GT(std::abs(l.phi), 0.04) << "local refinement error " << std::hypot(l.x, l.y) << " m, " << l.phi << " rad";
  }
}

// Every usable point of a scan is either oriented (it has a normal) or not.
TEST(ScanMatcher, EveryUsablePointIsOrientedOrUnoriented) {
  ScanMatcherConfig config;
  const LaserScan scan = testing::make_scan(room(), Pose2(0.5, 0.2, 0.3), 361);
  const OrientedPoints p = oriented_points(scan, config);
  EXPECT_EQ(p.points.size() + p.unoriented.size(), scan_points(scan, config).size());
  EXPECT_EQ(p.points.size(), p.normals.size());
  EXPECT_GT(p.unoriented.size(), 0u);  // the corners and the pillar's edges
  const ReferenceScan reference = ReferenceScan::from_points(p, config);
  EXPECT_GT(reference.unoriented_points().size(), 0u);
  EXPECT_LE(reference.unoriented_points().size(), p.unoriented.size());
}

// A wall 20 m ahead of a sparse laser (1° between beams) has its returns
// 0.35 m apart: normal_radius_m alone would give each only one neighbour a
// side. The neighbourhood grows with the beam spacing at the point's range, so
// every return but the wall's outermost on each side has a normal, facing
// the sensor.
TEST(ScanMatcher, AFarWallFacingASparseLaserHasNormals) {
  testing::SyntheticWorld far_wall;
  far_wall.walls = {{{20.0, -5.0}, {20.0, 5.0}}};
  const LaserScan scan = testing::make_scan(far_wall, Pose2(), 181);
  const ScanMatcherConfig config;
  ASSERT_LT(config.normal_radius_m, 2.0 * 20.0 * scan.angle_increment_rad);
  const std::size_t returns = scan_points(scan, config).size();
  ASSERT_GE(returns, 25u);
  const OrientedPoints p = oriented_points(scan, config);
  EXPECT_EQ(p.points.size(), returns - 2);
  for (const Eigen::Vector2d& n : p.normals) EXPECT_LT(n.x(), -0.99);
}

// A store seen with a sparse laser (1° between beams): one cabinet's face gives
// the refinement its lines; beyond it, 15-24 m away, stock and shelving
// (discs of 0.1-0.3 m, one or two returns each, ranges jumping between
// neighbouring beams) give no normals yet are most of the scan. The search
// scores all of the scan's points, so its field must be drawn from all of the
// reference's: from its oriented points alone, most of the scan would score as
// unseen and the match would be refused for too little overlap.
TEST(ScanMatcher, FarPointsWithoutNormalsStillCountAsOverlap) {
  testing::SyntheticWorld store;
  store.walls = {{{8.0, -6.5}, {8.0, -0.5}}};  // a cabinet's front
  std::mt19937 rng(7);
  std::uniform_real_distribution<double> range(15.0, 24.0), bearing(-std::numbers::pi, std::numbers::pi),
      radius(0.1, 0.3);
  for (int i = 0; i < 500; ++i) {
    const double r = range(rng);
    const double a = bearing(rng);
    store.discs.push_back({{r * std::cos(a), r * std::sin(a)}, radius(rng)});
  }
  const Pose2 x_WA(0.0, 0.0, 0.0);
  const Pose2 x_WB(0.4, 0.05, 0.03);
  const LaserScan A = testing::make_scan(store, x_WA, 181);
  const LaserScan B = testing::make_scan(store, x_WB, 181);
  const Pose2 truth = between(x_WA, x_WB);
  const Pose2 u_hat = compose(truth, Pose2(0.05, -0.03, 0.02));
  const Eigen::Matrix3d Q = odometry_like_covariance(u_hat);
  ScanMatcherConfig config;
  const OrientedPoints reference_points = oriented_points(A, config);
  ASSERT_GT(reference_points.unoriented.size(), reference_points.points.size());
  const std::vector<Eigen::Vector2d> points = scan_points(B, config);

  const std::optional<ScanMatch> m =
      match_scans(ReferenceScan::from_points(reference_points, config), points, u_hat, Q, config);
  ASSERT_TRUE(m.has_value());
  // One face fixes the distance to it and the heading; along it the prior
  // decides. The estimate stays within its covariance.
  const Pose2 e = between(m->x_AB, truth);
  const Eigen::Vector3d p(e.x, e.y, e.phi);
  EXPECT_LT(p.dot(m->covariance.ldlt().solve(p)), 16.3);  // chi2inv(0.999, 3)

  OrientedPoints oriented_only = reference_points;
  oriented_only.unoriented.clear();
  EXPECT_FALSE(match_scans(ReferenceScan::from_points(oriented_only, config), points, u_hat, Q, config).has_value());
}

// A row of thin posts 0.25 m apart and nothing else: shifts by one spacing
// along the row score alike and move every point: ambiguous, refused.
TEST(ScanMatcher, AnAmbiguousSceneIsRefused) {
  testing::SyntheticWorld posts;
  for (int i = -20; i <= 20; ++i) posts.discs.push_back({{3.0, 0.25 * i}, 0.05});
  ScanMatcherConfig config;
  const LaserScan A = testing::make_scan(posts, Pose2(), 361, 20.0);
  const LaserScan B = testing::make_scan(posts, Pose2(0.1, 0.0, 0.0), 361, 20.0);
  const Pose2 u_hat(0.1, 0.0, 0.0);
  const Eigen::Matrix3d Q = odometry_like_covariance(u_hat);
  EXPECT_FALSE(match_scans(ReferenceScan::from(A, config), scan_points(B, config), u_hat, Q, config).has_value());
}

// No usable points, too few, or a reference without normals: no estimate, no crash.
TEST(ScanMatcher, DegenerateInputGivesNoEstimate) {
  ScanMatcherConfig config;
  const Pose2 u(0.5, 0.0, 0.0);
  const Eigen::Matrix3d Q = odometry_like_covariance(u);
  const LaserScan A = testing::make_scan(room(), Pose2(), 361);
  const ReferenceScan reference = ReferenceScan::from(A, config);
  // Everything "no return".
  const LaserScan empty = testing::make_scan(testing::SyntheticWorld{}, Pose2(), 361, 20.0);
  EXPECT_TRUE(scan_points(empty, config).empty());
  EXPECT_FALSE(match_scans(reference, scan_points(empty, config), u, Q, config).has_value());
  EXPECT_FALSE(match_scans(ReferenceScan::from(empty, config), scan_points(A, config), u, Q, config).has_value());
  EXPECT_FALSE(match_scans(ReferenceScan(), scan_points(A, config), u, Q, config).has_value());
  // Non-finite points.
  const std::vector<Eigen::Vector2d> nan_points(100, Eigen::Vector2d(std::nan(""), 1.0));
  EXPECT_FALSE(match_scans(reference, nan_points, u, Q, config).has_value());
  // A handful of points.
  std::vector<Eigen::Vector2d> few = scan_points(A, config);
  few.resize(10);
  EXPECT_FALSE(match_scans(reference, few, u, Q, config).has_value());
  // Points with no counterpart in the reference (a scan from elsewhere, far away).
  std::vector<Eigen::Vector2d> far = scan_points(A, config);
  for (Eigen::Vector2d& p : far) p += Eigen::Vector2d(100.0, 0.0);
  EXPECT_FALSE(match_scans(reference, far, u, Q, config).has_value());
}

TEST(ScanMatcher, BadInputIsRejected) {
  ScanMatcherConfig config;
  const LaserScan A = testing::make_scan(room(), Pose2(), 361);
  const ReferenceScan reference = ReferenceScan::from(A, config);
  const std::vector<Eigen::Vector2d> points = scan_points(A, config);
  const Eigen::Matrix3d Q = Eigen::Matrix3d::Identity() * 1e-3;
  EXPECT_THROW(match_scans(reference, points, Pose2(std::nan(""), 0.0, 0.0), Q, config), std::invalid_argument);
  Eigen::Matrix3d singular = Q;
  singular(2, 2) = 0.0;
  EXPECT_THROW(match_scans(reference, points, Pose2(), singular, config), std::invalid_argument);
  ScanMatcherConfig bad = config;
  bad.last_gate_m = 2.0;  // above first_gate_m
  try {
    bad.validate();
    FAIL() << "expected std::invalid_argument";
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find("first_gate_m"), std::string::npos) << e.what();
  }
  bad = config;
  bad.max_independent_points = 0.0;
  EXPECT_THROW(bad.validate(), std::invalid_argument);
}

TEST(ScanMatcher, ReferencePointsHaveUnitNormalsFacingTheSensor) {
  ScanMatcherConfig config;
  const LaserScan A = testing::make_scan(room(), Pose2(0.5, 0.5, 0.3), 361);
  const ReferenceScan reference = ReferenceScan::from(A, config);
  ASSERT_GT(reference.size(), 250u);
  for (std::size_t i = 0; i < reference.size(); ++i) {
    EXPECT_NEAR(reference.normals()[i].norm(), 1.0, 1e-12);
    EXPECT_LT(reference.normals()[i].dot(reference.points()[i]), 0.0);
  }
}

TEST(ScanMatcher, NearestReferencePointMatchesExhaustiveSearch) {
  ScanMatcherConfig config;
  const ReferenceScan reference = ReferenceScan::from(testing::make_scan(room(), Pose2(0.5, 0.5, 0.3), 361), config);
  std::mt19937 rng(5);
  std::uniform_real_distribution<double> coordinate(-3.0, 11.0);
  for (int trial = 0; trial < 500; ++trial) {
    const Eigen::Vector2d q(coordinate(rng), coordinate(rng));
    for (const double gate : {0.1, 0.25, 0.7}) {
      int expected = -1;
      double best = gate * gate;
      for (std::size_t j = 0; j < reference.size(); ++j) {
        const double d2 = (reference.points()[j] - q).squaredNorm();
        if (d2 < best) {
          best = d2;
          expected = static_cast<int>(j);
        }
      }
      EXPECT_EQ(reference.nearest(q, gate), expected) << q.transpose() << " gate " << gate;
    }
  }
}

}  // namespace
}  // namespace lmf
