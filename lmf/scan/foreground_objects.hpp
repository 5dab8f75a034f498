// Small objects standing in front of their surroundings in one scan: people,
// other robots, anything that may move with or across the robot (beyond the
// paper; docs/design.md §10).
//
// The scan matcher assumes a static scene. A robot driving behind another one
// down a corridor sees the other's body at a constant distance ahead while the
// walls say nothing along the corridor: matched against that body, the scans
// "prove" that the robot stands still, and the odometry model learned from
// such matches shrinks its translation scale until the local map is metres
// short. Walls, which the local map is made of, are long; such objects are
// short and nearer than what lies beside them. So beams are grouped into runs
// of consecutive returns whose ranges do not jump by more than
// `min_range_jump_m`; a run is a small foreground object when
//   * its points all lie within `max_extent_m` of its first point, and
//   * on both sides the scan goes on farther away: the neighbouring beam
//     returns from farther (a jump), returns nothing, or is the scan's edge.
// A wall seen at a grazing angle breaks into short runs too, but each has a
// nearer neighbour on one side, so it stays. Static small objects (a pillar, a
// bin) are dropped as well: they are not walls, and the walls remain.
//
// Pure function, thread-safe.
#pragma once

#include <vector>

#include "lmf/scan/laser_scan.hpp"

namespace lmf {

// For each beam of `scan`: true when it returns from a small foreground object.
// `usable[i]` says whether beam i is a return at all (same size as the scan);
// unusable beams are never marked and count as "farther" neighbours.
// max_extent_m <= 0 marks nothing. Throws std::invalid_argument when the sizes
// differ or min_range_jump_m is not positive.
std::vector<bool> small_foreground_objects(const LaserScan& scan, const std::vector<bool>& usable,
                                           double max_extent_m, double min_range_jump_m);

}  // namespace lmf
