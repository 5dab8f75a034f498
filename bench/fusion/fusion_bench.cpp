// lmf_bench_fusion: time to fuse one local map (30 segments, half of them
// re-observed) into global maps of about 100, 500, 1000, 2000 and 4000
// segments, next to one rank-k update of a covariance lower triangle of the same
// size (k = rows kept by that fusion's EKF update), measured in the same loop.
// docs/design.md §9: the fusion's cost is bounded below by that update; the ratio is
// the overhead of everything else (target <= 2).
//
// The global maps are built by fusing synthetic local maps, one per 12 m cell
// of a serpentine grid of cells: 30 new walls per cell (one submap each) plus 3
// walls of the previous cell seen again, so P is dense and correlated as in a
// real run. The state keeps spare capacity (steady state: the buffer grows by
// 25 % at a time, which a single fusion rarely triggers).
//
// Usage: lmf_bench_fusion [--sizes=100,500,...] [Google Benchmark flags]
#include <algorithm>
#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <random>
#include <sstream>
#include <string>
#include <vector>

#include <Eigen/Core>
#include <benchmark/benchmark.h>

#include "fusion/serpentine_building.hpp"
#include "lmf/fusion/global_map.hpp"

namespace {

using lmf::fusion::FusionReport;
using lmf::fusion::GlobalMap;
using lmf::fusion::synthetic::Wall;
namespace synthetic = lmf::fusion::synthetic;
using Clock = std::chrono::steady_clock;

// The growing global map shared by the sizes (built once, in increasing size).
struct World {
  GlobalMap map;
  std::mt19937 rng{2024};
  int cells = 0;  // local maps fused so far (the robot is at cell `cells`)

  void grow_to(int segments) {
    while (map.counts().segments < segments) {
      map.fuse(synthetic::serpentine_growth_snapshot(cells, rng));
      ++cells;
    }
  }

