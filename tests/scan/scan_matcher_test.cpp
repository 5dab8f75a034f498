// The scan matcher of the local map's step 1: Jacobians against finite
// differences, a known increment recovered in a room, a corridor's unobservable
// direction left to the odometry prior, and bad input.
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
  const Pose2 u_hat = compose(truth, Pose2(0.15, 0.08, 0.03));
  const Eigen::Matrix3d Q = odometry_like_covariance(u_hat);
  const std::optional<ScanMatch> m =
      match_scans(ReferenceScan::from(A, config), scan_points(B, config), u_hat, Q, config);
  ASSERT_TRUE(m.has_value());
  ASSERT_TRUE(symmetric_positive_definite(m->covariance));
  // Lateral offset and heading come from the walls (in A's frame: y and phi) ...
  EXPECT_NEAR(m->x_AB.y, truth.y, 0.01);      // odometry: 8 cm off
  EXPECT_NEAR(m->x_AB.phi, truth.phi, 0.006);  // odometry: 0.03 rad off
  // ... the along-track position stays the odometry's, with its uncertainty.
  EXPECT_NEAR(m->x_AB.x, u_hat.x, 0.02);
  const Eigen::Matrix3d C = m->covariance;
  EXPECT_GT(C(0, 0), 0.8 * Q(0, 0));
  EXPECT_LT(C(1, 1), 0.1 * Q(1, 1));
  EXPECT_LT(C(2, 2), 0.2 * Q(2, 2));
}

TEST(ScanMatcher, TooFewPointsOrAFarEstimateFallBackToTheOdometry) {
  ScanMatcherConfig config;
  config.enabled = true;
  const LaserScan A = testing::make_scan(room(), Pose2(), 361);
  const ReferenceScan reference = ReferenceScan::from(A, config);
  const Pose2 u(0.5, 0.0, 0.0);
  const Eigen::Matrix3d Q = odometry_like_covariance(u);
  EXPECT_FALSE(match_scans(reference, {}, u, Q, config).has_value());
  // The true motion is 0.8 m, the odometry says 0.5 m with a 4 cm std: the
  // scans agree on ~0.8 m, 7 sigma from the odometry, which the prior test
  // (chi2inv(1 - 1e-4, 3) = 21.1) refuses ...
  const LaserScan B = testing::make_scan(room(), Pose2(0.8, 0.0, 0.0), 361);
  EXPECT_FALSE(match_scans(reference, scan_points(B, config), u, Q, config).has_value());
  // ... and a far looser one lets through.
  config.prior_alpha = 1e-30;
  const std::optional<ScanMatch> unchecked = match_scans(reference, scan_points(B, config), u, Q, config);
  ASSERT_TRUE(unchecked.has_value());
  EXPECT_NEAR(unchecked->x_AB.x, 0.8, 0.05);
  EXPECT_GT(unchecked->prior_distance2, 21.1);
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
  ASSERT_GT(reference.points.size(), 250u);
  for (std::size_t i = 0; i < reference.points.size(); ++i) {
    EXPECT_NEAR(reference.normals[i].norm(), 1.0, 1e-12);
    EXPECT_LT(reference.normals[i].dot(reference.points[i]), 0.0);
  }
}

}  // namespace
}  // namespace lmf
