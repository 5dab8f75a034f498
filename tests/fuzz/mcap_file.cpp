// Fuzz target: the MCAP container reader (lmf/bag/mcap_bag.hpp) on whole
// files, from MCAP files lmf-convert's writer makes (bag_file_target.hpp).
#include "bag_file_target.hpp"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  lmf::fuzz::fuzz_bag_file(data, size, ".mcap");
  return 0;
}

std::vector<lmf::fuzz::Bytes> LmfFuzzSeeds() {
  return lmf::fuzz::bag_fuzz_seeds(lmf::bag::BagFormat::mcap, {"none", "zstd"}, ".mcap");
}
