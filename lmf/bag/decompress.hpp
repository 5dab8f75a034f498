// The chunk codecs of ROS bags, through Debian's libraries: "bz2" (libbz2;
// ROS 1), "lz4" (liblz4, LZ4 frames; ROS 1 and MCAP), "zstd" (libzstd; MCAP).
// A chunk states its uncompressed size; nothing is allocated beyond what the
// codec can expand the chunk to (lz4 blocks at most ~255-fold; bz2 and zstd
// bounded at 1000-fold, or for zstd the size its frame states), so a damaged
// size field cannot ask for gigabytes.
//
// Pure, thread-safe.
#pragma once

#include <cstdint>
#include <span>
#include <stdexcept>
#include <string>
#include <vector>

namespace lmf::bag {

// Throws std::runtime_error saying what was wrong (unknown codec, a size the
// chunk cannot hold, the codec's own error, a result of another size).
std::vector<std::uint8_t> decompress(const std::string& codec, std::span<const std::uint8_t> compressed,
                                     std::uint64_t uncompressed_size);

}  // namespace lmf::bag
