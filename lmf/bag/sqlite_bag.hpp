// rosbag2's SQLite3 storage (bag_file.hpp dispatches here), through Debian's
// libsqlite3: the tables topics(id, name, type, serialization_format, ...) and
// messages(id, topic_id, timestamp, data). A bag is a .db3 file, or the folder
// rosbag2 writes (metadata.yaml and one or more .db3 files, read in name
// order, which is rosbag2's split order).
#pragma once

#include <vector>

#include "lmf/bag/bag_file.hpp"

namespace lmf::bag::sqlite {

// The .db3 files of a folder in name order (empty when none); a file: itself.
std::vector<std::filesystem::path> database_files(const std::filesystem::path& bag);

BagSummary summarize(const std::filesystem::path& bag);
void for_each_message(const std::filesystem::path& bag, const std::set<std::string>& topics,
                      const std::function<void(const BagMessage&)>& visit);

}  // namespace lmf::bag::sqlite
