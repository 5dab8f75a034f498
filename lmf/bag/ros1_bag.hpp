// ROS 1 bag 2.0 through Debian's librosbag-storage (bag_file.hpp dispatches here).
#pragma once

#include "lmf/bag/bag_file.hpp"

namespace lmf::bag::ros1 {

// The file must start with "#ROSBAG V2.0\n" (detect_bag_format checked it).
BagSummary summarize(const std::filesystem::path& file);
void for_each_message(const std::filesystem::path& file, const std::set<std::string>& topics,
                      const std::function<void(const BagMessage&)>& visit);

}  // namespace lmf::bag::ros1
