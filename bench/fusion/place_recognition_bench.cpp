// lmf_bench_place: place recognition (lmf/fusion/place_recognition.hpp) of one
// local map in global maps of about 250, 500, 1000 and 2000 segments (issue 38:
// 1000 segments in <= 50 ms, median).
//
// The building: 12 m cells along a serpentine (fusion/serpentine_building.hpp's
// layout), each holding 30 walls of 1-3 m at random places and axis-aligned
// headings, so no two cells look alike. The local map is the walls of one cell
// (every repetition a different one) seen from a random frame in that cell at
// a random heading. Each run checks that the place found is the true one
// within the registration's resolution (the benchmark fails otherwise).
//
// Usage: lmf_bench_place [Google Benchmark flags]
#include <cmath>
#include <random>
#include <vector>

#include <benchmark/benchmark.h>

#include "fusion/serpentine_building.hpp"
#include "lmf/fusion/place_recognition.hpp"

namespace {

using lmf::Pose2;
using lmf::fusion::RegistrationSegment;
namespace synthetic = lmf::fusion::synthetic;

std::vector<RegistrationSegment> cell_walls(int cell, std::mt19937& rng) {
  const Pose2 c = synthetic::serpentine_cell_frame(cell);
  std::uniform_real_distribution<double> position(-5.5, 5.5);
  std::uniform_real_distribution<double> length(1.0, 3.0);
  std::uniform_int_distribution<int> quarter(0, 3);
  std::vector<RegistrationSegment> walls;
  for (int w = 0; w < synthetic::kWallsPerCell; ++w) {
    walls.push_back({Pose2(c.x + position(rng), c.y + position(rng), quarter(rng) * M_PI / 2), length(rng)});
  }
  return walls;
}

void BM_RecognisePlace(benchmark::State& state) {
  const int cells = static_cast<int>(state.range(0)) / synthetic::kWallsPerCell;
  std::mt19937 rng(38);
  std::vector<std::vector<RegistrationSegment>> building;
  std::vector<RegistrationSegment> global;
  for (int i = 0; i < cells; ++i) {
    building.push_back(cell_walls(i, rng));
    global.insert(global.end(), building.back().begin(), building.back().end());
  }
  const lmf::fusion::FrameRegistrationConfig registration;
  const lmf::fusion::PlaceRecognitionConfig config;
  std::uniform_real_distribution<double> offset(-3.0, 3.0);
  std::uniform_real_distribution<double> heading(-M_PI, M_PI);
  int cell = 0;
  for (auto _ : state) {
    state.PauseTiming();
    cell = (cell + 7) % cells;
    const Pose2 centre = synthetic::serpentine_cell_frame(cell);
    const Pose2 x_WL(centre.x + offset(rng), centre.y + offset(rng), heading(rng));
    std::vector<RegistrationSegment> local;
    for (const RegistrationSegment& s : building[static_cast<std::size_t>(cell)]) {
      local.push_back({lmf::between(x_WL, s.location), s.length_m});
    }
    state.ResumeTiming();
    const lmf::fusion::PlaceRecognition place = lmf::fusion::recognise_place(local, global, registration, config);
    benchmark::DoNotOptimize(place);
    const Pose2 error = lmf::between(x_WL, place.x_WL);
    if (place.outcome != lmf::fusion::PlaceOutcome::kPlaced || std::hypot(error.x, error.y) > 0.1) {
      state.SkipWithError("the local map was not placed at its true place");
      break;
    }
  }
  state.counters["segments"] = static_cast<double>(global.size());
}
BENCHMARK(BM_RecognisePlace)->Arg(250)->Arg(500)->Arg(1000)->Arg(2000)->Unit(benchmark::kMillisecond);

}  // namespace

BENCHMARK_MAIN();
