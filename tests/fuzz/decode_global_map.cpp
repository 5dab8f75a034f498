// Fuzz target: LMF_GLOBAL_MAP as lmf-monitor reads it: runtime::decode_message<global_map_t>,
// the round trip, then MonitorState, its JSON line and table.
#include <cstddef>
#include <cstdint>
#include <vector>

#include "monitor_target.hpp"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  return lmf::fuzz::fuzz_monitor_message<lmf::global_map_t>(
      data, size, [](lmf::monitor::MonitorState& state, const lmf::runtime::GlobalMapSummary& m, std::int64_t now) { state.on_global_map(m, now); });
}

std::vector<lmf::fuzz::Bytes> LmfFuzzSeeds() {
  std::vector<lmf::fuzz::Bytes> seeds;
  for (const auto& m : lmf::fuzz::corpus().global_maps) seeds.push_back(lmf::fuzz::encode(m));
  return seeds;
}
