// Fuzz target: LMF_LOCAL_MAP as lmf-server receives it (the largest message: segments, a packed
// covariance of up to 1027 x 1027 and the scan poses):
// runtime::decode<LocalMapSnapshot> and, for accepted input, the re-encode round trip.
#include <cstddef>
#include <cstdint>
#include <vector>

#include "decode_target.hpp"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  return lmf::fuzz::fuzz_decode<lmf::LocalMapSnapshot>(data, size);
}

std::vector<lmf::fuzz::Bytes> LmfFuzzSeeds() {
  std::vector<lmf::fuzz::Bytes> seeds;
  for (const auto& v : lmf::fuzz::corpus().local_maps) seeds.push_back(lmf::fuzz::encode(lmf::runtime::to_message(v).value()));
  for (const auto& v : lmf::fuzz::corpus().pending_maps) seeds.push_back(lmf::fuzz::encode(lmf::runtime::to_message(v).value()));
  return seeds;
}
