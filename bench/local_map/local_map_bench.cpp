// lmf_bench_local_map: one full per-scan update of the robot local map
// (prediction, pairing, joint compatibility, EKF update, geometric update,
// fusion, additions, constraints, covariance check) with about 20, 80 and 170
// map segments (paper §II.B: 170 features was the real-time limit of the
// original; docs/design.md §4: "we aim far below" 10 ms).
//
// The maps are built by driving the local map itself down a synthetic corridor
// (walls broken by doorways, a room wall at every doorway) with seeded odometry
// and observation noise, so P is a realistic dense, correlated covariance. The
// timed scan then sees the nearby walls again plus one new wall across the
// corridor ahead (paired, added and constrained in the same update). Each
// iteration updates a fresh copy of the same map (the copy is not timed), and
// the per-update times give the median, p99 and max counters (wall clock, and
// cpu_* from the thread's CPU clock, which a busy machine's preemption does not
// inflate). check_every is LocalMapConfig::covariance_check_interval, the
// covariance supervision (a shifted Cholesky of P, O(n³/3)): 0 never (the
// bench never ships), 1 every scan, 10 the default. So that every setting is
// timed over a whole cycle of it, an iteration is kScansPerIteration scans in a
// row (the timed scan, then the robot standing still and seeing it again), each
// timed on its own: the median is the typical scan, p99 and max the checked ones.
#include <algorithm>
#include <chrono>
#include <ctime>
#include <cmath>
#include <random>
#include <utility>
#include <vector>

#include <benchmark/benchmark.h>

#include "lmf/local_map/local_map.hpp"

