#include "lmf/front_end/range_noise_estimate.hpp"

#include <cmath>
#include <random>

#include <gtest/gtest.h>

#include "scan/synthetic_scan.hpp"
#include "lmf/front_end/front_end.hpp"

namespace lmf {
namespace {

TEST(RangeNoiseEstimate, IsTheRootOfTheMedianOnceEnoughMatchesGaveEvidence) {
  RangeNoiseEstimate estimate;
  for (std::size_t i = 0; i + 1 < RangeNoiseEstimate::kMinMatches; ++i) estimate.add(4e-6);
  estimate.add(std::nullopt);  // no evidence: not counted
  EXPECT_FALSE(estimate.range_noise_per_m());
  estimate.add(1.0);  // an outlier moves a median by one place only
  ASSERT_TRUE(estimate.range_noise_per_m());
  EXPECT_DOUBLE_EQ(*estimate.range_noise_per_m(), 0.002);
  EXPECT_EQ(estimate.matches(), RangeNoiseEstimate::kMinMatches);
}

TEST(RangeNoiseEstimate, IsNeverBelowZeroAndForgetsBeyondItsWindow) {
  RangeNoiseEstimate estimate;
  for (std::size_t i = 0; i < RangeNoiseEstimate::kWindow; ++i) estimate.add(-1e-6);
  ASSERT_TRUE(estimate.range_noise_per_m());
  EXPECT_EQ(*estimate.range_noise_per_m(), 0.0);
  // Just over half the window new: the median is a new value only where the
  // oldest ones were forgotten.
  const std::size_t newer = RangeNoiseEstimate::kWindow / 2 + 1;
  for (std::size_t i = 0; i < newer; ++i) estimate.add(9e-6);
  EXPECT_DOUBLE_EQ(*estimate.range_noise_per_m(), 0.003);
  EXPECT_EQ(estimate.matches(), RangeNoiseEstimate::kWindow + newer);
}

// range_noise_evidence: the farthest third of the residuals spreads
// wider than the nearest third; for a laser whose noise does not grow with
// range the two thirds spread alike. The residual is the noise along the
// wall's normal, and a hall's long walls are seen obliquely: a 1 %-of-range
// laser shows 0.6-1.7e-5 here (a tenth of k² = 1e-4), a constant one 1e-7.
TEST(RangeNoiseEstimate, EachMatchMeasuresHowItsResidualsGrowWithRange) {
  // A hall 30 m x 8 m seen from near one end: ranges from 1 to 25 m.
  testing::SyntheticWorld hall;
  const Eigen::Vector2d c[4] = {{-2, -4}, {28, -4}, {28, 4}, {-2, 4}};
  for (int i = 0; i < 4; ++i) hall.walls.push_back({c[i], c[(i + 1) % 4]});
  hall.walls.push_back({{10.0, 4.0}, {10.0, 3.0}});
  const Pose2 x_WA(0.0, 0.5, 0.05);
  const Pose2 x_WB(0.5, 0.4, 0.0);
  const Pose2 u_hat = between(x_WA, x_WB);
  const Eigen::Matrix3d Q = Eigen::Vector3d(0.02 * 0.02, 0.02 * 0.02, 0.01 * 0.01).asDiagonal().toDenseMatrix();
  const ScanMatcherConfig config;
  const auto slope2 = [&](double noise_per_m, unsigned seed) {
    std::mt19937 rng(seed);
    const LaserScan A = testing::make_scan(hall, x_WA, 361, 80.0, 0.005, &rng, noise_per_m);
    const LaserScan B = testing::make_scan(hall, x_WB, 361, 80.0, 0.005, &rng, noise_per_m);
    const ReferenceScan reference = ReferenceScan::from(A, config);
    const std::vector<Eigen::Vector2d> points = scan_points(B, config);
    const std::optional<ScanMatch> m = match_scans(reference, points, u_hat, Q, config);
    const std::optional<double> evidence = m ? range_noise_evidence(reference, points, m->x_AB, config) : std::nullopt;
    EXPECT_TRUE(evidence);
    return evidence.value_or(std::nan(""));
  };
  for (const unsigned seed : {1U, 2U, 3U}) {
    EXPECT_GT(slope2(0.01, seed), 3e-6) << seed;
    EXPECT_LT(slope2(0.01, seed), 1e-4) << seed;
    EXPECT_LT(std::abs(slope2(0.0, seed)), 1e-6) << seed;
  }
}

// The front end measures the laser it is given: a robot driving down a 30 m
// hall with a laser whose noise is 1 % of the range, and with one whose noise
// is the same everywhere.
TEST(RangeNoiseEstimate, TheFrontEndMeasuresARangeProportionalLaserAndNotAConstantOne) {
  testing::SyntheticWorld hall;
  const Eigen::Vector2d c[4] = {{-2, -4}, {28, -4}, {28, 4}, {-2, 4}};
  for (int i = 0; i < 4; ++i) hall.walls.push_back({c[i], c[(i + 1) % 4]});
  for (double x = 3.0; x < 26.0; x += 6.0) hall.walls.push_back({{x, 4.0}, {x, 3.2}});
  const auto measured = [&](double noise_m, double noise_per_m, const ScanMatcherConfig& matching = {}) {
    MotionPriorConfig config;
    config.scan_matching = matching;
    config.odometry_prior = OdometryErrorModel::proportional(0.08, 0.08, 0.01, 0.001, 0.0005);
    FrontEnd front_end({config});
    std::mt19937 rng(3);
    for (int k = 0; k < 60; ++k) {
      const Pose2 truth(0.3 * k, 0.2 * std::sin(0.2 * k), 0.03 * std::sin(0.3 * k));
      LaserScan scan = testing::make_scan(hall, truth, 361, 80.0, noise_m, &rng, noise_per_m);
      scan.odometry = truth;
      scan.utime = 200000 * static_cast<int64_t>(k);
      front_end.register_scan(scan);
    }
    EXPECT_EQ(front_end.range_noise_measured(), matching.range_noise_from_residuals);
    EXPECT_EQ(front_end.range_noise().matches() >= RangeNoiseEstimate::kMinMatches, matching.range_noise_from_residuals);
    return front_end.range_noise_per_m();
  };
  const double at_half_percent = measured(0.005, 0.005);
  const double at_one_percent = measured(0.005, 0.01);
  EXPECT_GT(at_half_percent, 0.001);
  EXPECT_GT(at_one_percent, 1.2 * at_half_percent) << "more noise at range measures more";
  EXPECT_LT(measured(0.02, 0.0), 0.001);
  // Not measured where the configuration says so: its value holds throughout.
  ScanMatcherConfig fixed;
  fixed.range_noise_from_residuals = false;
  fixed.range_noise_per_m = 0.007;
  EXPECT_EQ(measured(0.005, 0.01, fixed), 0.007);
}

}  // namespace
}  // namespace lmf
