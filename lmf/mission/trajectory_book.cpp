#include "lmf/mission/trajectory_book.hpp"

#include <cmath>
#include <optional>
#include <vector>

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

namespace {

// x_LR of local map `seq`, the relation between its frame and the next one's,
// as the global map knows it best: between the two frames as their fusions
// left them (each fusion's pairings with the map corrected the frame and the
// robot's end pose), or the local map's own end pose where either frame is no
// longer remembered (GlobalMapConfig::frame_history_per_robot).
Pose2 frame_to_next(const fusion::GlobalMap& map, int robot_id, int64_t seq, const Pose2& x_LR) {
  const std::optional<Pose2> frame = map.fused_frame(robot_id, seq);
  const std::optional<Pose2> next = map.fused_frame(robot_id, seq + 1);
  return frame && next ? between(*frame, *next) : x_LR;
}

// The scan poses of a local map in its frame, bent so that the last one
// reaches `end` (the next frame, seen from this one) instead of x_LR: the
// correction C = end ⊖ x_LR (C ⊕ x_LR = end) is spread along the path, a
// scan at the fraction s of it taking s C (x, y and φ scaled; by scan count
// for a map that did not move).
std::vector<Pose2> bent_to(const std::vector<ScanPose>& poses, const Pose2& x_LR, const Pose2& end) {
  const Pose2 C = compose(end, inverse(x_LR));
  std::vector<double> along(poses.size(), 0.0);
  for (std::size_t i = 1; i < poses.size(); ++i) {
    along[i] = along[i - 1] + std::hypot(poses[i].x_LR.x - poses[i - 1].x_LR.x, poses[i].x_LR.y - poses[i - 1].x_LR.y);
  }
  const double length = along.empty() ? 0.0 : along.back();
  std::vector<Pose2> out;
  out.reserve(poses.size());
  for (std::size_t i = 0; i < poses.size(); ++i) {
    const double s = length > 0.0        ? along[i] / length
                     : poses.size() > 1 ? static_cast<double>(i) / static_cast<double>(poses.size() - 1)
                                        : 1.0;
    out.push_back(compose(Pose2(s * C.x, s * C.y, s * C.phi), poses[i].x_LR));
  }
  return out;
}

}  // namespace

std::vector<StampedPose> TrajectoryBook::final_trajectory(const fusion::GlobalMap& map, int robot_id) const {
  const auto robot = robots_.find(robot_id);
  const std::optional<fusion::CorrectedFrame> current = map.corrected_frame(robot_id);
  if (robot == robots_.end() || !current) return {};

  std::map<int64_t, Pose2> submap_frames;  // seq -> x_WF of the submap made from that local map
  for (const fusion::SubmapView& submap : map.submaps()) {
    if (submap.robot_id == robot_id) submap_frames[submap.seq] = submap.x_WF;
  }
  std::map<int64_t, Pose2> frames;
  frames[current->map_seq] = current->x_WL;
  int64_t next_seq = current->map_seq;
  for (auto it = robot->second.rbegin(); it != robot->second.rend(); ++it) {
    const int64_t seq = it->first;
    if (!map.has_fused(robot_id, seq)) continue;
    if (const auto s = submap_frames.find(seq); s != submap_frames.end()) {
      frames[seq] = s->second;
    } else if (seq + 1 == next_seq) {
      frames[seq] = compose(frames.at(next_seq), inverse(frame_to_next(map, robot_id, seq, it->second.x_LR)));
    } else {
      continue;  // not connected to a known frame (never for maps fused in sequence)
    }
    next_seq = seq;
  }
  // Each map's scans in its frame, bent to meet the next map's frame where it
  // is known, so the trajectory does not jump where the maps meet.
  std::vector<StampedPose> trajectory;
  for (const auto& [seq, shipped] : robot->second) {
    const auto f = frames.find(seq);
    if (f == frames.end() || !map.has_fused(robot_id, seq)) continue;
    const auto next = frames.find(seq + 1);
    const Pose2 end = next != frames.end() ? between(f->second, next->second) : shipped.x_LR;
    const std::vector<Pose2> poses = bent_to(shipped.scan_poses, shipped.x_LR, end);
    for (std::size_t i = 0; i < poses.size(); ++i) {
      trajectory.push_back({shipped.scan_poses[i].utime, compose(f->second, poses[i])});
    }
  }
  return trajectory;
}

}  // namespace lmf::mission
