// Where each robot's local maps stand on their way into the global map
// (docs/design.md §5, "Robots join on the fly"): which robots have joined, the frames
// L_r still needed, the local maps waiting, the ones fused, the frames of fused
// local maps remembered for late sightings, and the sightings still pending.
// It decides what to fuse next; GlobalMap fuses it.
//
// A robot joins with a known frame (GlobalMap::join_robot, or the first robot
// defining W) or through a sighting by a joined robot. Local maps of robots that
// have not joined, or that arrive out of order, wait and are fused in sequence
// order as soon as their frame is known; none is dropped. A local map older than
// the first known frame of its robot is anchored backwards,
// L_k = L_{k+1} ⊕ ⊖x_R(k) (fusion_equations.hpp, previous_frame): its frame
// and its robot R enter the state before it is fused.
//
// The state changes made here are those of the frames only (backward anchors,
// a sighted robot's first frame); the fusion's are in fusion_steps.hpp.
// Not thread-safe.
#pragma once

#include <cstdint>
#include <deque>
#include <map>
#include <optional>
#include <set>
#include <utility>
#include <vector>

#include <Eigen/Core>

#include "lmf/fusion/environment_graph.hpp"
#include "lmf/fusion/fusion_equations.hpp"
#include "lmf/fusion/global_state.hpp"
#include "lmf/geometry/pose2.hpp"
#include "lmf/local_map/local_map_snapshot.hpp"

namespace lmf::fusion {

class RobotArrivals {
 public:
  // The frame of one local map of a robot.
  struct FrameSlot {
    EntityId frame = 0;
    std::optional<EntityId> robot;  // pre-placed robot of a backward-anchored local map
  };

  // local_map_covariance_scale: GlobalMapConfig's, applied to the robot pose of
  // a backward-anchored map. frame_history: GlobalMapConfig::frame_history_per_robot.
  RobotArrivals(double local_map_covariance_scale, int frame_history);

  bool any_joined() const { return any_joined_; }
  bool is_joined(int robot_id) const;
  bool has_fused(int robot_id, std::int64_t seq) const;
  // x_WL of local map `seq` as its fusion left it, for the robot's last
  // frame_history fused maps; nullopt for the others.
  std::optional<Pose2> fused_frame(int robot_id, std::int64_t seq) const;
  bool is_queued(int robot_id, std::int64_t seq) const;
  int queued_count() const;
  std::vector<int> joined() const;  // ascending

  // A joined robot's current local map and its frame L_r.
  std::pair<std::int64_t, EntityId> current_frame(int robot_id) const;

  // Robots that have not joined and have local maps waiting, ascending.
  std::vector<int> waiting() const;
  // The oldest `count` of a robot's waiting local maps, oldest first.
  std::vector<const LocalMapSnapshot*> oldest_waiting_maps(int robot_id, int count) const;

  // The (validated, new) local map waits for its turn.
  void enqueue(const LocalMapSnapshot& snapshot);

  // The robot joins: its local map `seq` starts at `frame` (in `state`). Its
  // queued local maps contiguous down from seq - 1 are anchored backwards.
  void join(int robot_id, EntityId frame, std::int64_t seq, GlobalState& state);

  // What to fuse next for the robot, taken off its queue: backward-anchored
  // maps first, lowest seq first, then the map whose frame is the current one.
  // Anchors the next older queued map when its successor's frame is known.
  std::optional<LocalMapSnapshot> take_next(int robot_id, GlobalState& state);

  // --- For the fusion of local map `seq` of the robot (docs/design.md §5 step 6).
  const FrameSlot& frame_slot(int robot_id, std::int64_t seq) const;
  // An older local map may still come, whose backward anchor is this map's frame.
  bool older_map_may_come(int robot_id, std::int64_t seq) const;
  // After the fusion of the current map `seq`: L_r (entity `frame`) is now the
  // frame of seq + 1; `anchor`, a copy of the old L_r, stays the frame of seq.
  void advance(int robot_id, std::int64_t seq, EntityId frame, std::optional<EntityId> anchor);
  // After the fusion of the backward-anchored map `seq`: its robot has left the
  // state. Returns the frame of seq + 1.
  EntityId anchored_map_fused(int robot_id, std::int64_t seq);
  // Local map `seq` is fused; its frame as fused (x_WL, covariance) is remembered.
  void record_fused(int robot_id, std::int64_t seq, const Pose2& x_WL, const Eigen::Matrix3d& covariance);
  // Appends to `removals` the robot's frames no longer needed (not a submap,
  // not its current frame, not a backward anchor) and forgets them.
  void retire_frames(int robot_id, const EnvironmentGraph& graph, std::vector<EntityId>& removals);

  // --- Sightings (paper §IV).
  void add_pending(const RobotSighting& sighting) { pending_sightings_.push_back(sighting); }
  const std::deque<RobotSighting>& pending_sightings() const { return pending_sightings_; }
  // The first pending sighting that can be resolved now (its observed robot has
  // joined, or its observer's frame at observer_seq is known), taken off the list.
  std::optional<RobotSighting> take_resolvable(const EnvironmentGraph& graph);
  // The observed robot's first frame L_B (added to `state`) from the observer's
  // frame of observer_seq: that frame if still in the state (its current frame,
  // an anchor, or the submap copied from it), else the remembered one (then
  // approximately: its correlations with the map are lost). nullopt, and no
  // change, when neither is known.
  struct SightedJoin {
    EntityId frame = 0;
    bool approximate = false;
  };
  std::optional<SightedJoin> place_sighted_frame(const RobotSighting& sighting, const EnvironmentGraph& graph,
                                                 GlobalState& state) const;

 private:
  friend class GlobalMapArchive;  // global_map_archive.cpp: exact save/restore
  struct Robot {
    bool joined = false;
    std::int64_t next_seq = 0;  // the local map whose origin the forward frame is
    std::int64_t min_seq = 0;   // lowest seq whose frame is known
    std::map<std::int64_t, FrameSlot> frames;  // frames still needed, by seq
    std::map<std::int64_t, LocalMapSnapshot> queue;
    std::set<std::int64_t> fused;
    std::map<std::int64_t, std::pair<Pose2, Eigen::Matrix3d>> history;  // frame of fused seqs
  };

  const Robot* find(int robot_id) const;
  // The observer's frame of observer_seq in the state, if it is still there.
  std::optional<EntityId> observer_frame(const RobotSighting& sighting, const EnvironmentGraph& graph) const;
  const std::pair<Pose2, Eigen::Matrix3d>* remembered_frame(const RobotSighting& sighting) const;
  void anchor_backward(int robot_id, std::int64_t seq, GlobalState& state);

  double local_map_covariance_scale_;
  int frame_history_;
  std::map<int, Robot> robots_;
  std::deque<RobotSighting> pending_sightings_;
  bool any_joined_ = false;
};

}  // namespace lmf::fusion
