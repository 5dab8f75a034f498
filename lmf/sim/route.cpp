#include "lmf/sim/route.hpp"

#include <algorithm>
#include <cmath>
#include <map>
#include <numbers>
#include <stdexcept>
#include <string>
#include <utility>

#include "lmf/common/config_check.hpp"
#include "lmf/sim/ray_cast.hpp"

namespace lmf::sim {

void MotionConfig::validate() const {
  const ConfigCheck require("MotionConfig");
  require(speed_mps > 0.0 && speed_mps <= 3.0, "speed_mps must be in (0, 3]");
  require(turn_radius_m >= 0.1 && turn_radius_m <= 2.0, "turn_radius_m must be in [0.1, 2]");
  require(rotation_speed_radps > 0.0 && rotation_speed_radps <= 3.0, "rotation_speed_radps must be in (0, 3]");
  require(wall_margin_m >= 0.0 && wall_margin_m <= 0.5, "wall_margin_m must be in [0, 0.5]");
  require(room_visit_probability >= 0.0 && room_visit_probability <= 1.0, "room_visit_probability must be in [0, 1]");
  require(revisit_room_probability >= 0.0 && revisit_room_probability <= 1.0,
          "revisit_room_probability must be in [0, 1]");
}

namespace {

Eigen::Vector2d unit(double heading) { return {std::cos(heading), std::sin(heading)}; }
Eigen::Vector2d left_normal(double heading) { return {-std::sin(heading), std::cos(heading)}; }

}  // namespace

void Trajectory::start(const Pose2& x_WR) {
  if (started_) throw std::logic_error("Trajectory::start: already started");
  started_ = true;
  start_ = x_WR;
  end_p_ = {x_WR.x, x_WR.y};
  end_heading_ = x_WR.phi;
}

void Trajectory::require_started(const char* what) const {
  if (!started_) throw std::logic_error(std::string("Trajectory::") + what + ": start() first");
}

void Trajectory::add_line(const Eigen::Vector2d& to, double speed_mps) {
  require_started("add_line");
  const Eigen::Vector2d d = to - end_p_;
  const double len = d.norm();
  if (len < 1e-12) return;
  Piece p;
  p.kind = Kind::kLine;
  p.p0 = end_p_;
  p.heading0 = std::atan2(d.y(), d.x());
  p.rate = speed_mps;
  p.t0 = end_t_;
  p.s0 = end_s_;
  p.t1 = p.t0 + len / speed_mps;
  pieces_.push_back(p);
  end_p_ = to;
  end_heading_ = p.heading0;
  end_t_ = p.t1;
  end_s_ += len;
}

void Trajectory::add_arc(double turn_rad, double radius_m, double speed_mps) {
  require_started("add_arc");
  if (std::abs(turn_rad) < 1e-12) return;
  const double sign = turn_rad > 0.0 ? 1.0 : -1.0;
  Piece p;
  p.kind = Kind::kArc;
  p.p0 = end_p_ + sign * radius_m * left_normal(end_heading_);  // the arc's centre
  p.heading0 = end_heading_;
  p.radius = radius_m;
  p.rate = sign * speed_mps / radius_m;
  p.t0 = end_t_;
  p.s0 = end_s_;
  p.t1 = p.t0 + std::abs(turn_rad) * radius_m / speed_mps;
  pieces_.push_back(p);
  end_heading_ += turn_rad;
  end_p_ = p.p0 - sign * radius_m * left_normal(end_heading_);
  end_t_ = p.t1;
  end_s_ += std::abs(turn_rad) * radius_m;
}

void Trajectory::add_rotation(double turn_rad, double rate_radps) {
  require_started("add_rotation");
  if (std::abs(turn_rad) < 1e-12) return;
  Piece p;
  p.kind = Kind::kRotate;
  p.p0 = end_p_;
  p.heading0 = end_heading_;
  p.rate = turn_rad > 0.0 ? rate_radps : -rate_radps;
  p.t0 = end_t_;
  p.s0 = end_s_;
  p.t1 = p.t0 + std::abs(turn_rad) / rate_radps;
  pieces_.push_back(p);
  end_heading_ += turn_rad;
  end_t_ = p.t1;
}

std::pair<const Trajectory::Piece*, double> Trajectory::piece_at(double t_s) const {
  const double t = std::clamp(t_s, 0.0, duration_s());
  auto it = std::upper_bound(pieces_.begin(), pieces_.end(), t,
                             [](double value, const Piece& piece) { return value < piece.t1; });
  if (it == pieces_.end()) it = std::prev(pieces_.end());
  return {&*it, t - it->t0};
}

Pose2 Trajectory::pose_at(double t_s) const {
  if (pieces_.empty()) return {start_.x, start_.y, wrap_angle(start_.phi)};
  const auto [piece, dt] = piece_at(t_s);
  const Piece& p = *piece;
  switch (p.kind) {
    case Kind::kLine: {
      const Eigen::Vector2d q = p.p0 + p.rate * dt * unit(p.heading0);
      return {q.x(), q.y(), wrap_angle(p.heading0)};
    }
    case Kind::kArc: {
      const double h = p.heading0 + p.rate * dt;
      const double sign = p.rate > 0.0 ? 1.0 : -1.0;
      const Eigen::Vector2d q = p.p0 - sign * p.radius * left_normal(h);
      return {q.x(), q.y(), wrap_angle(h)};
    }
    case Kind::kRotate:
      return {p.p0.x(), p.p0.y(), wrap_angle(p.heading0 + p.rate * dt)};
  }
  return {};
}

double Trajectory::distance_at(double t_s) const {
  if (pieces_.empty()) return 0.0;
  const auto [piece, dt] = piece_at(t_s);
  const Piece& p = *piece;
  if (p.kind == Kind::kLine) return p.s0 + p.rate * dt;
  if (p.kind == Kind::kArc) return p.s0 + p.radius * std::abs(p.rate) * dt;
  return p.s0;
}

double Trajectory::length_m() const { return distance_at(duration_s()); }

Trajectory smooth_polyline(const std::vector<Eigen::Vector2d>& waypoints, const MotionConfig& config) {
  // Drop repeated points and the inner points of straight runs.
  std::vector<Eigen::Vector2d> pts;
  for (const auto& w : waypoints) {
    if (!pts.empty() && (w - pts.back()).norm() < 1e-9) continue;
    if (pts.size() >= 2) {
      const Eigen::Vector2d a = (pts.back() - pts[pts.size() - 2]).normalized();
      const Eigen::Vector2d b = (w - pts.back()).normalized();
      if (a.dot(b) > 1.0 - 1e-12) {
        pts.back() = w;
        continue;
      }
    }
    pts.push_back(w);
  }
  Trajectory traj;
  if (pts.empty()) return traj;
  const Eigen::Vector2d first = pts.size() >= 2 ? Eigen::Vector2d(pts[1] - pts[0]) : Eigen::Vector2d(1.0, 0.0);
  traj.start({pts[0].x(), pts[0].y(), std::atan2(first.y(), first.x())});
  constexpr double kReversal = 2.0 * std::numbers::pi / 3.0;  // sharper turns are made in place
  for (std::size_t i = 1; i + 1 < pts.size(); ++i) {
    const Eigen::Vector2d in = pts[i] - pts[i - 1];
    const Eigen::Vector2d out = pts[i + 1] - pts[i];
    const double turn = wrap_angle(std::atan2(out.y(), out.x()) - std::atan2(in.y(), in.x()));
    if (std::abs(turn) > kReversal) {
      traj.add_line(pts[i], config.speed_mps);
      traj.add_rotation(turn, config.rotation_speed_radps);
      continue;
    }
    // Fillet: an arc tangent to both legs, using at most 45 % of each leg.
    const double tan_half = std::tan(std::abs(turn) / 2.0);
    const double radius = std::min(config.turn_radius_m, 0.45 * std::min(in.norm(), out.norm()) / tan_half);
    const double d = radius * tan_half;
    traj.add_line(pts[i] - d * in.normalized(), config.speed_mps);
    traj.add_arc(turn, radius, config.speed_mps);
  }
  if (pts.size() >= 2) traj.add_line(pts.back(), config.speed_mps);
  return traj;
}

namespace {

constexpr double kMinRunUpM = 1.5;

struct Walker {
  const World& world;
  const MotionConfig& config;
  Rng& rng;
  std::map<std::pair<int, int>, int> edge_visits;
  std::vector<bool> room_seen;
  double straight_run_m = 0.0;  // distance since the walk last changed direction
  Eigen::Vector2d last_dir = Eigen::Vector2d::Zero();

