// The directions of a set of walls, modulo π, weighted by their length: which
// headings can line one map's walls up with another's (place_recognition.cpp).
// A point of a wall lies on another map's wall only where a wall of that map
// runs in its direction, or where one crosses it (a point or two); so a
// heading at which the walls of one map parallel little of the other's length
// cannot score a place, and need not be searched.
//
// Pure, thread-safe once built.
#pragma once

#include <vector>

#include "lmf/fusion/frame_registration.hpp"

namespace lmf::fusion {

class WallDirections {
 public:
  explicit WallDirections(const std::vector<RegistrationSegment>& walls);

  // Whether some wall runs within ±tolerance (rad) of `direction`, modulo π.
  bool any_within(double direction, double tolerance) const;

 private:
  static constexpr int kBins = 720;  // of π / 720 = 0.25°
  std::vector<double> cumulative_;   // length in bins [0, i), i = 0 .. 3 kBins (three turns of π, for wrapping)
};

// The share of the walls of `local` (by length) that some wall of `global`
// parallels when `local` is turned by `heading`: wall j counts when a global
// direction lies within the search's angular step plus the turn that moves
// its ends by one cell (resolution_m / (L_j / 2)) of its turned direction.
double parallel_share(const std::vector<RegistrationSegment>& local, const WallDirections& global, double heading,
                      double angular_step_rad, double resolution_m);

}  // namespace lmf::fusion
