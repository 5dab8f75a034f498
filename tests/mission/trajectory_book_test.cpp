// The final trajectory (trajectory_book.hpp): each local map's scans placed in
// its final frame and bent to meet the next map's.
#include "lmf/mission/trajectory_book.hpp"

#include <cmath>
#include <vector>

#include <gtest/gtest.h>

#include "fusion/synthetic_maps.hpp"
#include "lmf/fusion/global_map.hpp"

namespace lmf::mission {
namespace {

namespace syn = fusion::synthetic;

// A map of the room walls seen from x_WL, ending at x_LR_claimed (the true
// end is x_LR_true), with scan poses every 0.5 m along the claimed path.
LocalMapSnapshot straight_map(std::int64_t seq, const Pose2& x_WL, const Pose2& x_LR_true, double claimed_x,
                              const syn::Noise& noise) {
  LocalMapSnapshot s = syn::make_snapshot(0, seq, x_WL, x_LR_true, syn::room(3.0, 0.0, 12.0, 6.0, 2), noise);
  s.x_LR = Pose2(claimed_x, 0.0, 0.0);
  s.scan_poses.clear();
  for (int i = 0; i <= 4; ++i) s.scan_poses.push_back({s.first_utime + i * 200000, Pose2(0.25 * i * claimed_x, 0.0, 0.0)});
  s.last_utime = s.scan_poses.back().utime;
  return s;
}

// Map 1 claims 2.3 m where the robot went 2 m; map 2 sees the room's walls from
// where it truly began, so its fusion pulls its frame back. Map 1 left no
// submap (every wall was known), so its frame comes from map 2's: the
// trajectory holds no jump where the maps meet, and map 1's scans are spread
// over the 2 m the map says it drove.
TEST(TrajectoryBook, AMapWithoutASubmapIsPlacedByTheFusedFramesAndBentToMeetTheNext) {
  fusion::GlobalMap map;
  map.join_robot(0, Pose2());
  TrajectoryBook book;
  syn::Noise loose;
  loose.robot_xy_m = 0.2;
  const std::vector<LocalMapSnapshot> maps = {straight_map(0, Pose2(), Pose2(2.0, 0.0, 0.0), 2.0, {}),
                                              straight_map(1, Pose2(2.0, 0.0, 0.0), Pose2(2.0, 0.0, 0.0), 2.3, loose),
                                              straight_map(2, Pose2(4.0, 0.0, 0.0), Pose2(2.0, 0.0, 0.0), 2.0, {})};
  for (const LocalMapSnapshot& s : maps) {
    book.add(s);
    map.fuse(s);
  }
  ASSERT_TRUE(map.fused_frame(0, 2).has_value());
  EXPECT_NEAR(map.fused_frame(0, 2)->x, 4.0, 0.1) << "the fusion pulled map 2's frame back";
  const std::vector<StampedPose> trajectory = book.final_trajectory(map, 0);
  ASSERT_EQ(trajectory.size(), 15U);
  // Maps meet where the next begins: map k's last scan and map k+1's first.
  for (int k : {4, 9}) {
    EXPECT_NEAR(trajectory[k].pose.x, trajectory[k + 1].pose.x, 0.02) << k;
    EXPECT_NEAR(trajectory[k].pose.y, trajectory[k + 1].pose.y, 0.02) << k;
  }
  // Map 1's middle scan: halfway along the 2 m between its frame and the next.
  EXPECT_NEAR(trajectory[7].pose.x, 0.5 * (trajectory[5].pose.x + trajectory[9].pose.x), 0.02);
  EXPECT_NEAR(trajectory[9].pose.x - trajectory[5].pose.x, 2.0, 0.1);
}

}  // namespace
}  // namespace lmf::mission
