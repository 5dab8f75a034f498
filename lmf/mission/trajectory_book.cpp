#include "lmf/mission/trajectory_book.hpp"

namespace lmf::mission {

void TrajectoryBook::add(const LocalMapSnapshot& snapshot) {
  robots_[snapshot.robot_id][snapshot.seq] = Shipped{snapshot.x_LR, snapshot.scan_poses};
}

std::map<int, std::vector<StampedPose>> TrajectoryBook::final_trajectories(const fusion::GlobalMap& map) const {
  std::map<int, std::vector<StampedPose>> out;
  for (const auto& [robot_id, maps] : robots_) {
    std::vector<StampedPose> trajectory = final_trajectory(map, robot_id);
    if (!trajectory.empty()) out[robot_id] = std::move(trajectory);
  }
  return out;
}

std::vector<StampedPose> TrajectoryBook::final_trajectory(const fusion::GlobalMap& map, int robot_id) const {
  const auto robot = robots_.find(robot_id);
  const std::optional<fusion::CorrectedFrame> current = map.corrected_frame(robot_id);
  if (robot == robots_.end() || !current) return {};

  std::map<int64_t, Pose2> submap_frames;  // seq -> x_WF of the submap made from that local map
  for (const fusion::SubmapView& submap : map.submaps()) {
    if (submap.robot_id == robot_id) submap_frames[submap.seq] = submap.x_WF;
  }
  std::map<int64_t, Pose2> frames;
  Pose2 next_frame = current->x_WL;
  int64_t next_seq = current->map_seq;
  for (auto it = robot->second.rbegin(); it != robot->second.rend(); ++it) {
    const int64_t seq = it->first;
    if (!map.has_fused(robot_id, seq)) continue;
    if (const auto s = submap_frames.find(seq); s != submap_frames.end()) {
      frames[seq] = s->second;
    } else if (seq + 1 == next_seq) {
      frames[seq] = compose(next_frame, inverse(it->second.x_LR));
    } else {
      continue;  // not connected to a known frame (never for maps fused in sequence)
    }
    next_frame = frames[seq];
    next_seq = seq;
  }
  std::vector<StampedPose> trajectory;
  for (const auto& [seq, shipped] : robot->second) {
    const auto f = frames.find(seq);
    if (f == frames.end()) continue;
    for (const ScanPose& p : shipped.scan_poses) trajectory.push_back({p.utime, compose(f->second, p.x_LR)});
  }
  return trajectory;
}

}  // namespace lmf::mission
