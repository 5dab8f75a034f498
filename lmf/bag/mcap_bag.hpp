// ROS 2 MCAP files (bag_file.hpp dispatches here), read from the MCAP format
// specification (mcap.dev/spec), version 0: the leading magic, then records of
// <opcode u8><length u64><content> (little-endian; strings u32-length-prefixed).
// The data section is walked front to back: Schema (0x03), Channel (0x04) and
// Message (0x05) records, in Chunks (0x06, uncompressed, "zstd" or "lz4"
// frames, through Debian's libzstd and liblz4, checked against their CRC-32
// when it is set) or outside them, until Data End (0x0F) or the Footer (0x02);
// the summary section is not needed. A file that ends inside a record (a
// recorder killed) is read up to it and the cut reported. Messages come out in
// log-time order (chunks may overlap in time).
#pragma once

#include "lmf/bag/bag_file.hpp"

namespace lmf::bag::mcap {

BagSummary summarize(const std::filesystem::path& file);
void for_each_message(const std::filesystem::path& file, const std::set<std::string>& topics,
                      const std::function<void(const BagMessage&)>& visit);

}  // namespace lmf::bag::mcap
