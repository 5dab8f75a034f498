// Free-space evidence of one scan against line segments (beyond the paper).
//
// A beam that crosses a segment's span and returns from well behind it passed
// through where the segment should be. A map segment that most crossing beams
// pass through is not a wall: another robot or a person seen earlier and gone
// since, or a false extraction. A beam that ends on the segment supports it; a
// beam that ends in front of it (occlusion) or has no valid return says
// nothing. Beams at grazing incidence and crossings near the segment's ends
// say nothing either (a small error moves them across the end or along the wall).
#pragma once

#include <vector>

#include "lmf/geometry/pose2.hpp"
#include "lmf/scan/laser_scan.hpp"

namespace lmf {

struct SeeThroughConfig {
  bool enabled = true;
  // A beam passes through a segment if its valid return lies farther than
  // this behind the crossing point, and supports it within this distance (m, > 0).
  double margin_m = 0.3;
  // Crossings closer than this to either end of the segment are ignored (m, >= 0).
  double end_margin_m = 0.1;
  // Beams meeting the segment's line at less than this angle are ignored (rad, in [0, pi/2)).
  double min_incidence_rad = 0.35;
  // Verdict: at least min_beams beams pass through, they are at least
  // min_fraction of the beams that pass through or support it, and their
  // crossings spread over at least min_coverage of the checked length (the
  // segment minus the end margins): a wall the map extended across a doorway,
  // or a pillar seen from a new side, is seen through in part only.
  int min_beams = 5;
  double min_fraction = 1.0;
  double min_coverage = 0.7;

  // Throws std::invalid_argument naming the first invalid field and its value.
  void validate() const;
};

// A segment in the sensor frame: midpoint and direction, and its length.
struct SensorSegment {
  Pose2 location;
  double length_m = 0.0;
};

struct SeeThroughCount {
  int through = 0;            // valid returns behind the segment
  int support = 0;            // valid returns on it
  double through_extent_m = 0.0;  // spread of the through crossings along the segment
  double checked_length_m = 0.0;  // the segment's length minus the end margins
  bool seen_through(const SeeThroughConfig& config) const;
};

// Counts, per segment, the beams of `scan` that pass through it or end on it.
// A reading is a valid return if finite, >= min_range_m and < max_range_m (the
// caller's bounds: those of the segment extraction, so "no return" readings
// are never evidence).
std::vector<SeeThroughCount> count_see_through(const LaserScan& scan, const std::vector<SensorSegment>& segments,
                                               double min_range_m, double max_range_m,
                                               const SeeThroughConfig& config);

}  // namespace lmf
