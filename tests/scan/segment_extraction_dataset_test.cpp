// Segment extraction on real scans (belgioioso, the building of the paper's first experiment).
#include <algorithm>
#include <cmath>
#include <iostream>
#include <vector>

#include <gtest/gtest.h>

#include "lmf/io/carmen.hpp"
#include "lmf/scan/segment_extraction.hpp"
#include "test_support.hpp"

namespace lmf {
namespace {

struct Summary {
  std::size_t segments = 0;
  std::size_t points = 0;
  double worst_m = 0.0;
  double sum_sq = 0.0;
};

// Extracts the first 50 scans and checks every segment against its supporting
// points, recomputing their distances to the line from the ranges.
Summary check_first_scans(const io::CarmenLog& log, const ExtractionConfig& config, double max_distance_m) {
  Summary sum;
  for (std::size_t k = 0; k < 50; ++k) {
    SCOPED_TRACE(::testing::Message() << "scan " << k);
    const LaserScan& scan = log.scans[k];
    const auto segments = extract_segments_with_support(scan, config);
    EXPECT_GE(segments.size(), 2u);
    for (const ExtractedSegment& e : segments) {
      const ObservedSegment& s = e.segment;
      EXPECT_GE(s.length_m, config.min_length_m);
      EXPECT_GE(s.num_points, config.min_points);
      EXPECT_EQ(static_cast<int>(e.last_beam - e.first_beam) + 1, s.num_points);
      // The sensor sees the segment from its left.
      const Pose2 x_ER = inverse(s.location);
      EXPECT_GT(x_ER.transform_point(Eigen::Vector2d::Zero()).y(), 0.0);
      for (std::size_t i = e.first_beam; i <= e.last_beam; ++i) {
        const double d = std::abs(x_ER.transform_point(scan.beam_point(i)).y());
        EXPECT_LE(d, max_distance_m) << "beam " << i;
        sum.worst_m = std::max(sum.worst_m, d);
        sum.sum_sq += d * d;
        ++sum.points;
      }
    }
    sum.segments += segments.size();
  }
  return sum;
}

void print(const char* what, const Summary& s) {
  std::cout << what << ": " << s.segments << " segments, " << s.points << " supporting points, rms distance "
            << std::sqrt(s.sum_sq / static_cast<double>(s.points)) << " m, worst " << s.worst_m << " m\n";
}

TEST(SegmentExtractionDataset, BelgioiosoFirstScansGiveTightSegments) {
  LMF_REQUIRE_DATASETS(datasets);
  const io::CarmenLog log = io::read_carmen_log(datasets / "belgioioso-corrected.log.gz");
  ASSERT_GE(log.scans.size(), 50u);

  // Defaults (tuned for 5 cm noise): points within the split/merge distance.
  const Summary defaults = check_first_scans(log, ExtractionConfig{}, ExtractionConfig{}.split_distance_m + 1e-9);
  print("belgioioso scans 0-49, default config", defaults);
  EXPECT_LT(std::sqrt(defaults.sum_sq / static_cast<double>(defaults.points)), 0.04);

  // Tuned for this SICK's 1-2 cm noise: every point within a few cm of its line.
  ExtractionConfig sick;
  sick.split_distance_m = 0.06;
  sick.merge_distance_m = 0.06;
  sick.range_noise_m = 0.02;
  const Summary tuned = check_first_scans(log, sick, 0.06 + 1e-9);
  print("belgioioso scans 0-49, 6 cm split", tuned);
  EXPECT_LT(std::sqrt(tuned.sum_sq / static_cast<double>(tuned.points)), 0.025);
  // Most of the returns support some segment.
  EXPECT_GT(tuned.points, 50u * 200u);
}

}  // namespace
}  // namespace lmf
