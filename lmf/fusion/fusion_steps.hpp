// The fusion of one local map into the global map, step by step (paper §II.C,
// §III; docs/design.md §5 steps 1-7, then the steps beyond the paper). GlobalMap::fuse
// runs them in this order on one FusionContext; each reads what the earlier
// ones left there and adds its own part, and each can be run and timed on its own.
//
//   step 1   augment                          P⁻ = [[P, 0], [0, P_Mr]] (eq. 4)
//   beyond   relocate_frame                   registration against the nearby map
//   step 2   gate                             cheap geometric pre-filter of the pairs
//   step 2   test_individual_compatibility    eq. (12) measurements, chi2 (eq. 8) + overlap
//   step 3   test_joint_compatibility         incremental joint compatibility
//   step 3   update_with_pairings             one EKF update (eq. 9), careful inversion (§6)
//   step 4   update_geometry                  extend paired globals, drop used locals,
//                                             fuse globals that matched one local segment
//   step 5   make_new_submap                  unpaired local segments: new submap F_new
//   step 6   advance_robot_frame              L_r ← L_r ⊕ x_R, robot removed
//   step 7   connect_submaps                  environment graph edges
//   beyond   remove_footprint_segments        robot bodies (robot_footprints.hpp)
//   beyond   remove_crossing_segments         the less certain of two crossing segments
//   then     FusionContext::removals leave the state, and check_health.
//
// Pure and synchronous; not thread-safe (the context refers to the map's state).
#pragma once

#include <cstddef>
#include <optional>
#include <set>
#include <utility>
#include <vector>

#include <Eigen/Core>

#include "lmf/fusion/environment_graph.hpp"
#include "lmf/fusion/global_map.hpp"
#include "lmf/fusion/global_state.hpp"
#include "lmf/fusion/robot_arrivals.hpp"
#include "lmf/fusion/robot_footprints.hpp"
#include "lmf/geometry/pose2.hpp"
#include "lmf/local_map/local_map_snapshot.hpp"
#include "lmf/spmap/ekf.hpp"
#include "lmf/spmap/estimator.hpp"

namespace lmf::fusion {

// A pairing (global segment S_i, local segment S_j) that passed the gate.
struct PairingCandidate {
  EntityId global_segment = 0;
  EntityId local_segment = 0;
  std::size_t local_index = 0;
  spmap::ImplicitMeasurement measurement;  // eq. (12); moved to accepted_measurements when accepted
  Eigen::Index row = 0;                    // its first row in the gated pairs' joint innovation
  double distance2 = 0.0;                  // individual chi2 distance
};

// What the steps of one fusion share. The inputs are fixed at construction;
// each step fills its part, in step order.
struct FusionContext {
  // `frame`: the local map's frame L_r in the state; `anchored_robot`: its robot
  // R when the map was anchored backwards (R then already in the state).
  FusionContext(GlobalState& state, const GlobalMapConfig& config, int robot_id, const LocalMapSnapshot& snapshot,
                const RobotArrivals::FrameSlot& frame);

  bool anchored() const { return anchored_robot.has_value(); }

  GlobalState& state;
  const GlobalMapConfig& config;
  const int robot_id;
  const LocalMapSnapshot& snapshot;
  const EntityId L;
  const std::optional<EntityId> anchored_robot;
  const spmap::CarefulTolerance careful;  // the config's careful-inversion tolerance
  spmap::Chi2Table chi2;                  // at GlobalMapConfig::alpha
  FusionReport report;

  // The robot's own recent submaps, which the registration leaves out
  // (relocate_frame; FrameRegistrationConfig::own_recent_maps): filled when
  // the registration runs.
  std::set<EntityId> own_recent_submaps;