  void advance(const Eigen::Vector2d& from, const Eigen::Vector2d& to) {
    const Eigen::Vector2d d = to - from;
    const Eigen::Vector2d dir = d.normalized();
    straight_run_m = dir.dot(last_dir) > 1.0 - 1e-9 ? straight_run_m + d.norm() : d.norm();
    last_dir = dir;
  }

  int visits(int a, int b) const {
    const auto it = edge_visits.find({std::min(a, b), std::max(a, b)});
    return it == edge_visits.end() ? 0 : it->second;
  }
  void visit(int a, int b) { ++edge_visits[{std::min(a, b), std::max(a, b)}]; }

  // Exploration: branches driven less often are much more likely.
  int pick_weighted(int cur, const std::vector<int>& cands) {
    std::vector<double> w;
    double total = 0.0;
    for (int c : cands) {
      const double v = 1.0 + visits(cur, c);
      w.push_back(1.0 / (v * v));
      total += w.back();
    }
    double u = rng.uniform01() * total;
    for (std::size_t i = 0; i < cands.size(); ++i) {
      if (u < w[i]) return cands[i];
      u -= w[i];
    }
    return cands.back();
  }

  int next(int prev, int cur) {
    const RoadGraph& g = world.graph;
    std::vector<int> rooms;
    std::vector<int> corridors;
    for (int n : g.neighbours[static_cast<std::size_t>(cur)]) {
      if (n == prev) continue;
      (g.nodes[static_cast<std::size_t>(n)].kind == NodeKind::kRoomInside ? rooms : corridors).push_back(n);
    }
    if (rooms.empty() && corridors.empty()) return prev;  // dead end or room: turn back
    // Entering a room needs a straight run-up, so the turn into the door is a full arc
    // (two doors close together on opposite sides would otherwise make a zig-zag).
    if (straight_run_m < kMinRunUpM) rooms.clear();
    if (rooms.empty() && corridors.empty()) return prev;
    for (int r : rooms) {
      const int room = g.nodes[static_cast<std::size_t>(r)].room;
      const double p = room_seen[static_cast<std::size_t>(room)] ? config.revisit_room_probability
                                                                : config.room_visit_probability;
      if (rng.bernoulli(p)) {
        room_seen[static_cast<std::size_t>(room)] = true;
        return r;
      }
    }
    if (corridors.empty()) return rooms.front();
    return pick_weighted(cur, corridors);
  }
};

}  // namespace

Trajectory plan_route(const World& world, const StartSpot& start, const MotionConfig& config,
                      double min_duration_s, Rng& rng) {
  config.validate();
  const RoadGraph& g = world.graph;
  const Eigen::Vector2d heading = unit(start.heading_rad);
  int from = -1;
  int to = -1;
  for (std::size_t u = 0; u < g.nodes.size() && to < 0; ++u) {
    for (int v : g.neighbours[u]) {
      const Eigen::Vector2d a = g.nodes[u].p;
      const Eigen::Vector2d b = g.nodes[static_cast<std::size_t>(v)].p;
      const Eigen::Vector2d dir = (b - a).normalized();
      const Eigen::Vector2d ap = start.p - a;
      if (dir.dot(heading) > 0.999 && std::abs(dir.x() * ap.y() - dir.y() * ap.x()) < 1e-6 &&
          ap.dot(dir) >= -1e-9 && (b - start.p).dot(dir) > 1e-6) {
        from = static_cast<int>(u);
        to = v;
        break;
      }
    }
  }
  if (to < 0) {
    throw std::invalid_argument("plan_route: start (" + std::to_string(start.p.x()) + ", " +
                                std::to_string(start.p.y()) + ") is not on a road heading along it");
  }

  Walker walker{world, config, rng, {}, std::vector<bool>(world.rooms.size(), false)};
  std::vector<Eigen::Vector2d> waypoints = {start.p, g.nodes[static_cast<std::size_t>(to)].p};
  walker.visit(from, to);
  walker.advance(waypoints[0], waypoints[1]);
  int prev = from;
  int cur = to;
  double length = (waypoints[1] - waypoints[0]).norm();
  Trajectory traj;
  // Corners and rotations change the duration, so extend the walk until it is long enough.
  double target_length = config.speed_mps * min_duration_s + 10.0;
  for (;;) {
    while (length < target_length) {
      const int n = walker.next(prev, cur);
      walker.visit(cur, n);
      walker.advance(g.nodes[static_cast<std::size_t>(cur)].p, g.nodes[static_cast<std::size_t>(n)].p);
      length += (g.nodes[static_cast<std::size_t>(n)].p - g.nodes[static_cast<std::size_t>(cur)].p).norm();
      waypoints.push_back(g.nodes[static_cast<std::size_t>(n)].p);
      prev = cur;
      cur = n;
    }
    traj = smooth_polyline(waypoints, config);
    if (traj.duration_s() >= min_duration_s) break;
    target_length += config.speed_mps * (min_duration_s - traj.duration_s()) + 10.0;
  }

  // The generator guarantees the margin; check it so that a layout bug cannot go unnoticed.
  const WallIndex index(world.walls);
  const double step_s = 0.05 / config.speed_mps;
  for (double t = 0.0; t <= traj.duration_s(); t += step_s) {
    const Pose2 x = traj.pose_at(t);
    const Eigen::Vector2d p(x.x, x.y);
    const auto d = index.distance_to_nearest(p, config.wall_margin_m);
    if (d && *d < config.wall_margin_m - 1e-9) {
      throw std::logic_error("plan_route: path passes " + std::to_string(*d) + " m from a wall at (" +
                             std::to_string(p.x()) + ", " + std::to_string(p.y()) + ")");
    }
  }
  return traj;
}

}  // namespace lmf::sim
