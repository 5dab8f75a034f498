// Registration of a local map against the nearby global map (beyond the
// paper; docs/design.md §10, "Global association that survives drift").
//
// The fusion's pairing tests (§5.2-§5.3) judge each pairing in the frame L_r
// the map predicts, with the covariance it predicts. When that prediction is
// wrong by more than it admits (a heading a few degrees off after a long
// drive, an overconfident chain of local maps), the right pairings fail the
// χ² test, the few that pass may be wrong, and nothing brings the frame back.
// The registration looks for L_r where the map's walls are, independently of
// that covariance: points sampled along the local segments are scored against
// a likelihood field of the global segments over a window of poses around the
// predicted one (the correlative search of the scan matcher,
// lmf/scan/correlative_search.hpp). What the fusion does with the result is
// decided in fusion_steps.hpp (`register_frame`).
//
// Pure, thread-safe.
#pragma once

#include <concepts>
#include <optional>
#include <type_traits>
#include <vector>

#include <Eigen/Core>

#include "lmf/geometry/pose2.hpp"

namespace lmf::fusion {

struct FrameRegistrationConfig {
  bool enabled = true;
  // The window searched around the predicted frame: ±window_m in x and y,
  // ±window_rad in heading.
  double window_m = 1.5;
  double window_rad = 0.1;
  // Cell of the likelihood field and spacing of the sampled points (m); the
  // field's σ is twice this. The angular step is the resolution over the
  // farthest local point's distance from L_r (coarser only for a local map
  // beyond any real one's reach: frame_registration.cpp, the work bounds).
  double resolution_m = 0.05;
  // A registration is used only if at least this fraction of the local map's
  // points (likelihood-weighted mean) lie on the global map's walls ...
  double min_score = 0.3;
  // ... and it is not ambiguous (FrameRegistration::ambiguous).
  double ambiguity_ratio = 0.9;
  // The walls must constrain every direction: the smallest eigenvalue of the
  // points' mean translation information (Σ n nᵀ / N, n the wall normals:
  // 0.5 for two perpendicular walls seen equally, 0 in a corridor) at least this.
  double min_constraint = 0.05;
  // The robot's own submaps made from its last this many local maps are left
  // out of the reference: they were placed from the same chain of frames, so
  // they drifted with the frame and cannot tell it is off (they would make
  // the predicted frame score as well as the right one).
  int own_recent_maps = 3;
  // Pairings with the established map (all but those own recent submaps) are
  // a loop closure or a join of two robots' maps, the corrections the map can
  // least afford to get wrong. When the registration found nothing nearby (no
  // pose of the window explains min_score of the local map) although the
  // window held the frame's χ² region relative to a submap, the gate's pairs
  // with that submap are a few segments that happen to line up: refused
  // (FusionReport::unconfirmed_pairs). Beyond the window the gate decides.
  bool confirm_pairings = true;

  // Throws std::invalid_argument naming the first bad field.
  void validate() const;
};

// f(name, field) for every field, with its configuration-file name, in the
// map archive's order (see visit_fields(GlobalMapConfig&, F&&), global_map.hpp).
template <class Config, class F>
  requires std::same_as<std::remove_const_t<Config>, FrameRegistrationConfig>
void visit_fields(Config& c, F&& f) {
  f("enabled", c.enabled);
  f("window_m", c.window_m);
  f("window_rad", c.window_rad);
  f("resolution_m", c.resolution_m);
  f("min_score", c.min_score);
  f("ambiguity_ratio", c.ambiguity_ratio);
  f("min_constraint", c.min_constraint);
  f("own_recent_maps", c.own_recent_maps);
  f("confirm_pairings", c.confirm_pairings);
}

// A segment: its frame (midpoint, x along it) and length.
struct RegistrationSegment {
  Pose2 location;
  double length_m = 0.0;
};

// A point sampled along a segment, with its wall's unit normal.
struct SampledPoint {
  Eigen::Vector2d p;  // in the segments' frame
  Eigen::Vector2d n;
};

// Points every `spacing` (at most) along each segment, ends included.
std::vector<SampledPoint> sample_segments(const std::vector<RegistrationSegment>& segments, double spacing);

// The mean over the points of J Jᵀ, J = ∂(n · (x ⊕ p))/∂(x, y, φ) at x = 0:
// the mean squared displacement of the points across their walls for a small
// change d of the frame is dᵀ M d (M's translation block: Σ n nᵀ / N).
Eigen::Matrix3d mean_point_information(const std::vector<SampledPoint>& points);

struct FrameRegistration {
  Pose2 x_WL;                // the best pose of the window
  double score = 0.0;        // its mean likelihood, [0, 1]
  double prior_score = 0.0;  // the predicted frame's
  // Another pose of the window nearly as good (at least ambiguity_ratio times
  // the best) whose points lie more than two cells from the best's across
  // their walls, or the prediction nearly as good, and not all along one
  // direction (below).
  bool ambiguous = false;
  // When every such pose lies along one direction from the best (x, y, φ in
  // the best pose's frame; unit length): the walls fix the frame but along it
  // (a corridor with a few doors); the registration says nothing along it.
  std::optional<Eigen::Vector3d> unresolved;
  bool degenerate = false;   // the walls leave a direction unconstrained (min_constraint)
  // The angular step of the search (rad): the result's resolution in heading.
  double angular_step_rad = 0.0;
};

// The registration of `local` (segments in L) against `global` (segments in
// W) around the predicted x_WL; nullopt when there is nothing to register
// (no local or no nearby global points, or no pose of the window reaching
// min_score). The config must be valid.
std::optional<FrameRegistration> register_frame(const std::vector<RegistrationSegment>& local,
                                                const std::vector<RegistrationSegment>& global,
                                                const Pose2& x_WL_predicted, const FrameRegistrationConfig& config);

}  // namespace lmf::fusion
