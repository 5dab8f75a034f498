#include "lmf/scan/segment_extraction.hpp"

#include <algorithm>
#include <cmath>
#include <functional>
#include <iostream>
#include <limits>
#include <numbers>
#include <random>
#include <stdexcept>
#include <string>
#include <vector>

#include <Eigen/Dense>
#include <gtest/gtest.h>

#include "scan/synthetic_scan.hpp"
#include "test_support.hpp"

namespace lmf {
namespace {

using testing::Disc;
using testing::make_scan;
using testing::SyntheticWorld;
using testing::Wall;

constexpr double kPi = std::numbers::pi;

// Checks the frame conventions every segment must satisfy.
void expect_well_formed(const ObservedSegment& s) {
  const Eigen::Vector2d d(std::cos(s.location.phi), std::sin(s.location.phi));
  const Eigen::Vector2d mid(s.location.x, s.location.y);
  // The sensor (origin) is on the left: positive y in the segment frame.
  const Eigen::Vector2d sensor_in_E = inverse(s.location).transform_point(Eigen::Vector2d::Zero());
  EXPECT_GT(sensor_in_E.y(), 0.0);
  EXPECT_NEAR((s.last_point - s.first_point).dot(d), s.length_m, 1e-9);
  EXPECT_TRUE(testing::matrices_near(0.5 * (s.first_point + s.last_point), mid, 1e-9));
  EXPECT_TRUE(testing::matrices_near(s.covariance, s.covariance.transpose(), 1e-15));
  EXPECT_GT(s.covariance(0, 0), 0.0);
  EXPECT_GT(s.covariance.determinant(), 0.0);
}

TEST(SegmentExtraction, OneWallInFront) {
  std::mt19937 rng(1);
  const SyntheticWorld world{{{{2.0, -3.0}, {2.0, 3.0}}}, {}};
  const LaserScan scan = make_scan(world, {}, 361, 80.0, 0.01, &rng);
  const auto segments = extract_segments_with_support(scan, ExtractionConfig{});
  ASSERT_EQ(segments.size(), 1u);
  const ObservedSegment& s = segments[0].segment;
  expect_well_formed(s);
  // Direction +y: counter-clockwise scan order, the sensor on the left.
  EXPECT_NEAR(s.location.phi, kPi / 2.0, 0.01);
  EXPECT_NEAR(s.location.x, 2.0, 0.01);
  EXPECT_NEAR(s.location.y, 0.0, 0.05);
  EXPECT_NEAR(s.length_m, 6.0, 0.15);
  EXPECT_NEAR(s.first_point.y(), -3.0, 0.08);
  EXPECT_NEAR(s.last_point.y(), 3.0, 0.08);
  // Every beam that hits the wall supports the segment.
  int hits = 0;
  for (double r : scan.ranges_m) hits += r < 79.0 ? 1 : 0;
  EXPECT_EQ(s.num_points, hits);
  EXPECT_EQ(static_cast<int>(segments[0].last_beam - segments[0].first_beam) + 1, hits);
  EXPECT_LT(segments[0].max_residual_m, 0.05);
}

TEST(SegmentExtraction, CornerGivesTwoSegmentsMeeting) {
  std::mt19937 rng(2);
  const SyntheticWorld world{{{{3.0, -2.0}, {3.0, 2.0}}, {{3.0, 2.0}, {0.5, 2.0}}}, {}};
  const LaserScan scan = make_scan(world, {}, 361, 80.0, 0.01, &rng);
  const auto segments = extract_segments(scan, ExtractionConfig{});
  ASSERT_EQ(segments.size(), 2u);
  for (const auto& s : segments) expect_well_formed(s);
  EXPECT_NEAR(segments[0].location.phi, kPi / 2.0, 0.02);
  EXPECT_NEAR(std::abs(segments[1].location.phi), kPi, 0.02);
  EXPECT_NEAR(segments[0].location.x, 3.0, 0.02);
  EXPECT_NEAR(segments[1].location.y, 2.0, 0.02);
  // They meet at the corner.
  EXPECT_LT((segments[0].last_point - Eigen::Vector2d(3.0, 2.0)).norm(), 0.06);
  EXPECT_LT((segments[1].first_point - Eigen::Vector2d(3.0, 2.0)).norm(), 0.06);
}

TEST(SegmentExtraction, GapInAWallGivesTwoSegments) {
  std::mt19937 rng(3);
  const SyntheticWorld world{{{{2.0, -2.0}, {2.0, -0.3}}, {{2.0, 0.3}, {2.0, 2.0}}}, {}};
  const LaserScan scan = make_scan(world, {}, 361, 80.0, 0.01, &rng);
  const auto segments = extract_segments(scan, ExtractionConfig{});
  ASSERT_EQ(segments.size(), 2u);
  for (const auto& s : segments) {
    expect_well_formed(s);
    EXPECT_NEAR(s.location.phi, kPi / 2.0, 0.02);
    EXPECT_NEAR(s.location.x, 2.0, 0.02);
    EXPECT_NEAR(s.length_m, 1.7, 0.1);
  }
  EXPECT_NEAR(segments[1].first_point.y() - segments[0].last_point.y(), 0.6, 0.06);
}

TEST(SegmentExtraction, PointGapThresholdCutsClusters) {
  // Wall points 1.75 cm apart (2 m away, 0.5° beams).
  const SyntheticWorld world{{{{2.0, -1.0}, {2.0, 1.0}}}, {}};
  const LaserScan scan = make_scan(world);
  ExtractionConfig config;
  config.max_point_gap_m = 0.02;
  EXPECT_EQ(extract_segments(scan, config).size(), 1u);
  config.max_point_gap_m = 0.015;  // every point alone
  EXPECT_TRUE(extract_segments(scan, config).empty());

  // A dropped reading (no return) in the middle cuts the wall in two.
  LaserScan dropped = scan;
  dropped.ranges_m[180] = dropped.max_range_m;
  EXPECT_EQ(extract_segments(dropped, ExtractionConfig{}).size(), 2u);
}

TEST(SegmentExtraction, OutlyingEndReadingIsLeftOut) {
  // A mixed reading at the wall's edge, 25 cm behind it: close enough to stay in
  // the cluster, too far from the line to support it.
  const SyntheticWorld world{{{{2.0, -1.0}, {2.0, 1.0}}}, {}};
  LaserScan scan = make_scan(world);
  std::size_t last_hit = 0;
  for (std::size_t i = 0; i < scan.ranges_m.size(); ++i) {
    if (scan.ranges_m[i] < 79.0) last_hit = i;
  }
  scan.ranges_m[last_hit] += 0.25;
  const auto segments = extract_segments_with_support(scan, ExtractionConfig{});
  ASSERT_EQ(segments.size(), 1u);
  EXPECT_EQ(segments[0].last_beam, last_hit - 1);
  EXPECT_NEAR(segments[0].segment.location.phi, kPi / 2.0, 1e-9);
  EXPECT_LT(segments[0].max_residual_m, 1e-9);
}

TEST(SegmentExtraction, SupportingPointsLieNearTheirLine) {
  // A room at the default (5 cm) noise: whatever the split decides, every
  // supporting point is within the split/merge distance of its line.
  const SyntheticWorld room{{{{4.0, -3.0}, {4.0, 3.0}}, {{4.0, 3.0}, {-1.0, 3.0}}, {{-1.0, -3.0}, {4.0, -3.0}}}, {}};
  const ExtractionConfig config;
  std::mt19937 rng(6);
  int total = 0;
  for (int run = 0; run < 20; ++run) {
    const LaserScan scan = make_scan(room, {}, 361, 80.0, 0.05, &rng);
    const auto segments = extract_segments_with_support(scan, config);
    EXPECT_GE(segments.size(), 3u);
    for (const auto& e : segments) {
      const Pose2 x_ER = inverse(e.segment.location);
      for (std::size_t i = e.first_beam; i <= e.last_beam; ++i) {
        EXPECT_LE(std::abs(x_ER.transform_point(scan.beam_point(i)).y()), config.split_distance_m + 1e-9);
      }
    }
    total += static_cast<int>(segments.size());
  }
  EXPECT_LE(total, 20 * 4);  // mostly one segment per wall
}

TEST(SegmentExtraction, ThinWallFromBothSidesHasOppositeDirections) {
  const SyntheticWorld world{{{{2.0, -1.0}, {2.0, 1.0}}}, {}};
  const Pose2 x_WR1(0.0, 0.0, 0.0);
  const Pose2 x_WR2(4.0, 0.2, kPi);
  const auto seen1 = extract_segments(make_scan(world, x_WR1), ExtractionConfig{});
  const auto seen2 = extract_segments(make_scan(world, x_WR2), ExtractionConfig{});
  ASSERT_EQ(seen1.size(), 1u);
  ASSERT_EQ(seen2.size(), 1u);
  const Pose2 x_WE1 = compose(x_WR1, seen1[0].location);
  const Pose2 x_WE2 = compose(x_WR2, seen2[0].location);
  EXPECT_NEAR(x_WE1.x, 2.0, 1e-6);
  EXPECT_NEAR(x_WE2.x, 2.0, 1e-6);
  EXPECT_NEAR(std::abs(wrap_angle(x_WE1.phi - x_WE2.phi)), kPi, 1e-6);
  EXPECT_NEAR(x_WE1.phi, kPi / 2.0, 1e-6);
  EXPECT_NEAR(x_WE2.phi, -kPi / 2.0, 1e-6);
}

TEST(SegmentExtraction, ClutterGivesNoSegment) {
  // Two legs and a random blob of points: short, curved clusters.
  const SyntheticWorld legs{{}, {Disc{{1.5, 0.3}, 0.06}, Disc{{1.5, 0.0}, 0.06}}};
  EXPECT_TRUE(extract_segments(make_scan(legs), ExtractionConfig{}).empty());

  std::mt19937 rng(4);
  LaserScan blob = make_scan(SyntheticWorld{});
  std::uniform_real_distribution<double> range(1.9, 2.1);
  for (std::size_t i = 170; i < 190; ++i) blob.ranges_m[i] = range(rng);
  EXPECT_TRUE(extract_segments(blob, ExtractionConfig{}).empty());
}

TEST(SegmentExtraction, NoReturnReadingsAreIgnored) {
  // With a 4 m sensor, every miss reads 4 m: an arc of points 3.5 cm apart,
  // which would make segments if it were taken for returns.
  const SyntheticWorld world{{{{2.0, -1.0}, {2.0, 1.0}}}, {}};
  const LaserScan scan = make_scan(world, {}, 361, 4.0);
  const auto segments = extract_segments(scan, ExtractionConfig{});
  ASSERT_EQ(segments.size(), 1u);
  EXPECT_NEAR(segments[0].location.x, 2.0, 1e-6);
  EXPECT_NEAR(segments[0].length_m, 2.0, 0.05);

  // Readings just inside the no-return margin are still "no return".
  LaserScan almost = make_scan(SyntheticWorld{}, {}, 361, 4.0);
  for (double& r : almost.ranges_m) r = 4.0 - 0.5 * ExtractionConfig{}.no_return_margin_m;
  EXPECT_TRUE(extract_segments(almost, ExtractionConfig{}).empty());
  // Control: the same arc below the margin does give segments.
  for (double& r : almost.ranges_m) r = 3.0;
  EXPECT_FALSE(extract_segments(almost, ExtractionConfig{}).empty());
}

TEST(SegmentExtraction, ReadingsBeyondConfiguredRangeAndInvalidOnesAreIgnored) {
  const SyntheticWorld world{{{{2.0, -1.0}, {2.0, 1.0}}, {{6.0, -8.0}, {6.0, 8.0}}}, {}};
  LaserScan scan = make_scan(world);
  ExtractionConfig config;
  config.max_range_m = 5.0;
  auto segments = extract_segments(scan, config);
  ASSERT_EQ(segments.size(), 1u);
  EXPECT_NEAR(segments[0].location.x, 2.0, 1e-6);
  const int near_hits = static_cast<int>(std::count_if(scan.ranges_m.begin(), scan.ranges_m.end(),
                                                       [](double r) { return r < 5.0; }));
  EXPECT_EQ(segments[0].num_points, near_hits);

  // Bad readings (NaN, inf, negative, zero) cut a cluster but never fail.
  const std::size_t front = 180;
  scan.ranges_m[front] = std::nan("");
  scan.ranges_m[front + 1] = -1.0;
  scan.ranges_m[front + 2] = 0.0;
  scan.ranges_m[front + 3] = std::numeric_limits<double>::infinity();
  segments = extract_segments(scan, config);
  ASSERT_EQ(segments.size(), 2u);
  EXPECT_EQ(segments[0].num_points + segments[1].num_points, near_hits - 4);
}

TEST(SegmentExtraction, ClockwiseScanGivesTheSameSegment) {
  const SyntheticWorld world{{{{2.0, -3.0}, {1.0, 3.0}}}, {}};
  const LaserScan ccw = make_scan(world);
  LaserScan cw = ccw;
  cw.angle_min_rad = ccw.beam_angle(ccw.ranges_m.size() - 1);
  cw.angle_increment_rad = -ccw.angle_increment_rad;
  std::reverse(cw.ranges_m.begin(), cw.ranges_m.end());
  const auto a = extract_segments(ccw, ExtractionConfig{});
  const auto b = extract_segments(cw, ExtractionConfig{});
  ASSERT_EQ(a.size(), 1u);
  ASSERT_EQ(b.size(), 1u);
  EXPECT_TRUE(is_near(a[0].location, b[0].location, 1e-9, 1e-9));
  EXPECT_TRUE(testing::matrices_near(a[0].first_point, b[0].first_point, 1e-9));
}

TEST(SegmentExtraction, EmptyAndShortScans) {
  EXPECT_TRUE(extract_segments(LaserScan{}, ExtractionConfig{}).empty());
  LaserScan scan;
  scan.angle_min_rad = 0.0;
  scan.angle_increment_rad = 0.01;
  scan.max_range_m = 10.0;
  scan.ranges_m = {2.0, 2.0, 2.0};
  EXPECT_TRUE(extract_segments(scan, ExtractionConfig{}).empty());
}

TEST(SegmentExtraction, MinPointsAndLengthFilters) {
  const SyntheticWorld world{{{{2.0, -0.3}, {2.0, 0.3}}}, {}};  // 0.6 m, about 34 points
  const LaserScan scan = make_scan(world);
  ExtractionConfig config;
  EXPECT_EQ(extract_segments(scan, config).size(), 1u);
  config.min_length_m = 0.7;
  EXPECT_TRUE(extract_segments(scan, config).empty());
  config = ExtractionConfig{};
  config.min_points = 40;
  EXPECT_TRUE(extract_segments(scan, config).empty());
  config = ExtractionConfig{};
  config.min_points_per_m = 100.0;  // the wall has about 57 points per metre
  EXPECT_TRUE(extract_segments(scan, config).empty());
  config.min_points_per_m = 40.0;
  EXPECT_EQ(extract_segments(scan, config).size(), 1u);
}

// The error p_E = (lateral, angular) of the true wall seen from the estimated
// segment frame: x_true = x_est ⊕ (0, p_y, p_phi).
Eigen::Vector2d perturbation_of_truth(const ObservedSegment& s, const Wall& truth) {
  const Pose2 x_ER = inverse(s.location);
  const Eigen::Vector2d a = x_ER.transform_point(truth.a);
  const Eigen::Vector2d b = x_ER.transform_point(truth.b);
  Eigen::Vector2d t = b - a;
  if (t.x() < 0.0) t = -t;  // same orientation as the estimate
  const double lateral = a.y() - a.x() * t.y() / t.x();
  return {lateral, std::atan2(t.y(), t.x())};
}

struct NeesCase {
  const char* name;
  Wall wall;
};

// Over many noisy repetitions the predicted covariance must match the spread
// of the errors: the mean NEES of a 2-dof error is 2 (std of the mean over
// 500 runs: sqrt(4/500) ≈ 0.09).
TEST(SegmentExtraction, CovarianceIsConsistent) {
  const std::vector<NeesCase> cases = {
      {"oblique wall", {{3.0, -2.0}, {1.5, 2.5}}},
      // Far end at grazing incidence: uneven density, midpoint far from the centroid.
      {"side wall", {{0.5, 1.2}, {6.0, 1.2}}},
  };
  ExtractionConfig config;
  config.range_noise_m = 0.05;
  config.split_distance_m = 0.5;  // the noise must not split the wall
  config.merge_distance_m = 0.5;
  config.max_point_gap_m = 1.0;  // nor cut it where grazing points are sparse
  constexpr int kRuns = 500;
  for (const NeesCase& c : cases) {
    SCOPED_TRACE(c.name);
    std::mt19937 rng(42);
    const SyntheticWorld world{{c.wall}, {}};
    double nees_sum = 0.0;
    Eigen::Matrix2d empirical = Eigen::Matrix2d::Zero();
    Eigen::Matrix2d predicted = Eigen::Matrix2d::Zero();
    int used = 0;
    for (int run = 0; run < kRuns; ++run) {
      const auto segments = extract_segments(make_scan(world, {}, 361, 80.0, config.range_noise_m, &rng), config);
      ASSERT_EQ(segments.size(), 1u) << "run " << run;
      const ObservedSegment& s = segments[0];
      const Eigen::Vector2d p = perturbation_of_truth(s, c.wall);
      nees_sum += p.dot(s.covariance.inverse() * p);
      empirical += p * p.transpose();
      predicted += s.covariance;
      ++used;
    }
    const double nees = nees_sum / used;
    std::cout << c.name << ": mean NEES " << nees << " over " << used << " runs\n";
    EXPECT_GT(nees, 1.6);
    EXPECT_LT(nees, 2.4);
    empirical /= used;
    predicted /= used;
    // Each variance within 25 % (the sampling error of a variance over 500 runs is
    // about 6 %; at 5 cm noise and grazing incidence the fit's second-order error adds
    // about 14 % on the side wall, measured over 5000 runs; it vanishes at 5 mm).
    EXPECT_NEAR(empirical(0, 0) / predicted(0, 0), 1.0, 0.25);
    EXPECT_NEAR(empirical(1, 1) / predicted(1, 1), 1.0, 0.25);
  }
}

TEST(ExtractionConfig, DefaultsAreValid) { EXPECT_NO_THROW(ExtractionConfig{}.validate()); }

TEST(ExtractionConfig, InvalidFieldsAreNamed) {
  struct BadField {
    const char* field;
    std::function<void(ExtractionConfig&)> spoil;
  };
  const double nan = std::nan("");
  const std::vector<BadField> bad = {
      {"min_range_m", [](ExtractionConfig& c) { c.min_range_m = -0.1; }},
      {"min_range_m", [nan](ExtractionConfig& c) { c.min_range_m = nan; }},
      {"max_range_m", [](ExtractionConfig& c) { c.max_range_m = 0.01; }},
      {"no_return_margin_m", [](ExtractionConfig& c) { c.no_return_margin_m = -1.0; }},
      {"max_point_gap_m", [](ExtractionConfig& c) { c.max_point_gap_m = 0.0; }},
      {"split_distance_m", [](ExtractionConfig& c) { c.split_distance_m = -0.1; }},
      {"merge_distance_m", [nan](ExtractionConfig& c) { c.merge_distance_m = nan; }},
      {"min_points", [](ExtractionConfig& c) { c.min_points = 1; }},
      {"min_length_m", [](ExtractionConfig& c) { c.min_length_m = -1.0; }},
      {"min_points_per_m", [](ExtractionConfig& c) { c.min_points_per_m = -2.0; }},
      {"range_noise_m", [](ExtractionConfig& c) { c.range_noise_m = 0.0; }},
  };
  for (const BadField& b : bad) {
    ExtractionConfig config;
    b.spoil(config);
    try {
      config.validate();
      ADD_FAILURE() << b.field << ": no exception";
    } catch (const std::invalid_argument& e) {
      EXPECT_NE(std::string(e.what()).find(std::string("ExtractionConfig.") + b.field), std::string::npos)
          << e.what();
    }
    // extract_segments validates too.
    EXPECT_THROW(extract_segments(LaserScan{}, config), std::invalid_argument) << b.field;
  }
}

}  // namespace
}  // namespace lmf
