// Segments that cross (beyond the paper).
//
// Every map segment is a wall face a laser saw, and two wall faces cannot pass
// through each other: where two mapped segments cross, at least one of them is
// wrong. The usual culprit is a short segment fitted to noise at a bad angle
// (the split of a noisy wall at a stray point leaves a piece bounded by
// outliers on opposite sides: on the simulator's 5 cm noise such pieces lie
// 20–60° off the wall they sit on); its direction is the least known of the two.
//
// A proper crossing only: the crossing point lies farther than margin_m from
// every end of both segments (corners, T-junctions and ends that overshoot by
// a few centimetres are not crossings), and the two directions differ by at
// most max_angle_rad (near-perpendicular crossings are what an extent
// extended a little too far across a corner or a doorway looks like: both
// walls are real there).
//
// Pure functions, thread-safe.
#pragma once

#include <numbers>

#include <Eigen/Core>

namespace lmf::fusion {

struct CrossingRule {
  double margin_m = 0.1;            // > 0
  double max_angle_rad = std::numbers::pi / 3;  // in (0, pi/2]
};

// A segment by its end points (W, m).
struct EndPoints {
  Eigen::Vector2d start = Eigen::Vector2d::Zero();
  Eigen::Vector2d end = Eigen::Vector2d::Zero();
};

// True when a and b cross properly under `rule` (see above). Segments shorter
// than twice the margin never do; parallel ones never do.
bool segments_cross(const EndPoints& a, const EndPoints& b, const CrossingRule& rule);

}  // namespace lmf::fusion
