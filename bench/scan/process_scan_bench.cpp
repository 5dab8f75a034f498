// The local map's whole per-scan step, LocalMap::process_scan (scan match
// against the recent scans, segment extraction, EKF update and the rest of
// docs/design.md §4, with ship-and-reset every ~10 m as the agent does), on every scan
// of belgioioso-realodo (361 beams, odometry like a real robot's) in order, or
// on a synthetic room when the shared datasets are absent. One iteration is
// one scan; besides the mean, the counters give the per-scan CPU time's p50,
// p99 and max (us) over the iterations of the run.
#include <algorithm>
#include <cmath>
#include <cstdlib>
#include <ctime>
#include <filesystem>
#include <memory>
#include <numbers>
#include <string>
#include <vector>

#include <benchmark/benchmark.h>

#include "lmf/io/carmen.hpp"
#include "lmf/local_map/local_map.hpp"

namespace {

std::vector<lmf::LaserScan> realodo_scans(std::string& source) {
  const char* env = std::getenv("LMF_DATASETS_DIR");
  const std::filesystem::path dir = env != nullptr ? env : LMF_BENCH_DATASETS_DIR;
  const std::filesystem::path log_file = dir / "belgioioso-realodo.log.gz";
  if (std::filesystem::exists(log_file)) {
    source = "belgioioso-realodo, every scan in order";
    return lmf::io::read_carmen_log(log_file).scans;
  }
  // A 6 m wide hall with an end wall 14 m ahead, driven 0.5 m per scan.
  source = "synthetic hall (datasets absent)";
  std::vector<lmf::LaserScan> scans;
  for (int k = 0; k < 20; ++k) {
    lmf::LaserScan scan;
    scan.utime = 200000 * k;
    scan.angle_min_rad = -std::numbers::pi / 2.0;
    scan.angle_increment_rad = lmf::beam_increment_for_180deg(361);
    scan.max_range_m = 80.0;
    scan.odometry = lmf::Pose2(0.5 * k, 0.0, 0.0);
    for (std::size_t i = 0; i < 361; ++i) {
      const double a = scan.beam_angle(i);
      const double c = std::cos(a);
      const double s = std::sin(a);
      double r = c > 1e-9 ? (14.0 - 0.5 * k) / c : 1e9;
      if (std::abs(s) > 1e-9) r = std::min(r, 3.0 / std::abs(s));
      scan.ranges_m.push_back(r);
    }
    scans.push_back(scan);
  }
  return scans;
}

double thread_cpu_micros() {
  timespec t{};
  clock_gettime(CLOCK_THREAD_CPUTIME_ID, &t);
  return 1e6 * static_cast<double>(t.tv_sec) + 1e-3 * static_cast<double>(t.tv_nsec);
}

double quantile(std::vector<double> v, double q) {
  if (v.empty()) return 0.0;
  std::sort(v.begin(), v.end());
  return v[static_cast<std::size_t>(q * static_cast<double>(v.size() - 1))];
}

void BM_LocalMapProcessScan(benchmark::State& state) {
  std::string source;
  const std::vector<lmf::LaserScan> scans = realodo_scans(source);
  const lmf::LocalMapConfig config;
  auto map = std::make_unique<lmf::LocalMap>(config);
  std::size_t k = 0;
  int matched = 0;
  int tried = 0;
  std::vector<double> micros;
  for (auto _ : state) {
    if (k == scans.size()) {  // the log again, from a fresh agent
      state.PauseTiming();
      map = std::make_unique<lmf::LocalMap>(config);
      k = 0;
      state.ResumeTiming();
    }
    const double t0 = thread_cpu_micros();
    const lmf::ScanReport report = map->process_scan(scans[k]);
    if (report.should_ship) {
      benchmark::DoNotOptimize(map->snapshot());
      map->reset();
    }
    micros.push_back(thread_cpu_micros() - t0);
    matched += report.scan_matched ? 1 : 0;
    tried += report.scan_match_tried ? 1 : 0;
    ++k;
  }
  state.counters["p50_us"] = quantile(micros, 0.5);
  state.counters["p99_us"] = quantile(micros, 0.99);
  state.counters["max_us"] = quantile(micros, 1.0);
  state.SetLabel(source + ", " + std::to_string(matched) + "/" + std::to_string(tried) + " matched");
}
BENCHMARK(BM_LocalMapProcessScan)->Unit(benchmark::kMicrosecond)->Iterations(2000);

}  // namespace
