// Fuzz target: LMF_SIGHTING as lmf-server receives it (three 3x3 covariances):
// runtime::decode<Sighting> and, for accepted input, the re-encode round trip.
#include <cstddef>
#include <cstdint>
#include <vector>

#include "decode_target.hpp"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  return lmf::fuzz::fuzz_decode<lmf::fusion::RobotSighting>(data, size);
}

std::vector<lmf::fuzz::Bytes> LmfFuzzSeeds() {
  std::vector<lmf::fuzz::Bytes> seeds;
  for (const auto& v : lmf::fuzz::corpus().sightings) seeds.push_back(lmf::fuzz::encode(lmf::runtime::to_message(v).value()));
  for (const auto& v : lmf::fuzz::corpus().pending_sightings) seeds.push_back(lmf::fuzz::encode(lmf::runtime::to_message(v).value()));
  return seeds;
}
