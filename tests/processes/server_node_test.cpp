// lmf-server's node in one process over memq://: exactly-once acks, duplicates,
// robots joining through sightings, back-pressure, bad input on LMF_LOCAL_MAP
// and LMF_SIGHTING rejected by reason with the map unchanged, outputs at stop.
#include <chrono>
#include <cmath>
#include <cstdint>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <functional>
#include <limits>
#include <map>
#include <string>
#include <tuple>
#include <vector>

#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include "fusion_server/server_node.hpp"
#include "lmf/geometry/pose2.hpp"
#include "lmf/local_map/local_map_snapshot.hpp"
#include "runtime/bus.hpp"
#include "runtime/channels.hpp"
#include "runtime/convert.hpp"
#include "runtime/event_loop.hpp"
#include "server_test_support.hpp"

namespace {

namespace rt = lmf::runtime;
using namespace std::chrono_literals;
using lmf::LocalMapSnapshot;
using lmf::Pose2;
using lmf::testing::make_sighting;
using lmf::testing::reject_count;
using lmf::testing::reject_total;
using lmf::testing::to_msg;
using Status = rt::LocalMapAck::Status;

// room_local_map() with all six walls of the room and a third scan pose mid-way.
LocalMapSnapshot make_map(int robot_id, std::int64_t seq, const Pose2& x_WL0 = Pose2()) {
  LocalMapSnapshot s = lmf::testing::room_local_map(robot_id, seq, 6, x_WL0);
  s.scan_poses.insert(s.scan_poses.begin() + 1, {s.first_utime + 400'000, Pose2(0.5, 0.0, 0.0)});
  return s;
}

class ServerNodeTest : public lmf::testing::ServerNodeFixture {
 protected:
  ServerNodeTest() {
    out_ = std::filesystem::path(::testing::TempDir()) /
           ("lmf_server_" + std::string(::testing::UnitTest::GetInstance()->current_test_info()->name()));
    std::filesystem::remove_all(out_);
    bus_.subscribe_message<lmf::sighting_ack_t>(
        channels_.sighting_ack(), [this](const std::string&, const lmf::sighting_ack_t& ack) {
          sighting_acks_.emplace_back(ack.utime, ack.observer_id, ack.observed_id, ack.status);
        });
    bus_.subscribe_message<lmf::server_status_t>(
        channels_.server_status(), [this](const std::string&, const lmf::server_status_t& s) { statuses_.push_back(s); });
    bus_.subscribe_message<lmf::corrected_frames_t>(
        channels_.corrected_frames(), [this](const std::string&, const lmf::corrected_frames_t& f) { frames_.push_back(f); });
    bus_.subscribe_message<lmf::global_map_t>(
        channels_.global_map(), [this](const std::string&, const lmf::global_map_t& m) { maps_.push_back(m); });
  }

  lmf::server::ServerOptions options(std::size_t capacity = 16) const {
    lmf::server::ServerOptions o;
    o.out_dir = out_;
    o.max_robots = 4;
    o.queue_capacity = capacity;
    o.status_interval = 50ms;
    o.frames_interval = 100ms;
    o.map_interval = 100ms;
    o.map_min_interval = 0ms;
    return o;
  }

  int count_sighting_acks(std::int64_t utime, int observer, int observed, std::int8_t status) const {
    int n = 0;
    for (const auto& [t, a, b, st] : sighting_acks_) n += (t == utime && a == observer && b == observed && st == status);
    return n;
  }

  std::filesystem::path out_;
  std::vector<std::tuple<std::int64_t, int, int, std::int8_t>> sighting_acks_;  // (utime, observer, observed, status)
  std::vector<lmf::server_status_t> statuses_;
  std::vector<lmf::corrected_frames_t> frames_;
  std::vector<lmf::global_map_t> maps_;
};

TEST_F(ServerNodeTest, AcksEachLocalMapOnceAndDuplicatesAreNotRefused) {
  lmf::server::ServerNode node(bus_, loop_, channels_, options());
  for (std::int64_t seq = 0; seq < 4; ++seq) bus_.publish(channels_.local_map(), to_msg(make_map(0, seq)));
  ASSERT_TRUE(run_until([&] { return node.stats().acks_fused == 4; }));
  settle(node);
  for (std::int64_t seq = 0; seq < 4; ++seq) {
    EXPECT_EQ(count_acks(0, seq, Status::kFused), 1) << "seq " << seq;
    EXPECT_EQ(count_acks(0, seq, Status::kReceived), 1) << "seq " << seq << ": answered on receipt too";
    EXPECT_LT(first_ack(0, seq, Status::kReceived), first_ack(0, seq, Status::kFused)) << "seq " << seq;
  }
  EXPECT_EQ(node.view().fusion_count, 4);
  const auto counts = node.view().counts;
  EXPECT_GE(counts.segments, 1);
  EXPECT_EQ(counts.robots_joined, 1);

  // A resend (lost ack): DUPLICATE, counted, never fused again.
  bus_.publish(channels_.local_map(), to_msg(make_map(0, 2)));
  ASSERT_TRUE(run_until([&] { return count_acks(0, 2, Status::kDuplicate) == 1; }));
  settle(node);
  EXPECT_EQ(node.view().fusion_count, 4);
  EXPECT_EQ(node.view().counts.segments, counts.segments);
  EXPECT_EQ(count_acks(0, 2, Status::kFused), 1);
  EXPECT_EQ(reject_count(node, "stale_sequence"), 1);

  // Robot 1 has not joined: its map is held (QUEUED), then fused when robot 0 sees it.
  bus_.publish(channels_.local_map(), to_msg(make_map(1, 0, Pose2(2.0, 0.5, 0.1))));
  ASSERT_TRUE(run_until([&] { return count_acks(1, 0, Status::kQueued) == 1; }));
  EXPECT_EQ(count_acks(1, 0, Status::kFused), 0);
  bus_.publish(channels_.sighting(), to_msg(make_sighting(0, 1, 1'000'000)));
  ASSERT_TRUE(run_until([&] { return count_acks(1, 0, Status::kFused) == 1; }));
  settle(node);
  EXPECT_EQ(node.view().counts.robots_joined, 2);
  EXPECT_EQ(node.view().fusion_count, 5);
  EXPECT_EQ(node.stats().sightings_applied, 1);
  // A resend of the queued-then-fused map is a duplicate too.
  bus_.publish(channels_.local_map(), to_msg(make_map(1, 0, Pose2(2.0, 0.5, 0.1))));
  ASSERT_TRUE(run_until([&] { return count_acks(1, 0, Status::kDuplicate) == 1; }));

  // Periodic publications arrived and decode; the last frames know both robots.
  ASSERT_TRUE(run_until([&] { return !statuses_.empty() && !maps_.empty() && !frames_.empty(); }));
  ASSERT_TRUE(run_until([&] { return frames_.back().num_robots == 2; }));
  EXPECT_EQ(frames_.back().fusion_count, 5);
  for (int i = 0; i < frames_.back().num_robots; ++i) {
    if (frames_.back().robot_ids[i] == 0) {
      EXPECT_EQ(frames_.back().last_applied_seq[i], 3);
    }
  }
  ASSERT_TRUE(run_until([&] { return statuses_.back().fusions == 5; }));
  EXPECT_EQ(statuses_.back().num_robots_joined, 2);
  EXPECT_EQ(statuses_.back().num_segments, node.view().counts.segments);
  EXPECT_TRUE(statuses_.back().covariance_ok);
  ASSERT_TRUE(run_until([&] { return maps_.back().fusion_count == 5; }));
  EXPECT_EQ(maps_.back().num_segments, node.view().counts.segments);
}

TEST_F(ServerNodeTest, BadMessagesAreRejectedByReasonAndLeaveTheMapUnchanged) {
  lmf::server::ServerNode node(bus_, loop_, channels_, options());
  bus_.publish(channels_.local_map(), to_msg(make_map(0, 0)));
  bus_.publish(channels_.sighting(), to_msg(make_sighting(0, 2, 500'000)));  // robot 2 joins
  ASSERT_TRUE(run_until([&] { return node.stats().acks_fused == 1 && node.stats().sightings_applied == 1; }));
  settle(node);
  const lmf::server::MapView before = node.view();
  const std::int64_t acks_before = node.stats().acks_fused + node.stats().acks_queued;
  ASSERT_EQ(before.counts.robots_joined, 2);
  ASSERT_EQ(reject_total(node), 0);

  const std::vector<std::uint8_t> garbage = {0xde, 0xad, 0xbe, 0xef, 1, 2, 3, 4, 5, 6, 7, 8, 9, 10, 11, 12, 13};
  const double nan = std::numeric_limits<double>::quiet_NaN();
  // LMF_LOCAL_MAP: garbage, NaN, wrong covariance count, indefinite covariance,
  // unknown robot, replayed seq.
  bus_.publish_raw(channels_.local_map(), garbage);
  lmf::local_map_t m = to_msg(make_map(0, 1));
  m.segments[0].location.x = nan;
  bus_.publish(channels_.local_map(), m);
  m = to_msg(make_map(0, 1));
  m.covariance.push_back(0.0);
  m.num_covariance += 1;
  bus_.publish(channels_.local_map(), m);
  m = to_msg(make_map(0, 1));
  m.covariance[0] = -1.0;  // Var(p_R.x) < 0
  bus_.publish(channels_.local_map(), m);
  bus_.publish(channels_.local_map(), to_msg(make_map(3, 0)));  // robot 3 is known (max 4): a valid queued map
  bus_.publish(channels_.local_map(), to_msg(make_map(7, 0)));  // robot 7 is not
  bus_.publish(channels_.local_map(), to_msg(make_map(0, 0)));  // replayed
  // LMF_SIGHTING: garbage, NaN, indefinite covariance, unknown robot, self, replayed.
  bus_.publish_raw(channels_.sighting(), garbage);
  lmf::sighting_t s = to_msg(make_sighting(0, 1, 600'000));
  s.relative.y = nan;
  bus_.publish(channels_.sighting(), s);
  s = to_msg(make_sighting(0, 1, 600'000));
  s.covariance[0] = -0.5;
  bus_.publish(channels_.sighting(), s);
  bus_.publish(channels_.sighting(), to_msg(make_sighting(0, 9, 600'000)));
  s = to_msg(make_sighting(0, 1, 600'000));
  s.observed_id = 0;
  bus_.publish(channels_.sighting(), s);
  bus_.publish(channels_.sighting(), to_msg(make_sighting(0, 2, 500'000)));  // replayed

  ASSERT_TRUE(run_until([&] { return reject_total(node) >= 12 && count_acks(3, 0, Status::kQueued) == 1; }));
  settle(node);
  EXPECT_EQ(reject_total(node), 12);
  EXPECT_EQ(reject_count(node, "decode_failed"), 2);
  EXPECT_EQ(reject_count(node, "non_finite"), 2);
  EXPECT_EQ(reject_count(node, "wrong_size"), 1);
  EXPECT_EQ(reject_count(node, "covariance_not_psd"), 2);
  EXPECT_EQ(reject_count(node, "unknown_robot"), 2);
  EXPECT_EQ(reject_count(node, "stale_sequence"), 2);
  EXPECT_EQ(reject_count(node, "out_of_range") + reject_count(node, "wrong_size"), 2) << "the self-sighting";
  EXPECT_EQ(count_acks(0, 0, Status::kDuplicate), 1);
  // Sightings: the applied one was answered APPLIED, its replay DUPLICATE, the
  // unknown robot and the self-sighting REJECTED (the player stops resending);
  // what did not decode (garbage, NaN, indefinite) cannot be answered.
  EXPECT_EQ(count_sighting_acks(500'000, 0, 2, lmf::sighting_ack_t::APPLIED), 1);
  EXPECT_EQ(count_sighting_acks(500'000, 0, 2, lmf::sighting_ack_t::DUPLICATE), 1);
  EXPECT_EQ(count_sighting_acks(600'000, 0, 9, lmf::sighting_ack_t::REJECTED), 1);
  EXPECT_EQ(count_sighting_acks(600'000, 0, 0, lmf::sighting_ack_t::REJECTED), 1);
  EXPECT_EQ(count_sighting_acks(500'000, 0, 2, lmf::sighting_ack_t::RECEIVED), 1) << "on receipt, before APPLIED";
  EXPECT_EQ(sighting_acks_.size(), 5u);

  // Only the valid queued map of robot 3 reached the GlobalMap, which did not fuse it.
  const lmf::server::MapView& after = node.view();
  EXPECT_EQ(after.fusion_count, before.fusion_count);
  EXPECT_EQ(after.counts.segments, before.counts.segments);
  EXPECT_EQ(after.counts.submaps, before.counts.submaps);
  EXPECT_EQ(after.counts.robots_joined, before.counts.robots_joined);
  EXPECT_EQ(after.counts.state_dimension, before.counts.state_dimension);
  EXPECT_EQ(after.counts.queued_local_maps, before.counts.queued_local_maps + 1);
  EXPECT_EQ(after.endpoints, before.endpoints);
  EXPECT_EQ(node.stats().acks_fused + node.stats().acks_queued, acks_before + 1);

  // The status reports the reasons.
  const rt::ServerStatus status = node.make_status();
  std::map<std::string, std::int64_t> reasons(status.rejects.begin(), status.rejects.end());
  EXPECT_EQ(reasons["decode_failed"], 2);
  EXPECT_EQ(reasons["unknown_robot"], 2);
}

TEST_F(ServerNodeTest, FullQueueDefersWithoutAckAndResendsAreFusedOnce) {
  lmf::server::ServerNode node(bus_, loop_, channels_, options(1));
  constexpr std::int64_t kMaps = 24;
  // Like an agent: resend every unacknowledged map until acknowledged.
  const auto acked = [&](std::int64_t seq) {
    return count_acks(0, seq, Status::kFused) + count_acks(0, seq, Status::kQueued) > 0;
  };
  const auto all_acked = [&] {
    for (std::int64_t seq = 0; seq < kMaps; ++seq) {
      if (!acked(seq)) return false;
    }
    return true;
  };
  int rounds = 0;
  while (!all_acked() && rounds < 200) {
    for (std::int64_t seq = 0; seq < kMaps; ++seq) {
      if (!acked(seq)) bus_.publish(channels_.local_map(), to_msg(make_map(0, seq)));
    }
    // Quiet before the next round: worker idle and nothing left to deliver
    // (acks included), so only maps the server has not applied are resent; a
    // fixed wait was too short for a slow (sanitizer) build, whose resends
    // then crossed their acks and were answered DUPLICATE.
    run_until([&] { return !node.worker_busy() && loop_.poll() == 0; }, 1000ms);
    ++rounds;
  }
  ASSERT_TRUE(all_acked()) << "after " << rounds << " rounds";
  settle(node);
  EXPECT_GT(node.stats().deferred_queue_full, 0) << "capacity 1 and " << kMaps << " maps in one burst";
  // Out-of-order arrivals may be held (QUEUED) and fused later: every map is
  // acked FUSED exactly once, and QUEUED at most once before that.
  for (std::int64_t seq = 0; seq < kMaps; ++seq) {
    EXPECT_EQ(count_acks(0, seq, Status::kFused), 1) << "seq " << seq;
    EXPECT_LE(count_acks(0, seq, Status::kQueued), 1) << "seq " << seq;
    EXPECT_EQ(count_acks(0, seq, Status::kDuplicate), 0) << "seq " << seq;
    EXPECT_GE(count_acks(0, seq, Status::kReceived), 1) << "seq " << seq << ": taken, so answered on receipt";
  }
  EXPECT_EQ(node.view().fusion_count, kMaps);
  EXPECT_EQ(node.view().counts.queued_local_maps, 0);
}

TEST_F(ServerNodeTest, WritesOutputsOnRequestAndAtStop) {
  lmf::server::ServerNode node(bus_, loop_, channels_, options());
  for (std::int64_t seq = 0; seq < 3; ++seq) bus_.publish(channels_.local_map(), to_msg(make_map(0, seq)));
  ASSERT_TRUE(run_until([&] { return node.stats().acks_fused == 3; }));
  node.request_write();
  ASSERT_TRUE(run_until([&] { return std::filesystem::exists(out_ / "report.json"); }));
  settle(node);
  bus_.publish(channels_.local_map(), to_msg(make_map(0, 3)));
  ASSERT_TRUE(run_until([&] { return node.stats().acks_fused == 4; }));
  ASSERT_TRUE(node.shutdown(true));
  EXPECT_TRUE(node.shutdown(true)) << "idempotent";

  for (const char* name : {"map.json", "map.svg", "trajectory.txt", "trajectories/robot0.txt", "report.json"}) {
    EXPECT_TRUE(std::filesystem::exists(out_ / name)) << name;
  }
  std::ifstream report_file(out_ / "report.json");
  const nlohmann::json report = nlohmann::json::parse(report_file);
  ASSERT_EQ(report["fusions"].size(), 4u);
  EXPECT_EQ(report["fusions"][3]["seq"], 3);
  EXPECT_EQ(report["messages"]["acks_fused"], 4);
  EXPECT_EQ(report["fusion_timing"]["count"], 4);
  EXPECT_EQ(report["map"]["segments"], node.view().counts.segments);

  // Every scan pose of the four local maps, in W: 3 per map.
  std::ifstream trajectory(out_ / "trajectories/robot0.txt");
  int poses = 0;
  for (std::string line; std::getline(trajectory, line);) poses += (!line.empty() && line[0] != '#') ? 1 : 0;
  EXPECT_EQ(poses, 12);
  std::ifstream map_file(out_ / "map.json");
  const nlohmann::json map = nlohmann::json::parse(map_file, nullptr, false);
  EXPECT_FALSE(map.is_discarded());
}

TEST(ServerOptions, RejectsBadValues) {
  lmf::server::ServerOptions o;
  EXPECT_NO_THROW(o.validate());
  o.queue_capacity = 0;
  EXPECT_THROW(o.validate(), std::invalid_argument);
  o = {};
  o.first_robot = 5;
  o.max_robots = 4;
  EXPECT_THROW(o.validate(), std::invalid_argument);
  o = {};
  o.status_interval = 0ms;
  EXPECT_THROW(o.validate(), std::invalid_argument);
}

#ifdef LMF_SERVER_EXE
TEST(ServerProcess, HelpAndBadOptions) {
  const std::string exe = LMF_SERVER_EXE;
  EXPECT_EQ(std::system((exe + " --help > /dev/null").c_str()), 0);
  EXPECT_NE(std::system((exe + " --no-such-option 2> /dev/null").c_str()), 0);
  EXPECT_NE(std::system((exe + " --queue-capacity 0 2> /dev/null").c_str()), 0);
}
#endif

}  // namespace
