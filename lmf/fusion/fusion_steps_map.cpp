// Steps 4-7 of the fusion (docs/design.md §5): geometric update and fusion of global
// segments, the new submap, the frame advance and the environment graph
// (fusion_steps.hpp).
#include <algorithm>
#include <map>

#include "lmf/common/union_find.hpp"
#include "lmf/fusion/fusion_equations.hpp"
#include "lmf/fusion/fusion_steps.hpp"
#include "lmf/spmap/segment_ops.hpp"

namespace lmf::fusion {
namespace {

// Geometric update of one global segment (paper §II.C): its location and
// length change at once to cover the projection `interval`; moving its frame
// by dx along its axis changes the meaning of its lateral error,
// p' = [[1, dx], [0, 1]] p (docs/design.md §3). That change is composed into `shifts`,
// for one GlobalState::transform_perturbations over all extended segments.
void extend_to_cover(GlobalState& state, EntityId segment, const spmap::Interval& interval,
                     std::map<EntityId, Eigen::Matrix2d>& shifts) {
  Entity& e = state.mutable_entity(segment);
  const double half = 0.5 * e.length_m;
  const double lo = std::min(-half, interval.min);
  const double hi = std::max(half, interval.max);
  if (lo >= -half && hi <= half) return;
  const double dx = 0.5 * (lo + hi);
  e.location = compose(e.location, Pose2(dx, 0.0, 0.0));
  e.length_m = hi - lo;
  const auto [it, inserted] = shifts.try_emplace(segment, Eigen::Matrix2d::Identity());
  it->second = spmap::segment_frame_shift(dx) * it->second;
}

void apply_shifts(GlobalState& state, const std::map<EntityId, Eigen::Matrix2d>& shifts) {
  std::vector<GlobalState::LinearTerm> maps;
  maps.reserve(shifts.size());
  for (const auto& [id, J] : shifts) maps.push_back({id, J});
  state.transform_perturbations(maps);
}

// Global segments that matched one local segment are one wall: each set
// (union-find, the oldest id kept) is fused into its oldest member through the
// perfect constraint B(⊖x_keep ⊕ x_drop) = 0, if that passes its own chi2 test.
void fuse_matched_globals(FusionContext& f, const std::map<std::size_t, std::vector<EntityId>>& matches_of_local) {
  GlobalState& state = f.state;
  UnionFind<EntityId> sets;
  for (const auto& [j, globals_of_j] : matches_of_local) {
    for (std::size_t a = 1; a < globals_of_j.size(); ++a) sets.unite(globals_of_j[0], globals_of_j[a]);
  }
  for (const auto& [keep, members] : sets.sets()) {
    for (const EntityId drop : members) {
      if (drop == keep) continue;
      const spmap::ImplicitMeasurement m = spmap::measurement_from_chain(state.chain_between(keep, drop), {1, 2});
      if (!spmap::individual_compatibility(state, m, f.careful, f.chi2).passed) {
        ++f.report.global_fusions_rejected;
        continue;
      }
      spmap::ekf_update(state, {&m, 1}, f.careful);
      const Pose2 x_keep_drop = between(state.root_location(keep), state.root_location(drop));
      std::map<EntityId, Eigen::Matrix2d> shift;
      extend_to_cover(state, keep, spmap::project_extent(x_keep_drop, state.entity(drop).length_m), shift);
      apply_shifts(state, shift);
      f.removals.push_back(drop);
      ++f.report.global_segments_fused;
    }
  }
}

}  // namespace

void update_geometry(FusionContext& f) {
  // Project each paired local segment onto its (updated) global segment and
  // extend it; the used local segments go.
  GlobalState& state = f.state;
  f.paired.assign(f.local.size(), false);
  std::map<std::size_t, std::vector<EntityId>> matches_of_local;
  std::map<EntityId, Eigen::Matrix2d> shifts;
  for (const std::size_t a : f.accepted) {
    const PairingCandidate& c = f.candidates[a];
    const Pose2 x_SiSj = between(state.root_location(c.global_segment), state.root_location(c.local_segment));
    const double before = state.entity(c.global_segment).length_m;
    extend_to_cover(state, c.global_segment,
                    spmap::project_extent(x_SiSj, state.entity(c.local_segment).length_m), shifts);
    if (state.entity(c.global_segment).length_m > before) ++f.report.segments_extended;
    f.paired[c.local_index] = true;
    f.touched_submaps.insert(*state.entity(c.global_segment).parent);
    matches_of_local[c.local_index].push_back(c.global_segment);
  }
  apply_shifts(state, shifts);
  for (std::size_t j = 0; j < f.local.size(); ++j) {
    if (f.paired[j]) f.removals.push_back(f.local[j]);
  }
  f.report.local_segments_removed = static_cast<int>(f.removals.size());
  fuse_matched_globals(f, matches_of_local);
}

void make_new_submap(FusionContext& f, EnvironmentGraph& graph) {
  for (std::size_t j = 0; j < f.local.size(); ++j) {
    if (!f.paired[j]) f.unpaired.push_back(f.local[j]);
  }
  f.report.new_segments = static_cast<int>(f.unpaired.size());
  if (f.unpaired.empty()) return;
  // A backward-anchored map's next frame already exists (it defined this one):
  // L_k itself becomes the submap, the unpaired segments already its children.
  // Otherwise the submap is a copy of L_r, which moves on (step 6).
  EntityId submap = f.L;
  if (!f.anchored()) {
    submap = f.state.add_copy(f.L);
    for (const EntityId u : f.unpaired) f.state.mutable_entity(u).parent = submap;
  }
  graph.add_submap(submap, f.robot_id, f.snapshot.seq);
  f.report.new_submap = submap;
}

void advance_robot_frame(FusionContext& f, RobotArrivals& arrivals, const EnvironmentGraph& graph) {
  GlobalState& state = f.state;
  const std::int64_t seq = f.snapshot.seq;
  f.x_WL_fused = state.root_location(f.L);
  f.report.x_WL_fused = f.x_WL_fused;
  f.cov_L_fused = state.block(f.L, f.L);
  if (f.anchored()) {
    f.report.x_WL_next = state.root_location(arrivals.anchored_map_fused(f.robot_id, seq));
  } else {
    // An older local map may still come: this map's frame stays as its anchor
    // (the new submap, a copy of L_r, when there is one).
    std::optional<EntityId> anchor;
    if (arrivals.older_map_may_come(f.robot_id, seq)) anchor = f.report.new_submap ? *f.report.new_submap : state.add_copy(f.L);
    const FrameAdvance adv = advance_frame(state.entity(f.L).location, state.entity(f.R).location);
    state.replace_perturbation(f.L, {{f.L, adv.J_L}, {f.R, adv.J_R}});
    state.mutable_entity(f.L).location = adv.x_WL_next;
    f.report.x_WL_next = adv.x_WL_next;
    arrivals.advance(f.robot_id, seq, f.L, anchor);
  }
  f.removals.push_back(f.R);
  arrivals.record_fused(f.robot_id, seq, f.x_WL_fused, f.cov_L_fused);
  arrivals.retire_frames(f.robot_id, graph, f.removals);
}

void connect_submaps(FusionContext& f, EnvironmentGraph& graph) {
  if (f.report.new_submap) f.touched_submaps.insert(*f.report.new_submap);
  graph.connect(f.touched_submaps);
}

}  // namespace lmf::fusion
