#include "lmf/sim/mission.hpp"

#include <algorithm>
#include <cmath>
#include <map>
#include <numbers>
#include <stdexcept>
#include <string>
#include <tuple>
#include <utility>

#include "lmf/common/config_check.hpp"
#include "lmf/sim/random.hpp"
#include "lmf/sim/ray_cast.hpp"

namespace lmf::sim {
namespace {

// Stream tags of the independent random streams (mission.hpp).
constexpr uint64_t kRouteStream = 0x1000;
constexpr uint64_t kLaserStream = 0x2000;
constexpr uint64_t kOdometryStream = 0x3000;
constexpr uint64_t kPeopleStream = 0x4000;

std::vector<Person> place_people(const World& world, const PeopleConfig& config, uint64_t seed) {
  Rng rng(derive_seed(seed, kPeopleStream));
  std::vector<Person> people;
  const double half_width = 0.5 * world.config.corridor_width_m;
  const double max_offset = std::max(0.0, half_width - config.radius_m - 0.2);
  for (int i = 0; i < config.count; ++i) {
    const Wall& run = world.corridor_runs[rng.uniform_index(world.corridor_runs.size())];
    const Eigen::Vector2d along = (run.b - run.a).normalized();
    const Eigen::Vector2d side(-along.y(), along.x());
    const Eigen::Vector2d offset = rng.uniform(-max_offset, max_offset) * side;
    Person p;
    p.a = run.a + offset;
    p.b = run.b + offset;
    p.speed_mps = rng.uniform(config.min_speed_mps, config.max_speed_mps);
    p.phase_m = rng.uniform(0.0, 2.0 * (run.b - run.a).norm());
    p.radius_m = config.radius_m;
    people.push_back(p);
  }
  return people;
}

}  // namespace

void MissionConfig::validate() const {
  const ConfigCheck require("MissionConfig");
  require(num_robots >= 1 && num_robots <= 8, "num_robots must be in [1, 8]");
  require(duration_s > 0.0 && duration_s <= 86400.0, "duration_s must be in (0, 86400]");
  require(scan_rate_hz > 0.0 && scan_rate_hz <= 100.0, "scan_rate_hz must be in (0, 100]");
  require(std::isfinite(start_time_s) && start_time_s >= 0.0, "start_time_s must be finite and >= 0");
  require(robot_radius_m >= 0.0 && robot_radius_m <= 1.0, "robot_radius_m must be in [0, 1]");
  require(std::isfinite(robot_gap_m) && robot_gap_m >= 0.0 && robot_gap_m <= 2.0, "robot_gap_m must be in [0, 2]");
  require(std::isfinite(max_wait_s) && max_wait_s >= 0.0, "max_wait_s must be finite and >= 0");
  require(sightings.max_range_m > 0.0, "sightings.max_range_m must be positive");
  require(sightings.field_of_view_rad > 0.0 && sightings.field_of_view_rad <= 2.0 * std::numbers::pi,
          "sightings.field_of_view_rad must be in (0, 2 pi]");
  require(sightings.min_interval_s >= 0.0, "sightings.min_interval_s must be >= 0");
  require(people.count >= 0 && people.count <= 1000, "people.count must be in [0, 1000]");
  require(people.radius_m > 0.0 && people.radius_m <= 1.0, "people.radius_m must be in (0, 1]");
  require(people.min_speed_mps > 0.0 && people.min_speed_mps <= people.max_speed_mps && people.max_speed_mps <= 5.0,
          "people speeds must satisfy 0 < min_speed_mps <= max_speed_mps <= 5");
  world.validate();
  laser.validate();
  motion.validate();
  odometry.validate();
  real_odometry.validate();
  require(0.5 * world.door_width_m >= motion.wall_margin_m,
          "motion.wall_margin_m must not exceed half of world.door_width_m (robots drive through doors)");
}

Eigen::Vector2d Person::position_at(double t_s) const {
  const double length = (b - a).norm();
  if (length <= 0.0) return a;
  double s = std::fmod(phase_m + speed_mps * t_s, 2.0 * length);
  if (s < 0.0) s += 2.0 * length;
  if (s > length) s = 2.0 * length - s;  // walking back
  return a + (b - a) * (s / length);
}

bool robot_visible(const WallIndex& walls, const Pose2& x_WA, const Pose2& x_WB, const SightingConfig& config) {
  const Pose2 x_AB = between(x_WA, x_WB);
  const double range = std::hypot(x_AB.x, x_AB.y);
  if (range > config.max_range_m || range <= 0.0) return false;
  if (std::abs(std::atan2(x_AB.y, x_AB.x)) > 0.5 * config.field_of_view_rad) return false;
  return !walls.blocks({x_WA.x, x_WA.y}, {x_WB.x, x_WB.y});
}

namespace {

// Each robot's true pose at every scan time (MissionConfig::robot_gap_m): in
// robot order per step, a robot advances its route by one period unless that
// brings it, closer than it is, within two radii plus the gap of another
// robot's pose (this step's for the robots already moved, the last step's for
// the others); then it waits. Behind a robot heading away it waits as long as
// it takes; for one facing it (meeting head-on, where neither can give way on
// its route) at most max_wait_s in a row, then it drives on regardless.
void drive_routes(const MissionConfig& config, std::size_t scans, double period, std::vector<RobotRun>& robots) {
  const double keep = 2.0 * config.robot_radius_m + config.robot_gap_m;
  std::vector<double> waited(robots.size(), 0.0);
  for (RobotRun& run : robots) {
    run.route_times.assign(1, 0.0);
    run.true_poses.assign(1, run.trajectory.pose_at(0.0));
  }
  const auto distance = [](const Pose2& a, const Pose2& b) { return std::hypot(a.x - b.x, a.y - b.y); };
  for (std::size_t k = 1; k < scans; ++k) {
    for (std::size_t i = 0; i < robots.size(); ++i) {
      RobotRun& run = robots[i];
      const Pose2& now = run.true_poses.back();
      const double tau = run.route_times.back() + period;
      const Pose2 next = run.trajectory.pose_at(tau);
      bool blocked = false;
      bool head_on = false;
      for (std::size_t j = 0; j < robots.size() && config.robot_gap_m > 0.0; ++j) {
        if (j == i) continue;
        const Pose2& other = robots[j].true_poses.back();  // step k if j < i, else k - 1
        if (distance(next, other) >= keep || distance(next, other) >= distance(now, other)) continue;
        blocked = true;
        const bool facing = std::cos(other.phi) * (now.x - other.x) + std::sin(other.phi) * (now.y - other.y) > 0.0;
        head_on = head_on || facing;
      }
      const bool wait = blocked && (!head_on || waited[i] < config.max_wait_s - 1e-9);
      if (wait) {
        waited[i] += period;
        run.route_times.push_back(run.route_times.back());
        run.true_poses.push_back(now);
      } else {
        if (!blocked) waited[i] = 0.0;  // after a timeout: on regardless until clear
        run.route_times.push_back(tau);
        run.true_poses.push_back(next);
      }
    }
  }
}

}  // namespace

Mission simulate_mission(const MissionConfig& config) {
  config.validate();
  Mission mission;
  mission.config = config;
  mission.world = generate_world(config.world, config.seed);
  const World& world = mission.world;
  if (static_cast<std::size_t>(config.num_robots) > world.start_spots.size()) {
    throw std::invalid_argument("MissionConfig: num_robots exceeds the world's start spots");
  }
  const WallIndex walls(world.walls);
  mission.people = place_people(world, config.people, config.seed);

  const auto n = static_cast<std::size_t>(config.num_robots);
  const double period = 1.0 / config.scan_rate_hz;
  mission.robots.resize(n);
  for (std::size_t i = 0; i < n; ++i) {
    Rng route_rng(derive_seed(config.seed, kRouteStream + i));
    mission.robots[i].id = static_cast<int>(i);
    // One extra period so the last scan time is always inside the motion.
    mission.robots[i].trajectory =
        plan_route(world, world.start_spots[i], config.motion, config.duration_s + period, route_rng);
  }

  // Scan times (relative to start_time_s), the same for every robot, so that a sighting's
  // time is a scan time of both robots.
  std::vector<double> scan_times;
  for (std::size_t k = 0;; ++k) {
    const double t = period * static_cast<double>(k);
    if (t > config.duration_s + 1e-9) break;
    scan_times.push_back(t);
  }
  const std::vector<std::vector<double>> times(n, scan_times);
  drive_routes(config, scan_times.size(), period, mission.robots);

  for (std::size_t i = 0; i < n; ++i) {
    RobotRun& run = mission.robots[i];
    Rng laser_rng(derive_seed(config.seed, kLaserStream + i));
    RobotOdometry odometry(config.odometry_model, config.odometry, config.real_odometry,
                           derive_seed(config.seed, kOdometryStream + i));
    run.odometry_errors = odometry.errors();
    Pose2 x_OR;
    Pose2 x_WR_previous;
    for (std::size_t k = 0; k < times[i].size(); ++k) {
      const double t = times[i][k];
      const Pose2 x_WR = run.true_poses[k];
      std::vector<Circle> discs;
      if (config.robots_visible_in_scans && config.robot_radius_m > 0.0) {
        for (std::size_t j = 0; j < n; ++j) {
          if (j == i) continue;
          const Pose2& x_WB = mission.robots[j].true_poses[k];
          discs.push_back({{x_WB.x, x_WB.y}, config.robot_radius_m});
        }
      }
      for (const auto& person : mission.people) discs.push_back({person.position_at(t), person.radius_m});

      LaserScan scan = simulate_scan(walls, x_WR, config.laser, discs, laser_rng);
      scan.utime = std::llround((config.start_time_s + t) * 1e6);
      if (k == 0) {
        x_OR = x_WR;  // the odometry frame starts at the true start pose
      } else {
        const Pose2 u = between(x_WR_previous, x_WR);
        const Pose2 x_OR_next = compose(x_OR, odometry.increment(u));
        run.distance_m += std::hypot(u.x, u.y);
        run.odometry_distance_m += std::hypot(x_OR_next.x - x_OR.x, x_OR_next.y - x_OR.y);
        x_OR = x_OR_next;
      }
      scan.odometry = x_OR;
      run.scans.push_back(std::move(scan));
      x_WR_previous = x_WR;
    }
  }

  // Sightings at the observer's scan times, thinned per ordered pair.
  std::map<std::pair<int, int>, double> last;
  for (std::size_t a = 0; a < n; ++a) {
    for (std::size_t k = 0; k < times[a].size(); ++k) {
      const double t = times[a][k];
      const Pose2& x_WA = mission.robots[a].true_poses[k];
      for (std::size_t b = 0; b < n; ++b) {
        if (b == a) continue;
        const auto key = std::make_pair(static_cast<int>(a), static_cast<int>(b));
        const auto it = last.find(key);
        if (it != last.end() && t - it->second < config.sightings.min_interval_s) continue;
        const Pose2& x_WB = mission.robots[b].true_poses[k];
        if (!robot_visible(walls, x_WA, x_WB, config.sightings)) continue;
        last[key] = t;
        Sighting s;
        s.utime = mission.robots[a].scans[k].utime;
        s.observer = static_cast<int>(a);
        s.observed = static_cast<int>(b);
        s.observer_scan = k;
        s.observed_scan = k;
        s.x_AB = between(x_WA, x_WB);
        s.range_m = std::hypot(s.x_AB.x, s.x_AB.y);
        mission.sightings.push_back(s);
      }
    }
  }
  std::sort(mission.sightings.begin(), mission.sightings.end(), [](const Sighting& l, const Sighting& r) {
    return std::tie(l.utime, l.observer, l.observed) < std::tie(r.utime, r.observer, r.observed);
  });
  return mission;
}

}  // namespace lmf::sim