namespace {

using lmf::LocalMap;
using lmf::ObservedSegment;
using lmf::Pose2;

constexpr double kCorridorHalfWidth = 1.5;  // m
constexpr double kPiece = 2.0;              // m of wall between doorways
constexpr double kDoor = 0.8;               // m
constexpr double kRoomDepth = 3.0;          // m of room wall behind each doorway
constexpr double kRange = 7.0;              // m: walls whose nearest point is closer are seen
constexpr int kScansPerIteration = 10;      // a whole cycle of the default supervision

struct Wall {
  Eigen::Vector2d a;
  Eigen::Vector2d b;
};

// Both sides of the corridor: a piece of wall, then a doorway with a room wall
// going away from the corridor at its far edge.
std::vector<Wall> corridor(double length_m) {
  std::vector<Wall> walls;
  for (double x = 0.0; x < length_m; x += kPiece + kDoor) {
    for (double side : {1.0, -1.0}) {
      const double y = side * kCorridorHalfWidth;
      walls.push_back({{x, y}, {x + kPiece, y}});
      walls.push_back({{x + kPiece + kDoor, y}, {x + kPiece + kDoor, y + side * kRoomDepth}});
    }
  }
  return walls;
}

double distance_to(const Wall& w, const Eigen::Vector2d& p) {
  const Eigen::Vector2d d = w.b - w.a;
  const double t = std::clamp((p - w.a).dot(d) / d.squaredNorm(), 0.0, 1.0);
  return (w.a + t * d - p).norm();
}

// The walls a forward-looking 180° laser sees from x_LR, as noisy observations
// in the robot frame (midpoint frame, sensor on the left).
std::vector<ObservedSegment> observe(const std::vector<Wall>& walls, const Pose2& x_LR, std::mt19937& rng) {
  std::normal_distribution<double> lateral(0.0, 0.01);
  std::normal_distribution<double> angular(0.0, 0.005);
  const Pose2 x_RL = lmf::inverse(x_LR);
  std::vector<ObservedSegment> out;
  for (const Wall& w : walls) {
    if (distance_to(w, {x_LR.x, x_LR.y}) > kRange) continue;
    Eigen::Vector2d a = x_RL.transform_point(w.a);
    Eigen::Vector2d b = x_RL.transform_point(w.b);
    if (a.x() < 0.0 && b.x() < 0.0) continue;  // behind the laser
    // Clip to the half plane in front of the sensor.
    if (a.x() < 0.0 || b.x() < 0.0) {
      const Eigen::Vector2d& back = a.x() < 0.0 ? a : b;
      const Eigen::Vector2d& front = a.x() < 0.0 ? b : a;
      const Eigen::Vector2d cut = back + (front - back) * ((0.05 - back.x()) / (front.x() - back.x()));
      (a.x() < 0.0 ? a : b) = cut;
    }
    if ((b - a).norm() < 0.4) continue;
    const Eigen::Vector2d mid = 0.5 * (a + b);
    Eigen::Vector2d d = (b - a).normalized();
    if (Eigen::Vector2d(-d.y(), d.x()).dot(-mid) < 0.0) d = -d;
    ObservedSegment e;
    e.length_m = (b - a).norm();
    e.location = lmf::compose(Pose2(mid.x(), mid.y(), std::atan2(d.y(), d.x())),
                              Pose2(0.0, lateral(rng), angular(rng)));
    e.covariance << 1e-4, 0.0, 0.0, 2.5e-5;
    e.num_points = 40;
    out.push_back(e);
  }
  return out;
}

double thread_cpu_seconds() {
  timespec ts{};
  clock_gettime(CLOCK_THREAD_CPUTIME_ID, &ts);
  return static_cast<double>(ts.tv_sec) + 1e-9 * static_cast<double>(ts.tv_nsec);
}

struct Setup {
  LocalMap map;
  int64_t utime = 0;
  Pose2 odometry;                          // of the last scan folded in
  Pose2 next_odometry;                     // of the timed scan
  std::vector<ObservedSegment> next_scan;  // observations of the timed scan
};

// Drives down the corridor until the map holds at least `segments` segments.
Setup build(std::size_t segments, std::size_t check_every) {
  const std::vector<Wall> walls = corridor(400.0);
  lmf::LocalMapConfig config;
  config.covariance_check_interval = check_every;
  config.ship_distance_m = 1e9;
  config.max_segments = 100000;
  Setup s{LocalMap(config), 0, Pose2(), Pose2(), {}};
  std::mt19937 rng(7);
  std::normal_distribution<double> noise(0.0, 1.0);
  Pose2 truth(-1.0, 0.0, 0.0);
  Pose2 odometry = truth;
  const Pose2 step(0.5, 0.0, 0.0);
  for (;;) {
    const std::vector<ObservedSegment> scan = observe(walls, truth, rng);
    if (s.map.num_segments() >= segments) {
      // The timed scan also sees a new wall across the corridor ahead (a
      // screen nobody has seen yet): one addition and its perpendicular constraint.
      std::vector<Wall> screen = {{{truth.x + 4.0, -1.0}, {truth.x + 4.0, 0.5}}};
      s.next_odometry = odometry;
      s.next_scan = scan;
      for (const ObservedSegment& e : observe(screen, truth, rng)) s.next_scan.push_back(e);
      return s;
    }
    s.map.update(s.utime, odometry, scan);
    s.odometry = odometry;
    s.utime += 200000;
    truth = lmf::compose(truth, step);
    const Pose2 noisy(step.x * (1.0 + 0.08 * noise(rng)), 0.04 * noise(rng), 0.01 * noise(rng));
    odometry = lmf::compose(odometry, noisy);
  }
}

void BM_LocalMapScanUpdate(benchmark::State& state) {
  const Setup setup = build(static_cast<std::size_t>(state.range(0)), static_cast<std::size_t>(state.range(1)));
  std::vector<double> times_us;      // wall clock, one per scan
  std::vector<double> cpu_times_us;  // this thread's CPU time: immune to preemption on a busy machine
  lmf::ScanReport last;              // of the first scan of an iteration
  std::size_t checked = 0;
  for (auto _ : state) {
    LocalMap map = setup.map;  // untimed copy: every iteration updates the same map
    double iteration_seconds = 0.0;
    for (int k = 0; k < kScansPerIteration; ++k) {
      const double c0 = thread_cpu_seconds();
      const auto t0 = std::chrono::steady_clock::now();
      lmf::ScanReport report = map.update(setup.utime + k * 200000, setup.next_odometry, setup.next_scan);
      const auto t1 = std::chrono::steady_clock::now();
      const double c1 = thread_cpu_seconds();
      benchmark::DoNotOptimize(report);
      if (report.covariance_checked) ++checked;
      if (k == 0) last = std::move(report);
      const double seconds = std::chrono::duration<double>(t1 - t0).count();
      iteration_seconds += seconds;
      times_us.push_back(seconds * 1e6);
      cpu_times_us.push_back((c1 - c0) * 1e6);
    }
    state.SetIterationTime(iteration_seconds / kScansPerIteration);
  }
  std::sort(times_us.begin(), times_us.end());
  std::sort(cpu_times_us.begin(), cpu_times_us.end());
  const auto quantile = [](const std::vector<double>& sorted, double q) {
    return sorted[std::min(sorted.size() - 1, static_cast<std::size_t>(q * static_cast<double>(sorted.size())))];
  };
  const auto at = [&](double q) { return quantile(times_us, q); };
  state.counters["cpu_p50_us"] = quantile(cpu_times_us, 0.5);
  state.counters["cpu_p99_us"] = quantile(cpu_times_us, 0.99);
  state.counters["segments"] = static_cast<double>(setup.map.num_segments());
  state.counters["observations"] = last.observations;
  state.counters["tested"] = last.pairings_tried - last.pairings_rejected_overlap;
  state.counters["paired"] = last.pairings_accepted_joint;
  state.counters["added"] = last.segments_added;
  state.counters["constraints"] = last.constraints_applied;
  state.counters["checked_fraction"] = static_cast<double>(checked) / static_cast<double>(times_us.size());
  double sum_us = 0.0;
  for (double t : times_us) sum_us += t;
  state.counters["mean_us"] = sum_us / static_cast<double>(times_us.size());
  state.counters["p50_us"] = at(0.5);
  state.counters["p99_us"] = at(0.99);
  state.counters["max_us"] = times_us.back();
}

// Args: segments, covariance_check_interval (0 never, 1 every scan, 10 the default).
BENCHMARK(BM_LocalMapScanUpdate)
    ->ArgNames({"segments", "check_every"})
    ->ArgsProduct({{20, 80, 170}, {0, 1, static_cast<int64_t>(lmf::LocalMapConfig().covariance_check_interval)}})
    ->UseManualTime()
    ->Unit(benchmark::kMicrosecond)
    ->MinTime(1.0);

}  // namespace

BENCHMARK_MAIN();
