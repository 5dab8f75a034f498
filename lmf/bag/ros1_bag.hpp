// ROS 1 bag 2.0 (bag_file.hpp dispatches here), read from the format's
// description (wiki.ros.org/Bags/Format/2.0): after "#ROSBAG V2.0\n", records
// of <header_len u32><header><data_len u32><data>, the header a list of
// <len u32>name=value fields. The file is walked front to back: Chunk records
// (op 0x05; "none", "bz2" or "lz4") hold Connection (0x07) and Message Data
// (0x02) records; the index records at the end are not needed, so a bag whose
// recorder was killed before writing them is read up to where it ends, and
// that is reported. Messages come out in log-time order (chunks may be out of
// order). librosbag-storage is used to write bags (ros1_bag_writer.hpp), not
// to read them: it crashes on damaged files.
#pragma once

#include "lmf/bag/bag_file.hpp"

namespace lmf::bag::ros1 {

BagSummary summarize(const std::filesystem::path& file);
void for_each_message(const std::filesystem::path& file, const std::set<std::string>& topics,
                      const std::function<void(const BagMessage&)>& visit);

}  // namespace lmf::bag::ros1
