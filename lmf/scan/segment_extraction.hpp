// Line segments from one laser scan: split and merge followed by a least-squares
// fit (paper §IV; docs/design.md §4.2).
//
// Steps, all in the sensor (= robot) frame R:
//  1. keep readings in [min_range_m, min(max_range_m, scan.max_range_m - no_return_margin_m)];
//  2. cut the scan into clusters of consecutive valid beams no more than
//     max_point_gap_m apart (an invalid reading also cuts);
//  3. split each cluster recursively at the point farthest from the chord of its
//     end points while that distance exceeds split_distance_m (then also from the
//     fitted line, peeling off outlying end points);
//  4. merge adjacent pieces whose joint fit has every residual below merge_distance_m;
//  5. fit each piece by total least squares (orthogonal regression), end points
//     are the projections of its first and last points on the line;
//  6. drop pieces that are short, have few points or are sparse (clutter such as
//     people's legs in corridors).
//
// The covariance of the (lateral, angular) perturbation p_E of each segment
// comes from the fit and the range noise (derivation in segment_extraction.cpp).
//
// Pure functions, thread-safe.
#pragma once

#include <cstddef>
#include <vector>

#include "lmf/scan/laser_scan.hpp"
#include "lmf/scan/observed_segment.hpp"

namespace lmf {

struct ExtractionConfig {
  // Readings closer than this are sensor errors or the robot itself.
  double min_range_m = 0.05;
  // Readings farther than this are not used (sparse and noisy far away).
  double max_range_m = 30.0;
  // A reading at or beyond scan.max_range_m - no_return_margin_m means "no return".
  double no_return_margin_m = 0.1;
  // Consecutive points farther apart than this belong to different clusters.
  double max_point_gap_m = 0.4;
  // A piece is split while some point is farther than this from the chord of its
  // end points or from its fitted line, so every supporting point of a segment lies
  // within max(split_distance_m, merge_distance_m) of it. Set both to about 3x the
  // true range noise: smaller values shatter noisy walls (at 5 cm noise, 0.10 cuts
  // a 4 m wall into several pieces), larger ones straighten real corners and steps.
  // The defaults match the default 5 cm noise (the simulator's); for the real SICK
  // logs in datasets/ (1-2 cm) 0.06 keeps small steps and recesses apart.
  double split_distance_m = 0.15;
  // Two adjacent pieces are merged when every point lies within this of their joint fit.
  // (A point at the boundary of two pieces goes to the line it is closer to.)
  double merge_distance_m = 0.15;
  // A segment needs at least this many points (>= 2) ...
  int min_points = 6;
  // ... this length (m) ...
  double min_length_m = 0.4;
  // ... and at least this many points per metre of length (0 disables the test).
  double min_points_per_m = 0.0;
  // Standard deviation of one range reading (paper §IV: about ±5 cm), used for the
  // covariance only.
  double range_noise_m = 0.05;

  // Throws std::invalid_argument naming the first invalid field and its value.
  void validate() const;
};

// A segment together with the scan points that support it.
struct ExtractedSegment {
  ObservedSegment segment;
  // Inclusive beam index range: every beam in [first_beam, last_beam] is valid and
  // supports the fit (clusters never span an invalid reading).
  std::size_t first_beam = 0;
  std::size_t last_beam = 0;
  double max_residual_m = 0.0;  // largest orthogonal distance of a supporting point to the line
  double rms_residual_m = 0.0;
};

// Segments of `scan` in beam order (counter-clockwise for a positive angle
// increment). Each segment's frame x_RE has its origin at the midpoint and x
// along the segment oriented so the sensor lies on its left (+y); first_point
// lies on its -x end. Throws std::invalid_argument when `config` is invalid;
// bad readings (NaN, negative, no return) are skipped, never an error.
// The readings step 1 keeps as returns: [min_range_m, this).
double max_valid_range(const LaserScan& scan, const ExtractionConfig& config);

std::vector<ObservedSegment> extract_segments(const LaserScan& scan, const ExtractionConfig& config);

// Same as extract_segments, with the supporting beams and fit residuals.
std::vector<ExtractedSegment> extract_segments_with_support(const LaserScan& scan,
                                                            const ExtractionConfig& config);

}  // namespace lmf
