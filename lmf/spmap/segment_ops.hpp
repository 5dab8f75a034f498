// Geometric operations on segment entities that the EKF does not handle: extent
// overlap, endpoint (geometric) update with the frame-shift rule, and fusion of
// two map segments that are the same wall (docs/design.md §3, §4.6–4.7, §5.4).
#pragma once

#include <Eigen/Core>

#include "lmf/geometry/pose2.hpp"
#include "lmf/spmap/stochastic_map.hpp"

namespace lmf::spmap {

// Extent of segment B (location x_SB relative to segment S's frame, length
// length_B) projected on S's x axis: [min, max] in metres.
struct Interval {
  double min = 0.0;
  double max = 0.0;
};
Interval project_extent(const Pose2& x_SB, double length_B);

// Length of the overlap of S's extent [-length_S/2, length_S/2] and B's
// projection, negative when they are apart (the gap).
double extent_overlap(const Pose2& x_SB, double length_S, double length_B);

// Extends segment `s` so its extent covers [interval.min, interval.max] of its
// own axis (or keeps it if already covered): moves its frame by
// dx = (new_min + new_max)/2, sets the new length, and transforms P with
// segment_frame_shift(dx). Throws std::invalid_argument if `s` is not a segment
// or the interval is not finite with min <= max. (Entities whose parent is `s`
// would not be moved back; segments have no children in lmf.)
void extend_segment(StochasticMap& map, EntityId s, const Interval& interval_in_s);

// Fuses `drop` into `keep` (both segments of `map`): applies the perfect
// constraint B(⊖x_keep ⊕ x_drop) = 0 as an EKF update (careful inversion),
// extends `keep` to cover both extents, and removes `drop`. Returns false (and
// changes nothing) if the two are not compatible at `alpha` (individual test on
// the lateral and angular rows; opposite directions never pass). The two may
// have different parents (segments of two submaps). Throws
// std::invalid_argument if either is not a segment, they are the same, or
// `drop` has children.
bool fuse_segments(StochasticMap& map, EntityId keep, EntityId drop, double alpha);

}  // namespace lmf::spmap
