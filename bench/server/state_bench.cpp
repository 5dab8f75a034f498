// lmf_bench_state: the cost of lmf-server's durable state (fusion_server/
// state_store.hpp) for global maps of about 100, 500, 1000 and 2000 segments:
//   EncodeServerState   the snapshot payload (map archive + book + records), on the worker
//   WriteSnapshot       snapshot.tmp written + fsync, renames, fsync of the directory,
//                       journal rotation (what write_snapshot() does, after the encode)
//   Recover             read + CRC + decode of the snapshot (a restart, no journal)
//   JournalAppend       one local map of 30 segments appended and fdatasync'ed
// Real time (the fsyncs wait for the disk). The maps are built as in
// lmf_bench_fusion: synthetic local maps fused one per 12 m cell of a
// serpentine, 30 new walls per cell, so P is dense.
//
// Usage: lmf_bench_state [Google Benchmark flags]; the files go into
// $LMF_BENCH_STATE_DIR (default: a folder under the temp directory), which
// should be on the disk the server will use.
#include <chrono>
#include <cstdlib>
#include <filesystem>
#include <map>
#include <memory>
#include <random>
#include <string>
#include <vector>

#include <benchmark/benchmark.h>

#include "fusion/serpentine_building.hpp"
#include "fusion_server/state_store.hpp"
#include "lmf/fusion/global_map.hpp"
#include "runtime/convert.hpp"

namespace {

namespace fs = std::filesystem;
using lmf::fusion::GlobalMap;
namespace synthetic = lmf::fusion::synthetic;

struct World {
  lmf::server::FusionContext fusion{GlobalMap()};
  std::mt19937 rng{2024};
  int cells = 0;

  void grow_to(int segments) {
    while (fusion.map().counts().segments < segments) {
      fusion.fuse(synthetic::serpentine_growth_snapshot(cells, rng), 0.0);
      ++cells;
    }
  }
  std::string payload() const { return lmf::server::encode_server_state(fusion, {}); }
};

// One map per size (each built from scratch: a benchmark may run alone).
World& world(int segments) {
  static std::map<int, std::unique_ptr<World>> worlds;
  std::unique_ptr<World>& w = worlds[segments];
  if (!w) {
    w = std::make_unique<World>();
    w->grow_to(segments);
  }
  return *w;
}

fs::path bench_dir(const std::string& name) {
  const char* env = std::getenv("LMF_BENCH_STATE_DIR");
  const fs::path base = env != nullptr ? fs::path(env) : fs::temp_directory_path() / "lmf_bench_state";
  const fs::path dir = base / name;
  fs::remove_all(dir);
  return dir;
}

void sizes(benchmark::internal::Benchmark* b) {
  for (const int n : {100, 500, 1000, 2000}) b->Arg(n);
  b->Unit(benchmark::kMillisecond)->UseRealTime();
}

void BM_EncodeServerState(benchmark::State& state) {
  World& w = world(static_cast<int>(state.range(0)));
  std::size_t bytes = 0;
  for (auto _ : state) {
    const std::string p = w.payload();
    bytes = p.size();
    benchmark::DoNotOptimize(p.data());
  }
  state.counters["segments"] = w.fusion.map().counts().segments;
  state.counters["state_dim"] = static_cast<double>(w.fusion.map().state().dimension());
  state.counters["MB"] = static_cast<double>(bytes) / 1e6;
}
BENCHMARK(BM_EncodeServerState)->Apply(sizes);

void BM_WriteSnapshot(benchmark::State& state) {
  World& w = world(static_cast<int>(state.range(0)));
  const std::string payload = w.payload();
  const fs::path dir = bench_dir("write");
  lmf::server::StateStore store(lmf::server::StateStoreOptions{dir});
  const lmf::server::Recovery rec = store.recover();
  store.start(rec, 0, payload);
  std::int64_t lsn = 0;
  for (auto _ : state) {
    // One journal record per snapshot, as after a fusion (so the journal rotates).
    store.append("LMF_LOCAL_MAP", payload.data(), 16, 0);
    if (!store.write_snapshot(++lsn, payload)) state.SkipWithError("snapshot not written");
  }
  state.counters["segments"] = w.fusion.map().counts().segments;
  state.counters["MB"] = static_cast<double>(payload.size()) / 1e6;
}
BENCHMARK(BM_WriteSnapshot)->Apply(sizes);

void BM_Recover(benchmark::State& state) {
  World& w = world(static_cast<int>(state.range(0)));
  const fs::path dir = bench_dir("recover");
  {
    lmf::server::StateStore store(lmf::server::StateStoreOptions{dir});
    const lmf::server::Recovery rec = store.recover();
    store.start(rec, 0, w.payload());
  }
  int segments = 0;
  for (auto _ : state) {
    lmf::server::StateStore store(lmf::server::StateStoreOptions{dir});
    const lmf::server::Recovery rec = store.recover();
    segments = rec.state->fusion.map().counts().segments;
  }
  state.counters["segments"] = segments;
}
BENCHMARK(BM_Recover)->Apply(sizes);

void BM_JournalAppend(benchmark::State& state) {
  std::mt19937 rng(5);
  const auto msg = lmf::runtime::to_message(synthetic::serpentine_growth_snapshot(3, rng));
  const std::vector<std::uint8_t> bytes = lmf::runtime::encode_message(msg.value());
  const fs::path dir = bench_dir("journal");
  lmf::server::StateStore store(lmf::server::StateStoreOptions{dir});
  const lmf::server::Recovery rec = store.recover();
  store.start(rec, 0, world(0).payload());
  for (auto _ : state) store.append("LMF_LOCAL_MAP", bytes.data(), bytes.size(), 0);
  state.counters["bytes"] = static_cast<double>(bytes.size());
}
BENCHMARK(BM_JournalAppend)->Unit(benchmark::kMillisecond)->UseRealTime();

}  // namespace

BENCHMARK_MAIN();
