#include "lmf/bag/sqlite_bag.hpp"

#include <algorithm>
#include <map>
#include <memory>

#include <sqlite3.h>

#include "lmf/bag/container_support.hpp"

namespace lmf::bag::sqlite {
namespace {

struct CloseDatabase {
  void operator()(sqlite3* db) const { sqlite3_close(db); }
};
struct FinalizeStatement {
  void operator()(sqlite3_stmt* s) const { sqlite3_finalize(s); }
};
using Database = std::unique_ptr<sqlite3, CloseDatabase>;
using Statement = std::unique_ptr<sqlite3_stmt, FinalizeStatement>;

Database open(const std::filesystem::path& file) {
  sqlite3* db = nullptr;
  const int rc = sqlite3_open_v2(file.c_str(), &db, SQLITE_OPEN_READONLY, nullptr);
  Database owned(db);
  if (rc != SQLITE_OK) {
    throw BagFormatError(file, std::string("SQLite3: ") + (db != nullptr ? sqlite3_errmsg(db) : sqlite3_errstr(rc)));
  }
  return owned;
}

Statement prepare(sqlite3* db, const std::filesystem::path& file, const char* sql) {
  sqlite3_stmt* statement = nullptr;
  if (sqlite3_prepare_v2(db, sql, -1, &statement, nullptr) != SQLITE_OK) {
    throw BagFormatError(file, std::string("SQLite3 (not a rosbag2 database?): ") + sqlite3_errmsg(db));
  }
  return Statement(statement);
}

std::string text(sqlite3_stmt* s, int column) {
  const unsigned char* t = sqlite3_column_text(s, column);
  return t == nullptr ? "" : reinterpret_cast<const char*>(t);
}

struct Topic {
  std::string name;
  std::string type;
  std::string format;
};

std::map<std::int64_t, Topic> read_topics(sqlite3* db, const std::filesystem::path& file) {
  std::map<std::int64_t, Topic> topics;
  const Statement s = prepare(db, file, "SELECT id, name, type, serialization_format FROM topics");
  int rc = 0;
  while ((rc = sqlite3_step(s.get())) == SQLITE_ROW) {
    topics[sqlite3_column_int64(s.get(), 0)] = {text(s.get(), 1), text(s.get(), 2), text(s.get(), 3)};
  }
  if (rc != SQLITE_DONE) throw BagFormatError(file, std::string("SQLite3, table topics: ") + sqlite3_errmsg(db));
  return topics;
}

// Calls visit(topic, timestamp, blob) for every message of the bag's files, by file then time.
template <typename Visit>
void walk(const std::filesystem::path& bag, const char* sql, Visit&& visit) {
  const auto files = database_files(bag);
  if (files.empty()) throw BagFormatError(bag, "no .db3 file");
  for (const auto& file : files) {
    const Database db = open(file);
    const auto topics = read_topics(db.get(), file);
    const Statement s = prepare(db.get(), file, sql);
    int rc = 0;
    std::int64_t row = 0;
    while ((rc = sqlite3_step(s.get())) == SQLITE_ROW) {
      const auto topic = topics.find(sqlite3_column_int64(s.get(), 0));
      if (topic == topics.end()) {
        throw BagFormatError(file, "SQLite3, messages row " + std::to_string(row) + ": topic_id " +
                                       std::to_string(sqlite3_column_int64(s.get(), 0)) + " is not in topics");
      }
      visit(file, topic->second, sqlite3_column_int64(s.get(), 1), s.get(), row++);
    }
    if (rc != SQLITE_DONE) throw BagFormatError(file, std::string("SQLite3, table messages: ") + sqlite3_errmsg(db.get()));
  }
}

}  // namespace

std::vector<std::filesystem::path> database_files(const std::filesystem::path& bag) {
  if (!std::filesystem::is_directory(bag)) return {bag};
  std::vector<std::filesystem::path> files;
  for (const auto& entry : std::filesystem::directory_iterator(bag)) {
    if (entry.path().extension() == ".db3") files.push_back(entry.path());
  }
  std::sort(files.begin(), files.end());
  return files;
}

BagSummary summarize(const std::filesystem::path& bag) {
  SummaryCounter counter(BagFormat::sqlite3);
  walk(bag, "SELECT topic_id, timestamp FROM messages ORDER BY timestamp, id",
       [&](const std::filesystem::path&, const Topic& topic, std::int64_t t, sqlite3_stmt*, std::int64_t) {
         counter.count(topic.name, topic.type, t);
       });
  return counter.finish({});
}

void for_each_message(const std::filesystem::path& bag, const std::set<std::string>& topics,
                      const std::function<void(const BagMessage&)>& visit) {
  walk(bag, "SELECT topic_id, timestamp, data FROM messages ORDER BY timestamp, id",
       [&](const std::filesystem::path& file, const Topic& topic, std::int64_t t, sqlite3_stmt* s, std::int64_t row) {
         if (!topics.empty() && !topics.contains(topic.name)) return;
         if (topic.format != "cdr") {
           throw BagFormatError(file, "SQLite3, messages row " + std::to_string(row) + " on " + topic.name +
                                          ": serialization format \"" + topic.format + "\" is not read (cdr is)");
         }
         const auto* data = static_cast<const std::uint8_t*>(sqlite3_column_blob(s, 2));
         const auto size = static_cast<std::size_t>(sqlite3_column_bytes(s, 2));
         visit(BagMessage{topic.name, topic.type, t, MessageEncoding::cdr, {data, size}});
       });
}

}  // namespace lmf::bag::sqlite
