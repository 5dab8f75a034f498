// Fuzz target: LMF_SIGHTING_ACK as lmf-player receives it:
// runtime::decode<SightingAck> and, for accepted input, the re-encode round trip.
#include <cstddef>
#include <cstdint>
#include <vector>

#include "decode_target.hpp"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  return lmf::fuzz::fuzz_decode<lmf::runtime::SightingAck>(data, size);
}

std::vector<lmf::fuzz::Bytes> LmfFuzzSeeds() {
  std::vector<lmf::fuzz::Bytes> seeds;
  for (const auto& v : lmf::fuzz::corpus().sighting_acks) seeds.push_back(lmf::fuzz::encode(lmf::runtime::to_message(v)));
  return seeds;
}
