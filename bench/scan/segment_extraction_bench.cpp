// Segment extraction on one 361-beam scan: a real belgioioso scan when the
// shared datasets are present, else a synthetic corridor scan. The real-time
// budget of a 5 Hz laser is 200 ms per scan for the whole agent (docs/design.md §4).
#include <cmath>
#include <cstdlib>
#include <filesystem>
#include <iostream>
#include <numbers>
#include <string>

#include <benchmark/benchmark.h>

#include "lmf/io/carmen.hpp"
#include "lmf/scan/segment_extraction.hpp"

namespace {

// A corridor 2.4 m wide with doors and a cross wall 12 m ahead, 361 beams over 180°.
lmf::LaserScan synthetic_corridor() {
  lmf::LaserScan scan;
  scan.angle_min_rad = -std::numbers::pi / 2.0;
  scan.angle_increment_rad = lmf::beam_increment_for_180deg(361);
  scan.max_range_m = 80.0;
  scan.ranges_m.resize(361);
  for (std::size_t i = 0; i < scan.ranges_m.size(); ++i) {
    const double a = scan.beam_angle(i);
    const double c = std::cos(a);
    const double s = std::sin(a);
    double r = c > 1e-9 ? 12.0 / c : 1e9;                         // end wall x = 12
    if (std::abs(s) > 1e-9) r = std::min(r, 1.2 / std::abs(s));  // side walls y = ±1.2
    const double x = r * c;
    if (std::abs(s) > 1e-9 && std::fmod(x, 4.0) > 3.0) r = 1.4 / std::abs(s);  // door recesses
    r += 0.01 * std::sin(37.0 * static_cast<double>(i));  // deterministic "noise"
    scan.ranges_m[i] = std::min(r, scan.max_range_m);
  }
  return scan;
}

// Scan 100 of belgioioso if the datasets are there (LMF_DATASETS_DIR or ../shared/datasets).
lmf::LaserScan bench_scan(std::string& source) {
  const char* env = std::getenv("LMF_DATASETS_DIR");
  const std::filesystem::path dir = env != nullptr ? env : LMF_BENCH_DATASETS_DIR;
  const std::filesystem::path log_file = dir / "belgioioso-corrected.log.gz";
  if (std::filesystem::exists(log_file)) {
    const lmf::io::CarmenLog log = lmf::io::read_carmen_log(log_file);
    if (log.scans.size() > 100) {
      source = "belgioioso scan 100";
      return log.scans[100];
    }
  }
  source = "synthetic corridor";
  return synthetic_corridor();
}

void BM_ExtractSegments(benchmark::State& state) {
  std::string source;
  const lmf::LaserScan scan = bench_scan(source);
  const lmf::ExtractionConfig config;
  std::size_t segments = 0;
  for (auto _ : state) {
    const auto result = lmf::extract_segments(scan, config);
    segments = result.size();
    benchmark::DoNotOptimize(result.data());
  }
  state.SetLabel(source + ", " + std::to_string(scan.ranges_m.size()) + " beams, " + std::to_string(segments) +
                 " segments");
}
BENCHMARK(BM_ExtractSegments)->Unit(benchmark::kMicrosecond);

void BM_ExtractSegmentsSyntheticCorridor(benchmark::State& state) {
  const lmf::LaserScan scan = synthetic_corridor();
  const lmf::ExtractionConfig config;
  std::size_t segments = 0;
  for (auto _ : state) {
    const auto result = lmf::extract_segments(scan, config);
    segments = result.size();
    benchmark::DoNotOptimize(result.data());
  }
  state.SetLabel(std::to_string(segments) + " segments");
}
BENCHMARK(BM_ExtractSegmentsSyntheticCorridor)->Unit(benchmark::kMicrosecond);

}  // namespace

BENCHMARK_MAIN();
