// A whole simulated multi-robot mission, in memory: world, per-robot scans with noisy
// odometry, true poses, and robot-robot sightings. Deterministic: the same config (seed
// included) gives the same mission on every machine. Pure: no files, no clock, no threads.
//
// Robot ids are 0 .. num_robots-1. Robot i starts at World::start_spots[i] (robot 1 starts
// 5 m ahead of robot 0, in its view; robot 2 on the far side of the ring). Every robot scans
// at t = start_time_s + k / scan_rate_hz for k = 0, 1, ... while t <= start_time_s + duration_s,
// so scan k of every robot has the same timestamp (and a sighting's time is a scan of both).
//
// Independent random streams (from the seed) drive: the world layout, each robot's route,
// each robot's laser noise, each robot's odometry noise, and the people. Changing the number
// of people or the noise levels therefore does not change the world or the routes.
#pragma once

#include <cstdint>
#include <vector>

#include "lmf/geometry/pose2.hpp"
#include "lmf/scan/laser_scan.hpp"
#include "lmf/sim/laser.hpp"
#include "lmf/sim/odometry.hpp"
#include "lmf/sim/route.hpp"
#include "lmf/sim/world.hpp"

namespace lmf::sim {

struct SightingConfig {
  double max_range_m = 8.0;            // the observed robot's centre within this distance
  double field_of_view_rad = 3.14159265358979323846;  // centred on the observer's heading
  double min_interval_s = 10.0;        // at most one sighting per (observer, observed) per interval
};

struct PeopleConfig {
  int count = 0;                       // people walking up and down the corridors (clutter)
  double radius_m = 0.2;
  double min_speed_mps = 0.5;
  double max_speed_mps = 1.2;
};

struct MissionConfig {
  uint64_t seed = 1;
  int num_robots = 3;                  // in [1, 8]
  double duration_s = 1200.0;          // 20 minutes, > 0
  double scan_rate_hz = 5.0;           // in (0, 100]
  double start_time_s = 0.0;           // time of robot 0's first scan
  double robot_radius_m = 0.25;        // robots appear to each other's lasers as discs of this radius
  bool robots_visible_in_scans = true;
  // Robots keep their distance: a robot whose next step along its route would
  // bring its body within robot_gap_m of another robot's, closer than it is now,
  // waits (the route's time stands still) until the way is clear, at most
  // max_wait_s at a time; then it goes on regardless (two robots meeting head-on
  // in a corridor pass through each other, as without the rule). robot_gap_m = 0
  // turns it off (every robot drives its route on the clock, through the others).
  double robot_gap_m = 0.3;            // in [0, 2]
  double max_wait_s = 10.0;            // >= 0
  WorldConfig world;
  LaserConfig laser;
  MotionConfig motion;
  OdometryModel odometry_model = OdometryModel::kProportional;
  OdometryNoiseConfig odometry;        // the proportional model's noise
  RealOdometryConfig real_odometry;    // the real-robot model's (odometry_model == kReal)
  SightingConfig sightings;
  PeopleConfig people;
  // Throws std::invalid_argument naming the bad field.
  void validate() const;
};

struct RobotRun {
  int id = 0;
  std::vector<LaserScan> scans;  // LaserScan::odometry is the noisy odometry pose x_OR
  std::vector<Pose2> true_poses; // x_WR at each scan's time (same index as scans)
  Trajectory trajectory;         // the route's continuous motion, on the route's own time
  std::vector<double> route_times;  // the route's time at each scan (behind the scan's while it waited)
  double distance_m = 0.0;       // true distance travelled over the scans
  double odometry_distance_m = 0.0;  // the same from the odometry poses
  RealOdometryErrors odometry_errors;  // its systematic odometry errors (identity under kProportional)
};

// Robot `observed` seen by robot `observer` at one of the observer's scans (noise-free).
struct Sighting {
  int64_t utime = 0;
  int observer = 0;
  int observed = 0;
  std::size_t observer_scan = 0;  // index into the observer's scans
  std::size_t observed_scan = 0;  // index into the observed robot's scans (same time)
  Pose2 x_AB;                     // observed robot B seen from observer A (true)
  double range_m = 0.0;
};

// A person walking back and forth along a corridor centreline (offset sideways).
struct Person {
  Eigen::Vector2d a = Eigen::Vector2d::Zero();
  Eigen::Vector2d b = Eigen::Vector2d::Zero();
  double speed_mps = 1.0;
  double phase_m = 0.0;      // distance along the back-and-forth at time 0
  double radius_m = 0.2;
  Eigen::Vector2d position_at(double t_s) const;
};

struct Mission {
  MissionConfig config;
  World world;
  std::vector<RobotRun> robots;
  std::vector<Sighting> sightings;  // by time, then observer, then observed
  std::vector<Person> people;
};

// Simulates the whole mission. Throws std::invalid_argument for a bad config.
Mission simulate_mission(const MissionConfig& config);

// Whether `observed` at x_WB is visible from x_WA under `config` (range, field of view,
// no wall in between). Exposed for tests.
bool robot_visible(const WallIndex& walls, const Pose2& x_WA, const Pose2& x_WB, const SightingConfig& config);

}  // namespace lmf::sim
