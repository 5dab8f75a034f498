// Fuzz target: ROS 1 bags (through librosbag-storage, lmf/bag/ros1_bag.hpp)
// on whole files, from bags lmf-convert's writer makes (bag_file_target.hpp).
#include "bag_file_target.hpp"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  lmf::fuzz::fuzz_bag_file(data, size, ".bag");
  return 0;
}

std::vector<lmf::fuzz::Bytes> LmfFuzzSeeds() {
  return lmf::fuzz::bag_fuzz_seeds(lmf::bag::BagFormat::ros1, {"none", "lz4"}, ".bag");
}
