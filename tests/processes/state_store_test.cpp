// The fusion server's durable state (fusion_server/state_store.hpp): round
// trip, torn journal tails (good prefix used), corrupt records and snapshots
// (fallback to snapshot.prev, damaged files set aside, loud error when nothing
// is valid), the directory lock, LCM-log compatibility of the journal; and a
// ServerNode restarted on a copy of a running server's state directory (what
// kill -9 leaves) continues bit-identically and acks resends DUPLICATE.
#include <chrono>
#include <cmath>
#include <cstdint>
#include <filesystem>
#include <fstream>
#include <functional>
#include <memory>
#include <sstream>
#include <string>
#include <tuple>
#include <vector>

#include <gtest/gtest.h>
#include <lcm/lcm-cpp.hpp>

#include "fusion_server/server_node.hpp"
#include "fusion_server/state_store.hpp"
#include "lmf/fusion/global_map_archive.hpp"
#include "runtime/auth.hpp"
#include "runtime/bus.hpp"
#include "runtime/channels.hpp"
#include "runtime/convert.hpp"
#include "runtime/event_loop.hpp"
#include "server_test_support.hpp"

namespace {

namespace fs = std::filesystem;
namespace rt = lmf::runtime;
using namespace std::chrono_literals;
using lmf::LocalMapSnapshot;
using lmf::Pose2;
using lmf::server::JournalRecord;
using lmf::server::Recovery;
using lmf::server::StateError;
using lmf::server::StateStore;
using lmf::server::StateStoreOptions;
using lmf::testing::make_sighting;
using lmf::testing::to_msg;
using Status = rt::LocalMapAck::Status;

fs::path fresh_dir(const std::string& name) {
  const fs::path dir = fs::path(::testing::TempDir()) / ("lmf_state_" + name);
  fs::remove_all(dir);
  return dir;
}

// Local map `seq` of a robot moving about 1 m along x per map in the room's
// first five walls, with slightly wrong estimates (so updates really move the map).
LocalMapSnapshot make_map(int robot_id, std::int64_t seq, const Pose2& x_WL0 = Pose2()) {
  const Pose2 step(1.0, 0.02 * static_cast<double>(seq % 3), 0.01);
  LocalMapSnapshot s = lmf::testing::room_local_map(robot_id, seq, 5, x_WL0, step);
  for (std::size_t i = 0; i < s.segments.size(); ++i) {
    const double e = 0.01 * std::sin(static_cast<double>(seq * 7 + static_cast<std::int64_t>(i)));
    s.segments[i].location = lmf::compose(s.segments[i].location, Pose2(0.0, e, 0.5 * e));
  }
  return s;
}

std::vector<std::uint8_t> map_bytes(const LocalMapSnapshot& s) { return rt::encode_message(to_msg(s)); }

// A server-state payload whose map has `fused` local maps of robot 0.
std::string payload_with(int fused) {
  lmf::server::FusionContext fusion{lmf::fusion::GlobalMap()};
  fusion.join_first_robot(0);
  for (int seq = 0; seq < fused; ++seq) fusion.fuse(make_map(0, seq), 0.0);
  return lmf::server::encode_server_state(fusion, {});
}

int fused_in(const Recovery& r) {
  const auto& shipped = r.state->fusion.book().shipped();
  const auto robot = shipped.find(0);
  return robot == shipped.end() ? 0 : static_cast<int>(robot->second.size());
}

void append_maps(StateStore& store, std::int64_t from_seq, int count) {
  for (int i = 0; i < count; ++i) {
    const auto bytes = map_bytes(make_map(0, from_seq + i));
    store.append("LMF_LOCAL_MAP", bytes.data(), bytes.size(), 42);
  }
}

std::vector<std::int64_t> lsns(const Recovery& r) {
  std::vector<std::int64_t> out;
  for (const JournalRecord& j : r.records) out.push_back(j.lsn);
  return out;
}

std::vector<fs::path> journals(const fs::path& dir) {
  std::vector<fs::path> out;
  for (const auto& e : fs::directory_iterator(dir)) {
    if (e.path().extension() == ".lcmlog") out.push_back(e.path());
  }
  std::sort(out.begin(), out.end());
  return out;
}

std::string read_all(const fs::path& p) {
  std::ifstream in(p, std::ios::binary);
  std::ostringstream s;
  s << in.rdbuf();
  return s.str();
}

void write_all(const fs::path& p, const std::string& bytes) {
  std::ofstream out(p, std::ios::binary | std::ios::trunc);
  out << bytes;
}

bool mentions(const std::vector<std::string>& problems, const std::string& what) {
  for (const std::string& p : problems) {
    if (p.find(what) != std::string::npos) return true;
  }
  return false;
}

// A state directory with snapshot (lsn 2: maps 0, 1), snapshot.prev (lsn 0)
// and journal records 1..5 (maps 0..4): records 3..5 are after the snapshot.
fs::path standard_dir(const std::string& name) {
  const fs::path dir = fresh_dir(name);
  StateStore store(StateStoreOptions{dir});
  const Recovery rec = store.recover();
  EXPECT_TRUE(rec.fresh);
  store.start(rec, 0, payload_with(0));
  append_maps(store, 0, 2);
  EXPECT_TRUE(store.write_snapshot(2, payload_with(2)));
  append_maps(store, 2, 3);
  EXPECT_EQ(store.last_appended_lsn(), 5);
  return dir;
}

TEST(StateStoreTest, RoundTripSnapshotPlusJournal) {
  const fs::path dir = standard_dir("round_trip");
  EXPECT_TRUE(fs::exists(dir / "snapshot"));
  EXPECT_TRUE(fs::exists(dir / "snapshot.prev"));
  StateStore store(StateStoreOptions{dir});
  Recovery rec = store.recover();
  EXPECT_FALSE(rec.fresh);
  ASSERT_TRUE(rec.state.has_value());
  EXPECT_EQ(rec.snapshot_file, "snapshot");
  EXPECT_EQ(rec.snapshot_lsn, 2);
  EXPECT_EQ(fused_in(rec), 2);
  EXPECT_EQ(lsns(rec), (std::vector<std::int64_t>{3, 4, 5}));
  EXPECT_TRUE(rec.problems.empty());
  // The records are the messages as given, on their channel.
  const auto expected = map_bytes(make_map(0, 2));
  EXPECT_EQ(rec.records[0].channel, "LMF_LOCAL_MAP");
  EXPECT_EQ(rec.records[0].utime, 42);
  EXPECT_EQ(rec.records[0].data, std::string(expected.begin(), expected.end()));
  // Carry on: the journal continues at lsn 6 and old files are pruned.
  store.start(rec, 5, payload_with(5));
  append_maps(store, 5, 1);
  EXPECT_EQ(store.last_appended_lsn(), 6);
  EXPECT_LE(journals(dir).size(), 3u);
}

TEST(StateStoreTest, TheJournalIsAnLcmEventLog) {
  const fs::path dir = standard_dir("lcm_log");
  const std::vector<fs::path> files = journals(dir);
  ASSERT_FALSE(files.empty());
  std::int64_t events = 0;
  for (const fs::path& f : files) {
    lcm::LogFile log(f.string(), "r");
    ASSERT_TRUE(log.good());
    while (const lcm::LogEvent* e = log.readNextEvent()) {
      EXPECT_EQ(e->channel, "LMF_LOCAL_MAP");
      EXPECT_GT(e->eventnum, 0);
      lmf::local_map_t msg;
      EXPECT_GT(msg.decode(e->data, 0, e->datalen), 0);  // the message, then the 4-byte CRC
      ++events;
    }
  }
  EXPECT_GE(events, 3);
}

TEST(StateStoreTest, TornJournalTailIsCutAndTheGoodPrefixUsed) {
  const fs::path dir = standard_dir("torn");
  const fs::path last = journals(dir).back();
  const std::string bytes = read_all(last);
  write_all(last, bytes.substr(0, bytes.size() - 10));  // the last record (lsn 5) cut by a crash
  {
    StateStore store(StateStoreOptions{dir});
    Recovery rec = store.recover();
    EXPECT_EQ(rec.snapshot_lsn, 2);
    EXPECT_EQ(lsns(rec), (std::vector<std::int64_t>{3, 4}));
    ASSERT_EQ(rec.problems.size(), 1u);
    EXPECT_TRUE(mentions(rec.problems, "torn tail")) << rec.problems[0];
    store.start(rec, 4, payload_with(4));
    EXPECT_TRUE(fs::exists(dir / "damaged"));
    append_maps(store, 4, 1);  // the agent resends map 4 (never acked): lsn 5 again
    EXPECT_EQ(store.last_appended_lsn(), 5);
  }
  StateStore store(StateStoreOptions{dir});
  Recovery rec = store.recover();
  EXPECT_TRUE(rec.problems.empty()) << rec.problems.front();
  EXPECT_EQ(rec.snapshot_lsn, 4);
  EXPECT_EQ(lsns(rec), (std::vector<std::int64_t>{5}));
}

TEST(StateStoreTest, CorruptRecordStopsTheReplayAndIsSetAside) {
  const fs::path dir = standard_dir("corrupt_record");
  const fs::path last = journals(dir).back();
  std::string bytes = read_all(last);
  // Three records of equal size (maps 2, 3, 4): damage the middle one's data.
  const std::size_t record = bytes.size() / 3;
  bytes[record + record / 2] = static_cast<char>(bytes[record + record / 2] ^ 0x40);
  write_all(last, bytes);
  StateStore store(StateStoreOptions{dir});
  Recovery rec = store.recover();
  EXPECT_EQ(lsns(rec), (std::vector<std::int64_t>{3}));
  EXPECT_TRUE(mentions(rec.problems, "DAMAGED")) << (rec.problems.empty() ? "" : rec.problems[0]);
  EXPECT_TRUE(mentions(rec.problems, "checksum mismatch"));
  store.start(rec, 3, payload_with(3));
  EXPECT_EQ(fs::file_size(last), record);  // the good prefix stays
  bool tail_kept = false;
  for (const auto& e : fs::directory_iterator(dir / "damaged")) {
    tail_kept = tail_kept || fs::file_size(e.path()) == 2 * record;
  }
  EXPECT_TRUE(tail_kept);
  append_maps(store, 3, 1);
  EXPECT_EQ(store.last_appended_lsn(), 4);
}

TEST(StateStoreTest, CorruptSnapshotFallsBackToThePreviousOne) {
  const fs::path dir = standard_dir("corrupt_snapshot");
  std::string bytes = read_all(dir / "snapshot");
  bytes[bytes.size() / 2] = static_cast<char>(bytes[bytes.size() / 2] ^ 1);
  write_all(dir / "snapshot", bytes);
  {
    StateStore store(StateStoreOptions{dir});
    Recovery rec = store.recover();
    ASSERT_TRUE(rec.state.has_value());
    EXPECT_EQ(rec.snapshot_file, "snapshot.prev");
    EXPECT_EQ(rec.snapshot_lsn, 0);
    EXPECT_EQ(fused_in(rec), 0);
    EXPECT_EQ(lsns(rec), (std::vector<std::int64_t>{1, 2, 3, 4, 5}));  // its journal was kept
    EXPECT_TRUE(mentions(rec.problems, "snapshot is unusable"));
    EXPECT_TRUE(mentions(rec.problems, "checksum mismatch"));
    store.start(rec, 5, payload_with(5));
  }
  // The corrupt file went to damaged/, not to snapshot.prev.
  bool kept = false;
  for (const auto& e : fs::directory_iterator(dir / "damaged")) {
    kept = kept || e.path().filename().string().rfind("snapshot.", 0) == 0;
  }
  EXPECT_TRUE(kept);
  StateStore store(StateStoreOptions{dir});
  Recovery rec = store.recover();
  EXPECT_TRUE(rec.problems.empty());
  EXPECT_EQ(rec.snapshot_file, "snapshot");
  EXPECT_EQ(rec.snapshot_lsn, 5);
  EXPECT_EQ(fused_in(rec), 5);
}

TEST(StateStoreTest, NoValidSnapshotIsALoudErrorNotAnEmptyMap) {
  const fs::path dir = standard_dir("all_corrupt");
  for (const char* name : {"snapshot", "snapshot.prev"}) {
    const std::string bytes = read_all(dir / name);
    write_all(dir / name, bytes.substr(0, bytes.size() - 1));
  }
  StateStore store(StateStoreOptions{dir});
  try {
    store.recover();
    FAIL() << "recovered from corrupt snapshots";
  } catch (const StateError& e) {
    EXPECT_NE(std::string(e.what()).find("no valid snapshot"), std::string::npos) << e.what();
  }
}

TEST(StateStoreTest, ADirectoryIsUsedByOneServerAtATime) {
  const fs::path dir = fresh_dir("lock");
  StateStore first(StateStoreOptions{dir});
  EXPECT_THROW(StateStore second(StateStoreOptions{dir}), StateError);
}

TEST(StateStoreTest, ServerStatePayloadRoundTrips) {
  lmf::fusion::GlobalMap map;
  lmf::mission::TrajectoryBook book;
  map.join_robot(0, Pose2());
  std::vector<lmf::server::FusionRecord> fusions;
  for (int seq = 0; seq < 3; ++seq) {
    for (const auto& r : map.fuse(make_map(0, seq))) fusions.push_back({r, 1.5 * seq});
    book.add(make_map(0, seq));
  }
  std::vector<lmf::server::SightingRecord> sightings = {{make_sighting(0, 1, 7), "pending"}};
  const lmf::runtime::auth::HighWater high_water = {{"player", 1'700'000'000'000'123}, {"robot1", 42}};
  lmf::server::FusionRecords records;
  records.fusions = fusions;
  records.sightings = sightings;
  records.fusion_ms_sum = 12.5;
  records.last_covariance_ok = false;
  records.last_min_pivot = 0.25;
  records.latest_utime = 99;
  const lmf::server::FusionContext fusion(std::move(map), std::move(book), records);
  const std::string bytes = lmf::server::encode_server_state(fusion, high_water);
  lmf::server::ServerState s = lmf::server::decode_server_state(bytes);
  EXPECT_EQ(lmf::server::encode_server_state(s.fusion, s.taken_high_water), bytes);
  EXPECT_EQ(s.taken_high_water, high_water);
  EXPECT_EQ(s.fusion.records().fusions.size(), 3u);
  EXPECT_EQ(s.fusion.records().sightings[0].status, "pending");
  EXPECT_EQ(s.fusion.records().latest_utime, 99);
  EXPECT_DOUBLE_EQ(s.fusion.records().fusion_ms_sum, 12.5);
  EXPECT_FALSE(s.fusion.records().last_covariance_ok);
  EXPECT_EQ(s.fusion.records().last_min_pivot, 0.25);
  EXPECT_THROW(lmf::server::decode_server_state(bytes.substr(0, bytes.size() - 3)), lmf::fusion::ArchiveError);
}

// ---- the server node on a state directory ------------------------------------

class ServerStateTest : public lmf::testing::ServerNodeFixture {
 protected:
  ServerStateTest() {
    bus_.subscribe_message<lmf::sighting_ack_t>(
        channels_.sighting_ack(),
        [this](const std::string&, const lmf::sighting_ack_t& ack) {
          if (ack.status != lmf::sighting_ack_t::RECEIVED) sighting_acks_.push_back(ack.status);
        });
  }
  lmf::server::ServerOptions options(const fs::path& state, const std::string& name) const {
    lmf::server::ServerOptions o;
    o.out_dir = fresh_dir(name + "_out");
    o.max_robots = 4;
    o.state_dir = state;
    o.snapshot_interval = 3600s;  // only at start and stop: everything else stays in the journal
    return o;
  }
  void publish_map(int robot, std::int64_t seq, const Pose2& x_WL0 = Pose2()) {
    bus_.publish(channels_.local_map(), to_msg(make_map(robot, seq, x_WL0)));
  }
  void publish_sighting(const lmf::fusion::RobotSighting& s) { bus_.publish(channels_.sighting(), to_msg(s)); }

  static std::string archive(const lmf::fusion::GlobalMap& map) {
    std::ostringstream out;
    lmf::fusion::write_archive(map, out);
    return out.str();
  }

  std::vector<std::int8_t> sighting_acks_;  // final statuses (not RECEIVED), in arrival order
};

TEST_F(ServerStateTest, ARestartedServerContinuesBitIdentically) {
  const fs::path state = fresh_dir("server_live");
  const fs::path crashed = fresh_dir("server_crashed");
  const Pose2 x_WL1(2.0, 0.5, 0.1);
  std::string final_live;
  {
    lmf::server::ServerNode live(bus_, loop_, channels_, options(state, "live"));
    EXPECT_EQ(live.recovery().from, "new");
    for (int seq = 0; seq < 3; ++seq) publish_map(0, seq);
    publish_map(1, 0, x_WL1);  // queued: robot 1 has not joined
    ASSERT_TRUE(run_until([&] { return live.stats().acks_fused == 3 && live.stats().acks_queued == 1; }));
    settle(live);
    // What kill -9 leaves now: the start snapshot and a journal of 4 records.
    fs::copy(state, crashed, fs::copy_options::recursive);
    fs::remove(crashed / "lock");
    publish_sighting(make_sighting(0, 1, 2'500'000));
    for (int seq = 3; seq < 5; ++seq) publish_map(0, seq);
    publish_map(1, 1, x_WL1);
    ASSERT_TRUE(run_until([&] { return live.stats().acks_fused == 7; }));
    settle(live);
    live.shutdown(false);
    final_live = archive(*live.map_after_shutdown());
  }
  acks_.clear();
  lmf::server::ServerNode restarted(bus_, loop_, channels_, options(crashed, "restarted"));
  EXPECT_EQ(restarted.recovery().from, "snapshot");
  EXPECT_EQ(restarted.recovery().replayed_local_maps, 4);
  EXPECT_TRUE(restarted.recovery().problems.empty());
  // The agents resend what they had not seen acked; what the journal held is a duplicate.
  publish_map(0, 2);
  ASSERT_TRUE(run_until([&] { return count_acks(0, 2, Status::kDuplicate) == 1; }));
  publish_map(1, 0, x_WL1);
  ASSERT_TRUE(run_until([&] { return count_acks(1, 0, Status::kDuplicate) == 1; }));
  publish_sighting(make_sighting(0, 1, 2'500'000));
  for (int seq = 3; seq < 5; ++seq) publish_map(0, seq);
  publish_map(1, 1, x_WL1);
  ASSERT_TRUE(run_until([&] { return count_acks(0, 4, Status::kFused) == 1 && count_acks(1, 1, Status::kFused) == 1; }));
  settle(restarted);
  EXPECT_EQ(sighting_acks_, (std::vector<std::int8_t>{lmf::sighting_ack_t::APPLIED, lmf::sighting_ack_t::APPLIED}))
      << "the live server's answer, then the restarted one's (the sighting came after the crash copy)";
  restarted.shutdown(false);
  EXPECT_EQ(restarted.map_after_shutdown()->counts().robots_joined, 2);
  EXPECT_EQ(archive(*restarted.map_after_shutdown()), final_live);

  // A third life on the same state: the sighting's resend (its ack lost) is
  // answered DUPLICATE from the recovered records, never applied twice.
  sighting_acks_.clear();
  const fs::path copy = fresh_dir("server_third");  // `restarted` still holds the lock of `crashed`
  fs::copy(crashed, copy, fs::copy_options::recursive);
  fs::remove(copy / "lock");
  lmf::server::ServerNode third(bus_, loop_, channels_, options(copy, "third"));
  publish_sighting(make_sighting(0, 1, 2'500'000));
  ASSERT_TRUE(run_until([&] { return !sighting_acks_.empty(); }));
  settle(third);
  EXPECT_EQ(sighting_acks_, std::vector<std::int8_t>{lmf::sighting_ack_t::DUPLICATE});
  EXPECT_EQ(third.stats().sightings_applied, 0);
  third.shutdown(false);
  EXPECT_EQ(archive(*third.map_after_shutdown()), final_live);
}

// An authenticated server persists, per signer, the highest sequence number
// of what it took (snapshot) and re-reads the signers of the journal: after a
// restart, a capture of any earlier message is refused by the replay window
// (auth_replayed) before the node sees it, while the senders' new messages,
// signed with fresh numbers, are taken as before.
TEST_F(ServerStateTest, ACaptureReplayedAfterARestartIsRefusedByTheReplayWindow) {
  namespace auth = rt::auth;
  const auto keys = auth::make_system_keys({0, 1});
  const auto config_of = [&](const std::string& principal) {
    return auth::Config{principal, std::make_shared<const auth::KeyRing>(keys.at(principal))};
  };
  rt::Bus robot(bus_, config_of(auth::robot_principal(0)));
  rt::Bus player(bus_, config_of("player"));

  // The wire, as an eavesdropper (or lcm-logger) sees it.
  struct Wire {
    std::string channel;
    std::vector<std::uint8_t> bytes;
  };
  std::vector<Wire> captured;
  for (const std::string& channel : {channels_.local_map(), channels_.sighting()}) {
    bus_.subscribe(channel, [&](const std::string& on, const void*, std::size_t) {
      const auto heard = bus_.message_as_received();
      captured.push_back({on, {heard.begin(), heard.end()}});
    });
  }
  std::vector<Wire> before_restart;
  const auto replay_capture = [&] {
    for (const Wire& w : before_restart) {
      ASSERT_EQ(bus_.lcm().publish(w.channel, w.bytes.data(), static_cast<unsigned>(w.bytes.size())), 0);
    }
  };

  const fs::path state = fresh_dir("server_auth_live");
  const fs::path crashed = fresh_dir("server_auth_crashed");
  {
    rt::Bus server_bus(bus_, config_of("server"));
    lmf::server::ServerNode live(server_bus, loop_, channels_, options(state, "auth_live"));
    for (int seq = 0; seq < 2; ++seq) robot.publish(channels_.local_map(), to_msg(make_map(0, seq)));
    player.publish(channels_.sighting(), to_msg(make_sighting(0, 1, 2'500'000)));
    ASSERT_TRUE(run_until([&] { return live.stats().acks_fused == 2 && sighting_acks_.size() == 1; }));
    settle(live);
    ASSERT_EQ(captured.size(), 3u);
    ASSERT_EQ(server_bus.messages_verified(), 3);
    // What kill -9 leaves now: the start snapshot, everything since in the journal.
    fs::copy(state, crashed, fs::copy_options::recursive);
    fs::remove(crashed / "lock");
    live.shutdown(false);  // a final snapshot: the marks are in it
  }
  before_restart = captured;

  for (const fs::path& dir : {crashed, state}) {
    SCOPED_TRACE("restarted on " + dir.filename().string());
    const fs::path copy = fresh_dir(dir.filename().string() + "_restart");
    fs::copy(dir, copy, fs::copy_options::recursive);
    rt::Bus server_bus(bus_, config_of("server"));  // a new process: its windows start empty
    lmf::server::ServerNode restarted(server_bus, loop_, channels_, options(copy, copy.filename().string()));
    if (dir == crashed) {
      EXPECT_EQ(restarted.recovery().replayed_local_maps, 2);
    }
    replay_capture();
    ASSERT_TRUE(run_until([&] { return server_bus.rejects().count(rt::RejectReason::kAuthReplayed) == 3; }));
    settle(restarted);
    EXPECT_EQ(lmf::testing::reject_total(restarted), 3) << "refused by the windows, never seen by the node";
    EXPECT_EQ(restarted.stats().local_maps_received, 0);
    EXPECT_EQ(restarted.stats().sightings_received, 0);
    // The robot goes on, its messages signed with new numbers.
    acks_.clear();
    robot.publish(channels_.local_map(), to_msg(make_map(0, 2)));
    ASSERT_TRUE(run_until([&] { return count_acks(0, 2, Status::kFused) == 1; }));
    restarted.shutdown(false);
  }
}

TEST_F(ServerStateTest, AStateMadeWithAnotherConfigIsRefused) {
  const fs::path state = fresh_dir("server_config");
  {
    lmf::server::ServerNode node(bus_, loop_, channels_, options(state, "config_a"));
    publish_map(0, 0);
    ASSERT_TRUE(run_until([&] { return node.stats().acks_fused == 1; }));
    settle(node);
  }
  lmf::server::ServerOptions other = options(state, "config_b");
  other.global_map.gate_sigmas = 3.0;
  EXPECT_THROW({ lmf::server::ServerNode refused(bus_, loop_, channels_, other); }, StateError);
  // The same config recovers it (the refused attempt changed nothing).
  lmf::server::ServerNode node(bus_, loop_, channels_, options(state, "config_c"));
  EXPECT_EQ(node.view().fusion_count, 1);
}

}  // namespace
