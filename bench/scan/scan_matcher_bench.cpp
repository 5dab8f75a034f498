// The local map's scan matcher (step 1, scan_matcher.hpp) alone: the match of
// scan k against the history of the scans before it (search + refinement),
// then adding scan k to the history (its reference for the next match), over
// every scan of belgioioso-realodo in order (361 beams, odometry like a real
// robot's as prior), or a synthetic room when the shared datasets are absent.
// lmf-scan-match reports the match's per-scan CPU times as p50/p99 with the errors.
#include <algorithm>
#include <cmath>
#include <cstdlib>
#include <filesystem>
#include <numbers>
#include <string>
#include <vector>

#include <benchmark/benchmark.h>

#include "lmf/io/carmen.hpp"
#include "lmf/local_map/local_map_config.hpp"
#include "lmf/local_map/local_map_measurements.hpp"
#include "lmf/front_end/scan_history.hpp"
#include "lmf/scan/scan_matcher.hpp"

namespace {

std::vector<lmf::LaserScan> bench_scans(std::string& source) {
  const char* env = std::getenv("LMF_DATASETS_DIR");
  const std::filesystem::path dir = env != nullptr ? env : LMF_BENCH_DATASETS_DIR;
  const std::filesystem::path log_file = dir / "belgioioso-realodo.log.gz";
  if (std::filesystem::exists(log_file)) {
    source = "belgioioso-realodo, every scan in order";
    return lmf::io::read_carmen_log(log_file).scans;
  }
  // The end of a 6 m wide hall 8 m ahead, seen from a robot moving 0.5 m per scan.
  source = "synthetic room (datasets absent)";
  std::vector<lmf::LaserScan> scans;
  for (int k = 0; k < 8; ++k) {
    lmf::LaserScan scan;
    scan.angle_min_rad = -std::numbers::pi / 2.0;
    scan.angle_increment_rad = lmf::beam_increment_for_180deg(361);
    scan.max_range_m = 80.0;
    scan.odometry = lmf::Pose2(0.5 * k, 0.0, 0.0);
    for (std::size_t i = 0; i < 361; ++i) {
      const double a = scan.beam_angle(i);
      const double x0 = 0.5 * k;
      const double c = std::cos(a);
      const double s = std::sin(a);
      double r = c > 1e-9 ? (8.0 - x0) / c : 1e9;  // end wall x = 8
      if (std::abs(s) > 1e-9) r = std::min(r, 3.0 / std::abs(s));  // side walls y = ±3
      scan.ranges_m.push_back(r);
    }
    scans.push_back(scan);
  }
  return scans;
}

void BM_MatchConsecutiveScans(benchmark::State& state) {
  std::string source;
  const std::vector<lmf::LaserScan> scans = bench_scans(source);
  const lmf::LocalMapConfig config;
  std::size_t k = 1;
  int matched = 0;
  int tried = 0;
  lmf::ScanHistory history(config.scan_matching);
  history.add(scans.front(), lmf::Pose2(), false);
  for (auto _ : state) {
    const lmf::LaserScan& a = scans[k - 1];
    const lmf::LaserScan& b = scans[k];
    const lmf::Pose2 u = lmf::between(a.odometry, b.odometry);
    const auto m = lmf::match_scans(history.reference(), lmf::scan_points_by_kind(b, config.scan_matching), u,
                                    lmf::local_map::odometry_noise(u, config), config.scan_matching);
    history.add(b, m ? m->x_AB : u, m.has_value());
    benchmark::DoNotOptimize(m);
    matched += m.has_value() ? 1 : 0;
    ++tried;
    if (k + 1 < scans.size()) {
      ++k;
    } else {
      k = 1;
      history.add(scans.front(), lmf::Pose2(), false);
    }
  }
  state.SetLabel(source + ", " + std::to_string(scans.size() - 1) + " increments, " + std::to_string(matched) + "/" +
                 std::to_string(tried) + " matched");
}
BENCHMARK(BM_MatchConsecutiveScans)->Unit(benchmark::kMicrosecond);

}  // namespace