  // The measured local map: 15 walls of the last cell again, 15 of the next one.
  lmf::LocalMapSnapshot measured_snapshot() {
    std::vector<Wall> seen;
    const std::vector<Wall> previous = synthetic::serpentine_cell_walls(cells - 1);
    const std::vector<Wall> next = synthetic::serpentine_cell_walls(cells);
    seen.insert(seen.end(), previous.begin(), previous.begin() + 15);
    seen.insert(seen.end(), next.begin(), next.begin() + 15);
    return synthetic::serpentine_snapshot(cells, seen, rng);
  }
};

World& world() {
  static World w;
  return w;
}

double median(std::vector<double> v) {
  std::sort(v.begin(), v.end());
  const std::size_t n = v.size();
  return n % 2 == 1 ? v[n / 2] : 0.5 * (v[n / 2 - 1] + v[n / 2]);
}

struct Row {
  int segments = 0;
  long n = 0;
  int k = 0;
  int pairings = 0;
  double fusion_ms = 0.0;  // medians
  double rankk_ms = 0.0;
  double update_ms = 0.0;
  double fusion_min_ms = 0.0;  // best of the iterations (least disturbed by other processes)
  double rankk_min_ms = 0.0;
};
std::vector<Row>& rows() {
  static std::vector<Row> r;
  return r;
}

void BM_FuseLocalMap(benchmark::State& state) {
  World& w = world();
  w.grow_to(static_cast<int>(state.range(0)));
  const lmf::LocalMapSnapshot snapshot = w.measured_snapshot();
  // Steady state: some spare capacity (the buffer grows by 25 % when full).
  w.map.reserve(w.map.state().dimension() + std::max<Eigen::Index>(64, w.map.state().dimension() / 8));

  std::vector<double> fusion_s;
  std::vector<double> rankk_s;
  std::vector<double> phase[9];
  FusionReport last;
  Eigen::MatrixXd P_ref;
  Eigen::MatrixXd U;
  for (auto _ : state) {
    GlobalMap copy = w.map;  // not timed (the timed region is the fuse call)
    const Clock::time_point t0 = Clock::now();
    const std::vector<FusionReport> reports = copy.fuse(snapshot);
    const Clock::time_point t1 = Clock::now();
    const double seconds = std::chrono::duration<double>(t1 - t0).count();
    state.SetIterationTime(seconds);
    fusion_s.push_back(seconds);
    if (reports.size() != 1) {
      state.SkipWithError("the measured local map was not fused");
      return;
    }
    last = reports[0];
    const auto& t = last.time;
    const double phases[9] = {t.augment_s, t.gate_s,   t.individual_s, t.joint_s, t.update_s,
                              t.geometric_s, t.frames_s, t.remove_s,     t.health_s};
    for (int i = 0; i < 9; ++i) phase[i].push_back(phases[i]);

    // The reference: one rank-k update of an n x n lower triangle, n and k of this fusion.
    const Eigen::Index n = last.update_dimension;
    const Eigen::Index k = std::max(1, last.rows_kept);
    if (P_ref.rows() != n) {
      P_ref = Eigen::MatrixXd::Zero(n, n);  // touched: no page faults in the timing
      U = 1e-3 * Eigen::MatrixXd::Random(n, k);
    }
    const Clock::time_point r0 = Clock::now();
    P_ref.selfadjointView<Eigen::Lower>().rankUpdate(U, -1.0);
    const Clock::time_point r1 = Clock::now();
    benchmark::DoNotOptimize(P_ref.data());
    rankk_s.push_back(std::chrono::duration<double>(r1 - r0).count());
  }
  const double fusion_ms = 1e3 * median(fusion_s);
  const double rankk_ms = 1e3 * median(rankk_s);
  state.counters["segments"] = w.map.counts().segments;
  state.counters["n"] = static_cast<double>(last.update_dimension);
  state.counters["k"] = last.rows_kept;
  state.counters["gated"] = static_cast<double>(last.pairs_considered - last.gate_rejected);
  state.counters["jc_candidates"] = last.jc_candidates;
  state.counters["pairings"] = last.pairings_accepted;
  state.counters["new"] = last.new_segments;
  state.counters["fusion_ms"] = fusion_ms;
  state.counters["rankk_ms"] = rankk_ms;
  state.counters["ratio"] = fusion_ms / rankk_ms;
  const double fusion_min_ms = 1e3 * *std::min_element(fusion_s.begin(), fusion_s.end());
  const double rankk_min_ms = 1e3 * *std::min_element(rankk_s.begin(), rankk_s.end());
  state.counters["ratio_min"] = fusion_min_ms / rankk_min_ms;
  const char* names[9] = {"augment_ms", "gate_ms", "indiv_ms", "jc_ms", "update_ms",
                          "geom_ms",    "frames_ms", "remove_ms", "health_ms"};
  for (int i = 0; i < 9; ++i) state.counters[names[i]] = 1e3 * median(phase[i]);
  rows().push_back({w.map.counts().segments, static_cast<long>(last.update_dimension), last.rows_kept,
                    last.pairings_accepted, fusion_ms, rankk_ms, 1e3 * median(phase[4]), fusion_min_ms, rankk_min_ms});
}

std::vector<int> parse_sizes(int& argc, char** argv) {
  std::vector<int> sizes{100, 500, 1000, 2000, 4000};
  for (int i = 1; i < argc; ++i) {
    const std::string arg = argv[i];
    if (arg.rfind("--sizes=", 0) != 0) continue;
    sizes.clear();
    std::stringstream list(arg.substr(8));
    std::string item;
    while (std::getline(list, item, ',')) {
      const int size = std::atoi(item.c_str());
      if (size <= 0) {
        std::fprintf(stderr, "lmf_bench_fusion: bad size '%s' in %s\n", item.c_str(), arg.c_str());
        std::exit(2);
      }
      sizes.push_back(size);
    }
    std::sort(sizes.begin(), sizes.end());
    for (int j = i; j + 1 < argc; ++j) argv[j] = argv[j + 1];
    --argc;
    break;
  }
  return sizes;
}

}  // namespace

int main(int argc, char** argv) {
  const std::vector<int> sizes = parse_sizes(argc, argv);
  for (const int size : sizes) {
    // Fewer repetitions for the large maps (each one copies a P of up to ~0.7 GB);
    // the medians of fusion and reference are compared, both measured in one loop.
    const int iterations = std::max(5, 20000 / size);
    benchmark::RegisterBenchmark("BM_FuseLocalMap", BM_FuseLocalMap)
        ->Arg(size)
        ->Iterations(iterations)
        ->UseManualTime()
        ->Unit(benchmark::kMillisecond);
  }
  benchmark::Initialize(&argc, argv);
  if (benchmark::ReportUnrecognizedArguments(argc, argv)) return 1;
  benchmark::RunSpecifiedBenchmarks();
  benchmark::Shutdown();

  // Medians over the iterations, and the ratio of the best times.
  std::printf("\n%9s %7s %4s %8s %11s %11s %11s %7s %10s\n", "segments", "n", "k", "pairings", "fusion_ms",
              "update_ms", "rank-k_ms", "ratio", "ratio_min");
  for (const Row& r : rows()) {
    std::printf("%9d %7ld %4d %8d %11.3f %11.3f %11.3f %7.2f %10.2f\n", r.segments, r.n, r.k, r.pairings,
                r.fusion_ms, r.update_ms, r.rankk_ms, r.fusion_ms / r.rankk_ms, r.fusion_min_ms / r.rankk_min_ms);
  }
  return 0;
}
