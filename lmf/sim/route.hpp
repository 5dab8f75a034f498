// Robot routes through the simulated world and the continuous true motion along them.
//
// A route is a walk on the world's road graph: the robot never turns back except at a
// dead end or inside a room, prefers corridor branches it has driven less (so it explores
// new corridors and keeps closing loops), and enters a room behind a door it passes with
// room_visit_probability (revisit_room_probability for a room it has seen). The walk's
// polyline becomes a motion at constant speed: straight legs, circular arcs of
// turn_radius_m at 90° corners (smooth turns), and an in-place rotation at
// rotation_speed_radps where the robot turns back. All poses are x_WR (world frame).
#pragma once

#include <utility>
#include <vector>

#include <Eigen/Core>

#include "lmf/geometry/pose2.hpp"
#include "lmf/sim/random.hpp"
#include "lmf/sim/world.hpp"

namespace lmf::sim {

struct MotionConfig {
  double speed_mps = 0.5;                  // along legs and arcs, in (0, 3]
  double turn_radius_m = 0.6;              // corner arcs (shrunk on short legs), in [0.1, 2]
  double rotation_speed_radps = 0.6;       // turning in place, in (0, 3]
  double wall_margin_m = 0.45;             // the path keeps at least this from every wall, in [0, 0.5]
  double room_visit_probability = 0.3;     // entering an unvisited room behind a passed door
  double revisit_room_probability = 0.05;  // entering a room this robot has visited
  // Throws std::invalid_argument when out of range.
  void validate() const;
};

// A continuous motion: poses for every time in [0, duration_s()] (s from the motion's start).
class Trajectory {
 public:
  enum class Kind { kLine, kArc, kRotate };
  struct Piece {
    Kind kind = Kind::kLine;
    double t0 = 0.0;             // start time (s)
    double t1 = 0.0;             // end time (s)
    Eigen::Vector2d p0;          // line start; arc centre; rotation point
    double heading0 = 0.0;       // heading at t0 (rad)
    double rate = 0.0;           // line: speed (m/s); arc and rotation: yaw rate (rad/s)
    double radius = 0.0;         // arc radius (m)
    double s0 = 0.0;             // distance travelled before the piece (m)
  };

  // Building: start() once, then pieces that continue from the current end.
  void start(const Pose2& x_WR);
  // Straight to `to` (the heading becomes the line's direction).
  void add_line(const Eigen::Vector2d& to, double speed_mps);
  // Arc turning by `turn_rad` (signed, left positive) on a circle of `radius_m`.
  void add_arc(double turn_rad, double radius_m, double speed_mps);
  // Turning in place by `turn_rad` (signed).
  void add_rotation(double turn_rad, double rate_radps);

  // The pose at time t (clamped to [0, duration_s()]).
  Pose2 pose_at(double t_s) const;
  // Distance travelled up to time t.
  double distance_at(double t_s) const;
  double duration_s() const { return end_t_; }
  double length_m() const;
  const std::vector<Piece>& pieces() const { return pieces_; }

 private:
  void require_started(const char* what) const;
  // The piece driven at time t (clamped to [0, duration_s()]; pieces_ not
  // empty) and the time since it began.
  std::pair<const Piece*, double> piece_at(double t_s) const;

  std::vector<Piece> pieces_;
  Pose2 start_;
  bool started_ = false;
  Eigen::Vector2d end_p_ = Eigen::Vector2d::Zero();
  double end_heading_ = 0.0;  // unwrapped
  double end_t_ = 0.0;
  double end_s_ = 0.0;
};

// A robot's route from `start` for at least `min_duration_s` seconds.
// Throws std::invalid_argument when the start is not on a corridor centreline heading along it,
// and std::logic_error when the generated path breaks the wall margin (a generator bug).
Trajectory plan_route(const World& world, const StartSpot& start, const MotionConfig& config,
                      double min_duration_s, Rng& rng);

// Turns a waypoint polyline (axis-aligned or not) into a motion with smooth corners and
// in-place rotations at reversals (turns sharper than 120°). Exposed for tests.
Trajectory smooth_polyline(const std::vector<Eigen::Vector2d>& waypoints, const MotionConfig& config);

}  // namespace lmf::sim
