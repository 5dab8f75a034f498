// Place recognition of a local map in the whole global map (beyond the paper;
// docs/design.md §10, "Place recognition", issue 38 item 1).
//
// The frame registration (frame_registration.hpp) looks for L_r only within a
// window around the frame the map predicts. A robot that has not joined has
// no prediction at all, and one whose frame drifted beyond the window has a
// wrong one. Place recognition searches everywhere:
//  1. a global search: points sampled along the local segments every
//     `resolution_m` are scored against a likelihood field of all the global
//     segments at that coarse cell, at every heading (the step moves the
//     farthest local point by one cell) at which the local walls parallel
//     enough of the global ones to reach the search's floor
//     (wall_directions.hpp), and every translation that puts the
//     local map over the global one, by the branch and bound of the scan
//     matcher (lmf/scan/correlative_search.hpp; Hess et al. 2016, §V, the
//     global constraint search);
//  2. each distinct peak of that search (up to `max_candidates`, the best
//     first) refined by the frame registration around it, at its fine cell;
//  3. the best refined candidate accepted only when it reaches min_score, is
//     constrained in every direction (the registration's min_constraint),
//     unambiguous within its own window, and no other refined candidate
//     elsewhere scores at least the registration's ambiguity_ratio times its
//     score. Otherwise nothing is placed and the outcome says why.
//
// Pure, thread-safe.
#pragma once

#include <concepts>
#include <type_traits>
#include <vector>

#include "lmf/fusion/frame_registration.hpp"
#include "lmf/geometry/pose2.hpp"

namespace lmf::fusion {

struct PlaceRecognitionConfig {
  // A robot without a sighting joins where its local map is recognised. Off
  // by default: with it on, the demo's simulated building (rooms alike) made
  // one wrong join while the right place was not mapped yet, which the
  // ambiguity test cannot see (docs/results.md, "Place recognition").
  bool enabled = false;
  // Cell (m) of the global search's likelihood field, also its σ and the
  // spacing of the sampled local points: eight of the registration's cells;
  // each peak is refined within ± two of these cells (0.8 m), inside the
  // registration's own window (window_m 1.5).
  double resolution_m = 0.4;
  // A place explains at least this fraction of the local map's sampled points
  // (the registration's mean likelihood): most of the local map, two of every
  // three metres of its walls, lies on walls the global map already has. A
  // chance fit in a building of many walls explains about half of a local map
  // (each of its walls finds some wall near it at some pose; docs/results.md).
  double min_score = 2.0 / 3.0;
  // Distinct peaks of the global search refined, the best first.
  int max_candidates = 8;

  // Throws std::invalid_argument naming the first bad field.
  void validate() const;
};

template <class Config, class F>
  requires std::same_as<std::remove_const_t<Config>, PlaceRecognitionConfig>
void visit_fields(Config& c, F&& f) {
  f("enabled", c.enabled);
  f("resolution_m", c.resolution_m);
  f("min_score", c.min_score);
  f("max_candidates", c.max_candidates);
}

enum class PlaceOutcome {
  kPlaced,      // one place, constrained and unambiguous
  kNotFound,    // nothing explains min_score of the local map (or nothing to search)
  kAmbiguous,   // a second place elsewhere explains it nearly as well
  kDegenerate,  // the local map's walls leave a direction open (a corridor)
};
const char* to_string(PlaceOutcome outcome);

struct PlaceRecognition {
  PlaceOutcome outcome = PlaceOutcome::kNotFound;
  Pose2 x_WL;                // the best place (meaningful unless kNotFound)
  double score = 0.0;        // its refined score, [0, 1]
  double rival_score = 0.0;  // the best distinct other place's refined score (0: none)
  int candidates = 0;        // distinct peaks of the global search
  // The registration's cell and angular step at the best place: the
  // resolution of x_WL.
  double resolution_m = 0.0;
  double angular_step_rad = 0.0;
};

// Where the local map (segments in L) lies in the global map (segments in W).
// Both configs must be valid.
PlaceRecognition recognise_place(const std::vector<RegistrationSegment>& local,
                                 const std::vector<RegistrationSegment>& global,
                                 const FrameRegistrationConfig& registration, const PlaceRecognitionConfig& config);

}  // namespace lmf::fusion
