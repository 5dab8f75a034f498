// The scan poses of every local map a robot shipped, kept until the end so
// each scan's final estimate can be given in W: the final global frame of the
// local map it belonged to ⊕ its pose in that local map. Used by lmf-offline
// and by the fusion server (which gets the scan poses inside local_map_t).
#pragma once

#include <cstdint>
#include <map>
#include <vector>

#include "lmf/fusion/global_map.hpp"
#include "lmf/geometry/stamped_pose.hpp"
#include "lmf/local_map/local_map_snapshot.hpp"

namespace lmf::mission {

class TrajectoryBook {
 public:
  // Records a shipped local map (its scan poses and final x_LR). A second
  // record of the same (robot, seq) replaces the first.
  void add(const LocalMapSnapshot& snapshot);

  // Final trajectory in W of every robot the map knows (joined), in time order.
  // The frame of local map k is the submap made from it when it left one, else
  // x_WL(k) = x_WL(k+1) ⊕ ⊖x_LR(k), back from the robot's current frame.
  std::map<int, std::vector<StampedPose>> final_trajectories(const fusion::GlobalMap& map) const;
  std::vector<StampedPose> final_trajectory(const fusion::GlobalMap& map, int robot_id) const;

  // What was recorded, robot -> seq -> map (e.g. for the server's durable state:
  // add() each back into an empty book to restore it).
  struct Shipped {
    Pose2 x_LR;
    std::vector<ScanPose> scan_poses;
  };
  const std::map<int, std::map<int64_t, Shipped>>& shipped() const { return robots_; }

 private:
  std::map<int, std::map<int64_t, Shipped>> robots_;  // robot -> seq -> map
};

}  // namespace lmf::mission
