#include "lmf/spmap/segment_ops.hpp"

#include <cmath>
#include <limits>
#include <numbers>
#include <stdexcept>
#include <string>

#include <Eigen/Eigenvalues>
#include <gtest/gtest.h>

#include "lmf/spmap/covariance_check.hpp"
#include "lmf/spmap/ekf.hpp"
#include "spmap_test_util.hpp"
#include "test_support.hpp"

namespace lmf::spmap {
namespace {

using lmf::testing::matrices_near;

TEST(SegmentOps, ProjectExtentAndOverlap) {
  // B centred at x = 3 on S's axis, length 4: [1, 5]; S is [-2, 2].
  const Interval i = project_extent(Pose2(3.0, 0.1, 0.0), 4.0);
  EXPECT_NEAR(i.min, 1.0, 1e-12);
  EXPECT_NEAR(i.max, 5.0, 1e-12);
  EXPECT_NEAR(extent_overlap(Pose2(3.0, 0.1, 0.0), 4.0, 4.0), 1.0, 1e-12);
  // Opposite direction: same interval.
  const Interval flipped = project_extent(Pose2(3.0, 0.0, std::numbers::pi), 4.0);
  EXPECT_NEAR(flipped.min, 1.0, 1e-12);
  EXPECT_NEAR(flipped.max, 5.0, 1e-12);
  // Apart: negative overlap is the gap.
  EXPECT_NEAR(extent_overlap(Pose2(6.0, 0.0, 0.0), 2.0, 2.0), -4.0, 1e-12);
  // Rotated by 90 degrees: B projects to a point.
  const Interval point = project_extent(Pose2(0.5, 1.0, std::numbers::pi / 2), 2.0);
  EXPECT_NEAR(point.max - point.min, 0.0, 1e-12);
}

// Variance of the lateral error at the point `x_along` (m, in the segment's frame).
double lateral_variance_at(const StochasticMap& map, EntityId s, double x_along) {
  const Eigen::Vector2d a(1.0, x_along);
  return a.dot(map.block(s, s) * a);
}

TEST(SegmentOps, ExtendSegmentKeepsCovarianceMeaning) {
  std::mt19937 rng(41);
  StochasticMap map;
  const EntityId R = map.add(EntityKind::kRobot, Pose2(0.3, 0.1, 0.2));
  const EntityId S = map.add(EntityKind::kSegment, Pose2(1.0, 2.0, 0.3), std::nullopt, 2.0);
  map.mutable_covariance() = test::random_spd(map.dimension(), rng, 0.01);
  const Pose2 x_before = map.entity(S).location;
  const Eigen::MatrixXd cross_before = map.block(R, S);
  const double physical_x = 0.7;  // in the old frame
  const Eigen::Vector2d point = x_before.transform_point({physical_x, 0.0});
  const double var_before = lateral_variance_at(map, S, physical_x);

  extend_segment(map, S, Interval{-0.5, 3.0});  // new extent [-1, 3]: dx = 1
  const Entity& s = map.entity(S);
  EXPECT_DOUBLE_EQ(s.length_m, 4.0);
  EXPECT_TRUE(is_near(s.location, compose(x_before, Pose2(1.0, 0.0, 0.0)), 1e-12, 1e-12));
  // The same physical point, seen from the moved frame.
  const Eigen::Vector2d local = between(s.location, Pose2(point.x(), point.y(), 0.0)).vector().head<2>();
  EXPECT_NEAR(local.y(), 0.0, 1e-12);
  EXPECT_NEAR(lateral_variance_at(map, S, local.x()), var_before, 1e-15);
  // Cross-covariances follow: Cov(p_R, lateral at the point) is unchanged.
  const Eigen::Vector2d a_before(1.0, physical_x);
  const Eigen::Vector2d a_after(1.0, local.x());
  EXPECT_TRUE(matrices_near(map.block(R, S) * a_after, cross_before * a_before, 1e-15));
  EXPECT_TRUE(check_covariance(map.covariance()).ok());

  // Already covered: nothing changes.
  const Eigen::MatrixXd P = map.covariance();
  extend_segment(map, S, Interval{-1.0, 2.0});
  EXPECT_DOUBLE_EQ(map.entity(S).length_m, 4.0);
  EXPECT_TRUE(matrices_near(map.covariance(), P, 0.0));

  EXPECT_THROW(extend_segment(map, R, Interval{0.0, 1.0}), std::invalid_argument);
  EXPECT_THROW(extend_segment(map, S, Interval{1.0, 0.0}), std::invalid_argument);
}

TEST(SegmentOps, FuseCollinearOverlappingSegments) {
  StochasticMap map;
  const EntityId R = map.add(EntityKind::kRobot, Pose2(0.0, -1.0, 0.0));
  const EntityId F = map.add(EntityKind::kFrame, Pose2(0.0, 0.0, 0.0));
  // keep: x in [-2, 2] on y = 0; drop: x in [1, 5], 2 cm off, slightly rotated,
  // stored in a submap frame F (global-map layout).
  const EntityId keep = map.add(EntityKind::kSegment, Pose2(0.0, 0.0, 0.0), std::nullopt, 4.0);
  const EntityId drop = map.add(EntityKind::kSegment, Pose2(3.0, 0.02, 0.005), F, 4.0);
  Eigen::MatrixXd P = Eigen::MatrixXd::Zero(map.dimension(), map.dimension());
  P.block(0, 0, 3, 3) = Eigen::Vector3d(0.01, 0.01, 0.001).asDiagonal();
  P.block(3, 3, 3, 3) = Eigen::Vector3d(1e-4, 1e-4, 1e-5).asDiagonal();
  P.block(6, 6, 2, 2) = Eigen::Vector2d(4e-4, 1e-4).asDiagonal();
  P.block(8, 8, 2, 2) = Eigen::Vector2d(4e-4, 1e-4).asDiagonal();
  P(0, 7) = P(7, 0) = 1e-4;  // robot correlated with keep
  map.mutable_covariance() = P;

  ASSERT_TRUE(fuse_segments(map, keep, drop, 0.05));
  EXPECT_FALSE(map.contains(drop));
  EXPECT_EQ(map.dimension(), 8);
  const Entity& k = map.entity(keep);
  const Pose2 x = map.root_location(keep);
  const Eigen::Vector2d a = x.transform_point({-0.5 * k.length_m, 0.0});
  const Eigen::Vector2d b = x.transform_point({0.5 * k.length_m, 0.0});
  EXPECT_NEAR(a.x(), -2.0, 0.02);
  EXPECT_NEAR(b.x(), 5.0, 0.02);
  EXPECT_NEAR(k.length_m, 7.0, 0.02);
  EXPECT_NEAR(a.y(), 0.0, 0.05);
  EXPECT_NEAR(b.y(), 0.0, 0.05);
  const CovarianceHealth health = check_covariance(map.covariance());
  EXPECT_TRUE(health.ok()) << health.describe();
  EXPECT_TRUE(map.contains(R));
}

TEST(SegmentOps, FuseRefusesIncompatibleAndChangesNothing) {
  StochasticMap map;
  const EntityId keep = map.add(EntityKind::kSegment, Pose2(0.0, 0.0, 0.0), std::nullopt, 4.0);
  const EntityId drop = map.add(EntityKind::kSegment, Pose2(3.0, 0.5, 0.0), std::nullopt, 4.0);
  map.mutable_covariance() = Eigen::Vector4d(1e-4, 1e-5, 1e-4, 1e-5).asDiagonal();
  const StochasticMap before = map;
  EXPECT_FALSE(fuse_segments(map, keep, drop, 0.05));
  EXPECT_TRUE(map.contains(drop));
  EXPECT_TRUE(matrices_near(map.covariance(), before.covariance(), 0.0));
  EXPECT_TRUE(is_near(map.entity(keep).location, before.entity(keep).location, 0.0, 0.0));
  EXPECT_DOUBLE_EQ(map.entity(keep).length_m, 4.0);

  EXPECT_THROW(fuse_segments(map, keep, keep, 0.05), std::invalid_argument);
  const EntityId robot = map.add(EntityKind::kRobot, Pose2());
  EXPECT_THROW(fuse_segments(map, keep, robot, 0.05), std::invalid_argument);
}

TEST(CovarianceCheck, FlagsAsymmetricAndIndefinite) {
  Eigen::Matrix3d good;
  good << 2, 0.5, 0, 0.5, 1, 0.1, 0, 0.1, 0.5;
  EXPECT_TRUE(check_covariance(good).ok());
  EXPECT_TRUE(check_covariance(Eigen::MatrixXd::Zero(3, 3)).ok());  // PSD, singular

  Eigen::Matrix3d asym = good;
  asym(0, 2) += 1e-3;
  const CovarianceHealth h_asym = check_covariance(asym);
  EXPECT_FALSE(h_asym.symmetric);
  EXPECT_FALSE(h_asym.ok());
  EXPECT_NEAR(h_asym.max_asymmetry, 1e-3, 1e-12);

  Eigen::Matrix2d indefinite;
  indefinite << 1, 2, 2, 1;  // eigenvalues 3, -1
  const CovarianceHealth h_ind = check_covariance(indefinite);
  EXPECT_TRUE(h_ind.symmetric);
  EXPECT_FALSE(h_ind.positive_semidefinite);
  ASSERT_TRUE(h_ind.min_eigenvalue.has_value());
  EXPECT_NEAR(*h_ind.min_eigenvalue, -1.0, 1e-12);
  EXPECT_FALSE(h_ind.describe().empty());

  Eigen::Matrix2d nan = Eigen::Matrix2d::Identity();
  nan(1, 1) = std::numeric_limits<double>::quiet_NaN();
  EXPECT_FALSE(check_covariance(nan).ok());
}

// Sizes below and above the switch from the left-looking Cholesky to
// Eigen::LLT (100 rows) must give the same verdicts.
TEST(CovarianceCheck, SameVerdictsForSmallAndLargeMatrices) {
  for (const int n : {5, 63, 100, 101, 140}) {
    SCOPED_TRACE("n = " + std::to_string(n));
    // Rank n/3 (singular, PSD) with a wide spread of scales.
    Eigen::MatrixXd A = Eigen::MatrixXd::Random(n, std::max(1, n / 3));
    A.row(0) *= 1e3;
    const Eigen::MatrixXd singular = A * A.transpose();
    EXPECT_TRUE(check_covariance(singular).ok());
    const Eigen::MatrixXd full = singular + Eigen::MatrixXd::Identity(n, n);
    const CovarianceHealth ok = check_covariance(full);
    EXPECT_TRUE(ok.ok());
    EXPECT_FALSE(ok.min_eigenvalue.has_value());  // certified by the factorisation alone

    // One eigenvalue pushed to -1e-5 x the largest variance: 1e4 times the
    // tolerance (1e-9 x that variance).
    const double negative = -1e-5 * full.diagonal().maxCoeff();
    const Eigen::SelfAdjointEigenSolver<Eigen::MatrixXd> es(full);
    Eigen::VectorXd lambda = es.eigenvalues();
    lambda(0) = negative;
    const Eigen::MatrixXd indefinite = es.eigenvectors() * lambda.asDiagonal() * es.eigenvectors().transpose();
    const CovarianceHealth bad = check_covariance(0.5 * (indefinite + indefinite.transpose()));
    EXPECT_TRUE(bad.symmetric);
    EXPECT_FALSE(bad.positive_semidefinite);
    ASSERT_TRUE(bad.min_eigenvalue.has_value());
    EXPECT_NEAR(*bad.min_eigenvalue, negative, 1e-3 * std::abs(negative));

    // Entries that overflow inside the factorisation, an inf and a NaN.
    Eigen::MatrixXd huge = full;
    huge(n - 1, 0) = huge(0, n - 1) = 1e300;
    EXPECT_FALSE(check_covariance(huge).ok());
    Eigen::MatrixXd inf = full;
    inf(n / 2, n / 2) = std::numeric_limits<double>::infinity();
    EXPECT_FALSE(check_covariance(inf).ok());
    Eigen::MatrixXd nan = full;
    nan(0, n - 1) = std::numeric_limits<double>::quiet_NaN();  // upper triangle only
    EXPECT_FALSE(check_covariance(nan).ok());
  }
}

}  // namespace
}  // namespace lmf::spmap