  // Step 1: the robot R and the local segments S_j in the state (children of L).
  EntityId R = 0;
  std::vector<EntityId> local;
  // Step 2: gated pairs (global segment, index into `local`), their joint
  // innovation, and the pairs that passed the individual and overlap tests.
  std::vector<std::pair<EntityId, std::size_t>> gated;
  spmap::Innovation gated_innovation;
  Eigen::VectorXd gated_h;  // their stacked ĥ, rows as in gated_innovation
  std::vector<PairingCandidate> candidates;
  // Step 3: the jointly compatible candidates (indices into `candidates`) and their measurements.
  std::vector<std::size_t> accepted;
  std::vector<spmap::ImplicitMeasurement> accepted_measurements;
  // Step 4: which local segments were paired, the submaps the pairings touched,
  // and the entities leaving the state at the end (steps 4-9 add to it).
  std::vector<bool> paired;
  std::set<EntityId> touched_submaps;
  std::vector<EntityId> removals;
  // Step 5: the local segments that stay, children of the new submap.
  std::vector<EntityId> unpaired;
  // Step 6: L_r as fused, before it advanced.
  Pose2 x_WL_fused;
  Eigen::Matrix3d cov_L_fused = Eigen::Matrix3d::Zero();
};

// Step 1 (eq. 4): the robot and the local segments enter the state as children
// of L_r, independent of the map; P_Mr is the shipped covariance times
// GlobalMapConfig::local_map_covariance_scale.
void augment(FusionContext& f);

// Beyond the paper, before the pairing tests: the local map registered
// against the nearby global map (frame_registration.hpp). When the registered
// frame contradicts the predicted one (χ², 3 dof, at `alpha`, in the frame's
// covariance plus the registration's resolution) and the registration is
// neither ambiguous nor degenerate, L_r moves there (its children with it)
// and its covariance grows by the move, diag(δ_x², δ_y², δ_φ²): the
// prediction was overconfident by that much, and the pairing tests then judge
// the pairings from the registered frame. Otherwise nothing changes. Where
// the walls leave one direction u open (FrameRegistration::unresolved), δ
// keeps the prediction along u. The robot's own recent submaps (`graph`,
// own_recent_maps) are not registered against.
void relocate_frame(FusionContext& f, const EnvironmentGraph& graph);

// Step 2: the geometric gate between every global segment (outside L_r) and
// every local segment; fills `gated` and the report's funnel counts. When the
// registration found nothing nearby where its window held the frame
// (FrameRegistrationConfig::confirm_pairings), pairs with submaps other than
// the robot's own recent ones are counted as unconfirmed instead.
void gate(FusionContext& f);

// Step 2: implicit measurements of the gated pairs (eq. 12), the individual chi2
// test (eq. 8) and the overlap test; several pairings per local segment allowed.
void test_individual_compatibility(FusionContext& f);

// Step 3: incremental joint compatibility, best individual distance first.
void test_joint_compatibility(FusionContext& f);

// Step 3: one EKF update with every accepted pairing (eq. 9, docs/design.md §6).
void update_with_pairings(FusionContext& f);

// Step 4: geometric update of the paired global segments, removal of the used
// local segments, fusion of global segments that matched one local segment.
void update_geometry(FusionContext& f);

// Step 5: the unpaired local segments stay; their frame becomes a submap (a
// copy of L_r with its correlations, or L_r itself for a backward-anchored map).
void make_new_submap(FusionContext& f, EnvironmentGraph& graph);

// Step 6: L_r ← L_r ⊕ x_R and the robot leaves; the robot's frames no longer
// needed go; the fused frame is remembered for late sightings.
void advance_robot_frame(FusionContext& f, RobotArrivals& arrivals, const EnvironmentGraph& graph);

// Step 7: the submaps this local map touched become neighbours in the graph.
void connect_submaps(FusionContext& f, EnvironmentGraph& graph);

// Beyond the paper: adds the map's scan poses (in W, L_r as fused) to the
// footprints and removes every segment inside a footprint (robot_footprints.hpp).
void remove_footprint_segments(FusionContext& f, RobotFootprints& footprints);

// Beyond the paper: for each new segment crossing another one staying in the
// map, the one of the two with the larger angular variance leaves
// (crossing_segments.hpp).
void remove_crossing_segments(FusionContext& f);

// Covariance supervision after the removals (GlobalMapConfig::health):
// `current_frame` is the robot's frame after the fusion.
void check_health(FusionContext& f, EntityId current_frame);

}  // namespace lmf::fusion
