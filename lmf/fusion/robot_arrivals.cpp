#include "lmf/fusion/robot_arrivals.hpp"

#include <algorithm>

namespace lmf::fusion {

RobotArrivals::RobotArrivals(double local_map_covariance_scale, int frame_history)
    : local_map_covariance_scale_(local_map_covariance_scale), frame_history_(frame_history) {}

const RobotArrivals::Robot* RobotArrivals::find(int robot_id) const {
  const auto it = robots_.find(robot_id);
  return it == robots_.end() ? nullptr : &it->second;
}

bool RobotArrivals::is_joined(int robot_id) const {
  const Robot* r = find(robot_id);
  return r != nullptr && r->joined;
}

bool RobotArrivals::has_fused(int robot_id, std::int64_t seq) const {
  const Robot* r = find(robot_id);
  return r != nullptr && r->fused.count(seq) != 0;
}

std::optional<Pose2> RobotArrivals::fused_frame(int robot_id, std::int64_t seq) const {
  const Robot* r = find(robot_id);
  if (r == nullptr) return std::nullopt;
  const auto it = r->history.find(seq);
  if (it == r->history.end()) return std::nullopt;
  return it->second.first;
}

bool RobotArrivals::is_queued(int robot_id, std::int64_t seq) const {
  const Robot* r = find(robot_id);
  return r != nullptr && r->queue.count(seq) != 0;
}

int RobotArrivals::queued_count() const {
  std::size_t n = 0;
  for (const auto& [id, r] : robots_) n += r.queue.size();
  return static_cast<int>(n);
}

std::vector<int> RobotArrivals::waiting() const {
  std::vector<int> out;
  for (const auto& [id, r] : robots_) {
    if (!r.joined && !r.queue.empty()) out.push_back(id);
  }
  return out;
}

std::vector<const LocalMapSnapshot*> RobotArrivals::oldest_waiting_maps(int robot_id, int count) const {
  std::vector<const LocalMapSnapshot*> out;
  const Robot* r = find(robot_id);
  if (r == nullptr) return out;
  for (auto it = r->queue.begin(); it != r->queue.end() && static_cast<int>(out.size()) < count; ++it) {
    out.push_back(&it->second);
  }
  return out;
}

std::vector<int> RobotArrivals::joined() const {
  std::vector<int> out;
  for (const auto& [id, r] : robots_) {
    if (r.joined) out.push_back(id);
  }
  return out;
}

std::pair<std::int64_t, EntityId> RobotArrivals::current_frame(int robot_id) const {
  const Robot& r = robots_.at(robot_id);
  return {r.next_seq, r.frames.at(r.next_seq).frame};
}

void RobotArrivals::enqueue(const LocalMapSnapshot& snapshot) {
  robots_[snapshot.robot_id].queue.emplace(snapshot.seq, snapshot);
}

// ---------------------------------------------------------------------------
// Joining and what to fuse next

void RobotArrivals::join(int robot_id, EntityId frame, std::int64_t seq, GlobalState& state) {
  Robot& r = robots_[robot_id];
  r.joined = true;
  any_joined_ = true;
  r.next_seq = seq;
  r.min_seq = seq;
  r.frames[seq] = {frame, std::nullopt};
  // Local maps recorded before this frame, contiguous down from seq - 1: their
  // frames follow backwards from this one.
  for (std::int64_t k = seq - 1; k >= 0 && r.queue.count(k) != 0; --k) anchor_backward(robot_id, k, state);
}

void RobotArrivals::anchor_backward(int robot_id, std::int64_t seq, GlobalState& state) {
  Robot& r = robots_.at(robot_id);
  const LocalMapSnapshot& s = r.queue.at(seq);
  const EntityId next = r.frames.at(seq + 1).frame;
  // L_k = L_{k+1} ⊕ ⊖x_R(k): the robot's final pose of map k is the next frame.
  const PreviousFrame pf = previous_frame(state.root_location(next), s.x_LR);
  const EntityId L = state.add(EntityKind::kFrame, pf.x_WL_previous);
  const EntityId R = state.add(EntityKind::kRobot, s.x_LR, L);
  state.set_block(R, R, local_map_covariance_scale_ * s.covariance.topLeftCorner(3, 3));
  state.replace_perturbation(L, {{next, pf.J_next}, {R, pf.J_R}});
  r.frames[seq] = {L, R};
  r.min_seq = std::min(r.min_seq, seq);
}

std::optional<LocalMapSnapshot> RobotArrivals::take_next(int robot_id, GlobalState& state) {
  while (true) {
    Robot& r = robots_.at(robot_id);
    std::optional<std::int64_t> next;
    // Backward-anchored maps first (they are the older ones), lowest seq first.
    for (const auto& [seq, slot] : r.frames) {
      if (slot.robot) {
        next = seq;
        break;
      }
    }
    if (!next && r.queue.count(r.next_seq) != 0) next = r.next_seq;
    if (!next && r.min_seq > 0 && r.queue.count(r.min_seq - 1) != 0 && r.frames.count(r.min_seq) != 0) {
      anchor_backward(robot_id, r.min_seq - 1, state);
      continue;
    }
    if (!next) return std::nullopt;
    LocalMapSnapshot snapshot = std::move(r.queue.at(*next));
    r.queue.erase(*next);
    return snapshot;
  }
}

// ---------------------------------------------------------------------------
// Frames of a fused local map

const RobotArrivals::FrameSlot& RobotArrivals::frame_slot(int robot_id, std::int64_t seq) const {
  return robots_.at(robot_id).frames.at(seq);
}

bool RobotArrivals::older_map_may_come(int robot_id, std::int64_t seq) const {
  return seq == robots_.at(robot_id).min_seq && seq > 0;
}

void RobotArrivals::advance(int robot_id, std::int64_t seq, EntityId frame, std::optional<EntityId> anchor) {
  Robot& r = robots_.at(robot_id);
  r.frames.erase(seq);
  if (anchor) r.frames[seq] = {*anchor, std::nullopt};
  r.frames[seq + 1] = {frame, std::nullopt};
  r.next_seq = seq + 1;
}

EntityId RobotArrivals::anchored_map_fused(int robot_id, std::int64_t seq) {
  Robot& r = robots_.at(robot_id);
  r.frames.at(seq).robot.reset();
  return r.frames.at(seq + 1).frame;
}

void RobotArrivals::record_fused(int robot_id, std::int64_t seq, const Pose2& x_WL, const Eigen::Matrix3d& covariance) {
  Robot& r = robots_.at(robot_id);
  r.fused.insert(seq);
  r.history[seq] = {x_WL, covariance};
  while (static_cast<int>(r.history.size()) > frame_history_) r.history.erase(r.history.begin());
}

void RobotArrivals::retire_frames(int robot_id, const EnvironmentGraph& graph, std::vector<EntityId>& removals) {
  Robot& r = robots_.at(robot_id);
  for (auto it = r.frames.begin(); it != r.frames.end();) {
    const std::int64_t seq = it->first;
    const FrameSlot& slot = it->second;
    const bool needed = seq == r.next_seq || slot.robot.has_value() || (seq == r.min_seq && r.min_seq > 0);
    if (needed) {
      ++it;
      continue;
    }
    const EntityId frame = slot.frame;
    it = r.frames.erase(it);
    const bool shared =
        std::any_of(r.frames.begin(), r.frames.end(), [frame](const auto& kv) { return kv.second.frame == frame; });
    if (!shared && !graph.is_submap(frame)) removals.push_back(frame);
  }
}

// ---------------------------------------------------------------------------
// Sightings

std::optional<EntityId> RobotArrivals::observer_frame(const RobotSighting& s, const EnvironmentGraph& graph) const {
  const Robot& observer = robots_.at(s.observer_id);
  if (const auto it = observer.frames.find(s.observer_seq); it != observer.frames.end()) return it->second.frame;
  return graph.submap_of(s.observer_id, s.observer_seq);
}

const std::pair<Pose2, Eigen::Matrix3d>* RobotArrivals::remembered_frame(const RobotSighting& s) const {
  const Robot& observer = robots_.at(s.observer_id);
  const auto it = observer.history.find(s.observer_seq);
  return it == observer.history.end() ? nullptr : &it->second;
}

std::optional<RobotSighting> RobotArrivals::take_resolvable(const EnvironmentGraph& graph) {
  for (auto it = pending_sightings_.begin(); it != pending_sightings_.end(); ++it) {
    const bool resolvable = is_joined(it->observed_id) ||
                            (is_joined(it->observer_id) &&
                             (observer_frame(*it, graph).has_value() || remembered_frame(*it) != nullptr));
    if (!resolvable) continue;
    const RobotSighting s = *it;
    pending_sightings_.erase(it);
    return s;
  }
  return std::nullopt;
}

std::optional<RobotArrivals::SightedJoin> RobotArrivals::place_sighted_frame(const RobotSighting& s,
                                                                            const EnvironmentGraph& graph,
                                                                            GlobalState& state) const {
  if (!is_joined(s.observer_id)) return std::nullopt;
  if (const std::optional<EntityId> frame = observer_frame(s, graph)) {
    const SightedFrame sf = sighted_frame(state.root_location(*frame), s);
    const EntityId L_B = state.add(EntityKind::kFrame, sf.x_WLB);
    state.replace_perturbation(L_B, {{*frame, sf.J_LA}});
    state.add_to_block(L_B, sf.noise);
    return SightedJoin{L_B, false};
  }
  if (const auto* remembered = remembered_frame(s)) {
    const SightedFrame sf = sighted_frame(remembered->first, s);
    const EntityId L_B = state.add(EntityKind::kFrame, sf.x_WLB);
    state.set_block(L_B, L_B, sf.J_LA * remembered->second * sf.J_LA.transpose() + sf.noise);
    return SightedJoin{L_B, true};
  }
  return std::nullopt;  // the observer has not reached (or not yet fused) that local map
}

}  // namespace lmf::fusion
