// Fuzz target: LMF_AGENT_STATUS as lmf-monitor reads it: runtime::decode_message<agent_status_t>,
// the round trip, then MonitorState, its JSON line and table.
#include <cstddef>
#include <cstdint>
#include <vector>

#include "monitor_target.hpp"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  return lmf::fuzz::fuzz_monitor_message<lmf::agent_status_t>(
      data, size, [](lmf::monitor::MonitorState& state, const lmf::runtime::AgentStatus& m, std::int64_t now) { state.on_agent_status(m, now); });
}

std::vector<lmf::fuzz::Bytes> LmfFuzzSeeds() {
  std::vector<lmf::fuzz::Bytes> seeds;
  for (const auto& m : lmf::fuzz::corpus().agent_statuses) seeds.push_back(lmf::fuzz::encode(m));
  return seeds;
}
