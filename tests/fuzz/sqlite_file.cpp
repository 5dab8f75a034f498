// Fuzz target: rosbag2's SQLite3 storage (lmf/bag/sqlite_bag.hpp) on whole
// .db3 files, from a small rosbag2-shaped database made here (the topics and
// messages tables, CDR LaserScan and Odometry). SQLite checks its own file
// format; what is fuzzed is lmf's reading of what it returns (unknown topic
// ids, NULL or short blobs, odd types).
#include <sqlite3.h>

#include "bag_file_target.hpp"
#include "lmf/bag/wire_encoder.hpp"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  lmf::fuzz::fuzz_bag_file(data, size, ".db3");
  return 0;
}

std::vector<lmf::fuzz::Bytes> LmfFuzzSeeds() {
  using lmf::bag::MessageEncoding;
  const std::filesystem::path file = lmf::fuzz::bag_fuzz_file(".db3");
  std::filesystem::remove(file);
  sqlite3* db = nullptr;
  sqlite3_open(file.c_str(), &db);
  sqlite3_exec(db,
               "CREATE TABLE topics(id INTEGER PRIMARY KEY, name TEXT NOT NULL, type TEXT NOT NULL, "
               "serialization_format TEXT NOT NULL, offered_qos_profiles TEXT NOT NULL);"
               "CREATE TABLE messages(id INTEGER PRIMARY KEY, topic_id INTEGER NOT NULL, timestamp INTEGER NOT NULL, "
               "data BLOB NOT NULL);"
               "INSERT INTO topics VALUES(1, '/scan', 'sensor_msgs/msg/LaserScan', 'cdr', '');"
               "INSERT INTO topics VALUES(2, '/odom', 'nav_msgs/msg/Odometry', 'cdr', '');",
               nullptr, nullptr, nullptr);
  sqlite3_stmt* insert = nullptr;
  sqlite3_prepare_v2(db, "INSERT INTO messages(topic_id, timestamp, data) VALUES(?, ?, ?)", -1, &insert, nullptr);
  for (int k = 0; k < 3; ++k) {
    const std::int64_t t = 1'000'000'000LL + 100'000'000LL * k;
    lmf::bag::RosOdometry odometry;
    odometry.header = {t, "odom"};
    odometry.child_frame_id = "base_link";
    odometry.pose.translation = {0.1 * k, 0.0, 0.0};
    lmf::bag::RosLaserScan scan;
    scan.header = {t, "base_link"};
    scan.angle_min = -1.5f;
    scan.angle_max = 1.5f;
    scan.angle_increment = 0.5f;
    scan.range_max = 30.0f;
    scan.ranges = {1.0f, 2.0f, 3.0f, 4.0f, 5.0f, 6.0f, 7.0f};
    const std::pair<int, std::vector<std::uint8_t>> rows[] = {
        {2, lmf::bag::encode_odometry(odometry, MessageEncoding::cdr)},
        {1, lmf::bag::encode_laser_scan(scan, MessageEncoding::cdr)}};
    for (const auto& [topic, bytes] : rows) {
      sqlite3_bind_int(insert, 1, topic);
      sqlite3_bind_int64(insert, 2, t);
      sqlite3_bind_blob(insert, 3, bytes.data(), static_cast<int>(bytes.size()), SQLITE_TRANSIENT);
      sqlite3_step(insert);
      sqlite3_reset(insert);
    }
  }
  sqlite3_finalize(insert);
  sqlite3_close(db);
  std::ifstream in(file, std::ios::binary);
  return {lmf::fuzz::Bytes(std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>())};
}
