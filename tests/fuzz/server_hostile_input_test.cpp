// Hostile input through the real lmf-server node over memq://:
// every kind of bad local map and sighting the issue lists (oversized,
// NaN/inf, wrong array sizes, indefinite covariances, bad angles, unknown
// robots, sequence numbers from the past, values the GlobalMap itself
// refuses) is rejected with its counted reason, and the map after shutdown is
// bit-for-bit the map of the valid inputs alone (MapFingerprint). Then a flood
// of mutated messages, one at a time, must leave the server's map identical
// to a GlobalMap fed the same messages through the same decisions.
//
// Asymmetric covariances cannot travel (the wire holds the packed upper
// triangle, runtime/convert.hpp); the GlobalMap's own check for them is fuzzed
// by the global_map_fuse target.
#include <chrono>
#include <cmath>
#include <cstdint>
#include <functional>
#include <limits>
#include <map>
#include <set>
#include <thread>
#include <string>
#include <tuple>
#include <utility>
#include <vector>

#include <gtest/gtest.h>

#include "fuzz_support.hpp"
#include "fusion_server/server_node.hpp"
#include "lmf/geometry/pose2.hpp"
#include "mutator.hpp"
#include "processes/server_test_support.hpp"
#include "runtime/bus.hpp"
#include "runtime/channels.hpp"
#include "runtime/convert.hpp"
#include "runtime/event_loop.hpp"

namespace {

namespace rt = lmf::runtime;
using namespace std::chrono_literals;
using lmf::LocalMapSnapshot;
using lmf::Pose2;
using lmf::fuzz::Bytes;
using lmf::testing::make_sighting;
using lmf::testing::reject_count;
using lmf::testing::reject_total;
using lmf::testing::room_local_map;
using lmf::testing::to_msg;

constexpr int kMaxRobots = 4;
constexpr int kMaxSegments = 8;  // DecodeLimits of the test server: 9 segments are oversized

class ServerHostileInput : public lmf::testing::ServerNodeFixture {
 protected:
  lmf::server::ServerOptions options() const {
    lmf::server::ServerOptions o;
    o.out_dir = std::filesystem::path(::testing::TempDir()) / "lmf_server_hostile";
    o.max_robots = kMaxRobots;
    o.queue_capacity = 4096;  // never full here: every message gets a decision
    o.limits.max_message_bytes = 1 << 16;
    o.limits.max_segments = kMaxSegments;
    return o;
  }

  // What the server has decided so far: every message ends in a counted
  // rejection or an acknowledgement (or, for sightings, an applied one).
  std::int64_t decisions(const lmf::server::ServerNode& node) const {
    return static_cast<std::int64_t>(acks_.size()) + node.stats().sightings_applied + reject_total(node);
  }

  // Publishes one message and runs the loop until the server decided on it.
  bool send(lmf::server::ServerNode& node, const std::string& channel, const Bytes& bytes) {
    const std::int64_t before = decisions(node);
    bus_.publish_raw(channel, bytes);
    const auto end = std::chrono::steady_clock::now() + 10s;
    while (decisions(node) == before || node.worker_busy()) {
      if (std::chrono::steady_clock::now() > end) return false;
      if (loop_.poll() == 0) std::this_thread::sleep_for(50us);
    }
    loop_.poll();
    return true;
  }
  template <class Msg>
  bool send(lmf::server::ServerNode& node, const std::string& channel, const Msg& m) {
    return send(node, channel, rt::encode_message(m));
  }
};

TEST_F(ServerHostileInput, EveryKindOfBadMessageIsRejectedByReasonAndTheMapIsThatOfTheGoodOnes) {
  lmf::server::ServerNode node(bus_, loop_, channels_, options());
  // The good inputs, and the same applied to a GlobalMap directly.
  lmf::fusion::GlobalMap reference(options().global_map);
  reference.join_robot(0, Pose2());  // as the server does at start (first robot 0)
  ASSERT_TRUE(send(node, channels_.local_map(), to_msg(room_local_map(0, 0))));
  reference.fuse(room_local_map(0, 0));
  ASSERT_TRUE(send(node, channels_.sighting(), to_msg(make_sighting(0, 2, 500'000))));
  reference.add_sighting(make_sighting(0, 2, 500'000));
  const std::int64_t fusions = node.view().fusion_count;
  ASSERT_EQ(node.view().counts.robots_joined, 2);
  ASSERT_EQ(lmf::fuzz::fingerprint(reference).counts.robots_joined, 2);

  const double nan = std::numeric_limits<double>::quiet_NaN();
  const double inf = std::numeric_limits<double>::infinity();
  const std::string map_channel = channels_.local_map();
  const std::string sighting_channel = channels_.sighting();
  std::map<std::string, std::int64_t> expected;
  const auto bad = [&](const std::string& channel, const Bytes& bytes, const std::string& reason) {
    ASSERT_TRUE(send(node, channel, bytes)) << "no decision on a message expected to be " << reason;
    ++expected[reason];
    EXPECT_EQ(reject_count(node, reason), expected[reason]) << "after a message expected to be " << reason;
  };
  const auto bad_map = [&](const std::function<void(lmf::local_map_t&)>& edit, const std::string& reason) {
    lmf::local_map_t m = to_msg(room_local_map(0, 1));
    edit(m);
    bad(map_channel, rt::encode_message(m), reason);
  };
  const auto bad_sighting = [&](const std::function<void(lmf::sighting_t&)>& edit, const std::string& reason) {
    lmf::sighting_t s = to_msg(make_sighting(0, 1, 600'000));
    edit(s);
    bad(sighting_channel, rt::encode_message(s), reason);
  };

  // ---- LMF_LOCAL_MAP ----
  bad(map_channel, Bytes{0xde, 0xad, 0xbe, 0xef, 1, 2, 3, 4, 5, 6, 7, 8, 9}, "decode_failed");
  Bytes truncated = rt::encode_message(to_msg(room_local_map(0, 1)));
  truncated.resize(truncated.size() - 3);
  bad(map_channel, truncated, "decode_failed");
  bad(map_channel, Bytes((1 << 16) + 1, 0), "oversized");                      // more bytes than the limit
  bad(map_channel, rt::encode_message(to_msg(room_local_map(0, 1, kMaxSegments + 1))), "oversized");  // too many segments
  {
    // A forged count on the wire (lcm-gen's encoder would read past the vector):
    // num_segments follows hash, utime, robot_id, seq, first_scan_utime,
    // num_scans and the robot pose (8 + 8 + 4 + 8 + 8 + 4 + 24 bytes).
    Bytes forged = rt::encode_message(to_msg(room_local_map(0, 1)));
    constexpr std::size_t kNumSegmentsAt = 64;
    ASSERT_EQ(forged.at(kNumSegmentsAt + 3), 5) << "local_map_t layout changed";
    forged[kNumSegmentsAt + 1] = 0x10;  // 5 -> 0x00100005 segments
    bad(map_channel, forged, "oversized");
  }
  bad_map([&](auto& m) { m.segments[2].location.y = nan; }, "non_finite");
  bad_map([&](auto& m) { m.covariance[4] = inf; }, "non_finite");
  bad_map([&](auto& m) { m.robot.x = -inf; }, "non_finite");
  bad_map([](auto& m) { m.covariance.push_back(0.0), ++m.num_covariance; }, "wrong_size");
  bad_map([](auto& m) { m.covariance.pop_back(), --m.num_covariance; }, "wrong_size");
  bad_map([](auto& m) { m.num_scans += 1; }, "wrong_size");
  bad_map([](auto& m) { m.covariance[0] = -1e-3; }, "covariance_not_psd");     // Var(x_R) < 0
  bad_map([](auto& m) { m.covariance[1] = 2e-3; }, "covariance_not_psd");      // |Cov(x, y)| > sqrt(Var x Var y)
  bad_map([](auto& m) { m.segments[0].location.phi = 4.0; }, "bad_angle");
  bad_map([](auto& m) { m.seq = -1; }, "out_of_range");
  bad_map([](auto& m) { m.first_scan_utime = m.utime + 1; }, "out_of_range");
  bad_map([](auto& m) { m.segments[1].length = -2.0f; }, "out_of_range");
  bad_map([](auto& m) { m.segments[1].location.x = 1e7; }, "out_of_range");    // refused by the GlobalMap itself
  bad(map_channel, rt::encode_message(to_msg(room_local_map(7, 0))), "unknown_robot");  // --max-robots 4
  bad(map_channel, rt::encode_message(to_msg(room_local_map(0, 0))), "stale_sequence"); // applied before: from the past

  // ---- LMF_SIGHTING ----
  bad(sighting_channel, Bytes{1, 2, 3}, "decode_failed");
  bad(sighting_channel, Bytes((1 << 16) + 1, 7), "oversized");
  bad_sighting([&](auto& s) { s.relative.x = nan; }, "non_finite");
  bad_sighting([&](auto& s) { s.observer_covariance[3] = inf; }, "non_finite");
  bad_sighting([](auto& s) { s.covariance[0] = -0.5; }, "covariance_not_psd");
  bad_sighting([](auto& s) { s.observed_covariance[0] = 1e-4, s.observed_covariance[1] = 1e-2; }, "covariance_not_psd");
  bad_sighting([](auto& s) { s.observed_in_local.phi = -3.5; }, "bad_angle");
  bad_sighting([](auto& s) { s.observer_seq = -3; }, "out_of_range");
  bad_sighting([](auto& s) { s.observed_id = s.observer_id; }, "out_of_range");  // a robot seeing itself
  bad_sighting([](auto& s) { s.relative.x = 2e6; }, "out_of_range");             // refused by the GlobalMap
  bad_sighting([](auto& s) { s.observed_id = 9; }, "unknown_robot");
  bad_sighting([](auto& s) { s.observer_id = kMaxRobots; }, "unknown_robot");
  bad(sighting_channel, rt::encode_message(to_msg(make_sighting(0, 2, 500'000))), "stale_sequence");  // replayed

  EXPECT_EQ(node.view().fusion_count, fusions);
  const std::int64_t total = reject_total(node);
  std::int64_t expected_total = 0;
  for (const auto& [name, n] : expected) expected_total += n;
  EXPECT_EQ(total, expected_total) << "a message was counted under an unexpected reason";

  ASSERT_TRUE(node.shutdown(false));
  ASSERT_NE(node.map_after_shutdown(), nullptr);
  const lmf::fuzz::MapFingerprint after = lmf::fuzz::fingerprint(*node.map_after_shutdown());
  const lmf::fuzz::MapFingerprint good = lmf::fuzz::fingerprint(reference);
  EXPECT_TRUE(after == good) << "server: " << after.describe() << "\nreference: " << good.describe();
}

// Mutated local maps and sightings, one at a time. The reference makes the
// server's decisions (lmf-server header): decode, robot ids below
// --max-robots, no robot seeing itself, (robot, seq) and (utime, observer,
// observed) applied once, then the GlobalMap's own validation.
TEST_F(ServerHostileInput, MutatedMessagesLeaveTheSameMapAsTheServersDecisionsOnAGlobalMap) {
  lmf::server::ServerNode node(bus_, loop_, channels_, options());
  lmf::fusion::GlobalMap reference(options().global_map);
  reference.join_robot(0, Pose2());
  std::set<std::pair<int, std::int64_t>> applied_maps;
  std::set<std::tuple<std::int64_t, int, int>> seen_sightings;
  std::int64_t reference_rejects = 0;
  const rt::DecodeLimits limits = options().limits;

  std::vector<Bytes> map_seeds;
  for (std::int64_t seq = 0; seq < 4; ++seq) map_seeds.push_back(rt::encode_message(to_msg(room_local_map(0, seq))));
  map_seeds.push_back(rt::encode_message(to_msg(room_local_map(1, 0, 4, Pose2(2.0, 0.5, 0.1)))));
  std::vector<Bytes> sighting_seeds = {rt::encode_message(to_msg(make_sighting(0, 1, 900'000))),
                                       rt::encode_message(to_msg(make_sighting(0, 3, 950'000)))};
  lmf::fuzz::Mutator map_mutator(map_seeds, 1 << 16);
  lmf::fuzz::Mutator sighting_mutator(sighting_seeds, 1 << 12);

  constexpr std::uint64_t kInputs = 400;
  for (std::uint64_t i = 0; i < kInputs; ++i) {
    const bool sighting = i % 4 == 3;
    // Every 8th input is a seed as it is, so valid maps and sightings get applied too.
    const Bytes bytes = i % 8 == 0 ? map_seeds[(i / 8) % map_seeds.size()]
                                   : (sighting ? sighting_mutator.input(7, i) : map_mutator.input(7, i));
    ASSERT_TRUE(send(node, sighting ? channels_.sighting() : channels_.local_map(), bytes)) << "input " << i;
    if (sighting) {
      const auto s = rt::decode<lmf::fusion::RobotSighting>(bytes.data(), bytes.size(), limits);
      if (!s || s.value().observer_id >= kMaxRobots || s.value().observed_id >= kMaxRobots ||
          !seen_sightings.insert({s.value().utime, s.value().observer_id, s.value().observed_id}).second) {
        ++reference_rejects;
        continue;
      }
      try {
        reference.add_sighting(s.value());
      } catch (const lmf::fusion::InvalidInput&) {
        ++reference_rejects;
      }
    } else {
      const auto m = rt::decode<LocalMapSnapshot>(bytes.data(), bytes.size(), limits);
      if (!m || m.value().robot_id >= kMaxRobots || applied_maps.count({m.value().robot_id, m.value().seq}) != 0) {
        ++reference_rejects;
        continue;
      }
      try {
        reference.fuse(m.value());
        applied_maps.insert({m.value().robot_id, m.value().seq});
      } catch (const lmf::fusion::InvalidInput&) {
        ++reference_rejects;
      }
    }
  }
  EXPECT_EQ(reject_total(node), reference_rejects);
  EXPECT_GT(reference_rejects, static_cast<std::int64_t>(kInputs / 4)) << "the mutations should mostly be refused";
  EXPECT_GT(node.view().fusion_count, 0) << "and some maps fused";

  ASSERT_TRUE(node.shutdown(false));
  const lmf::fuzz::MapFingerprint after = lmf::fuzz::fingerprint(*node.map_after_shutdown());
  const lmf::fuzz::MapFingerprint expected = lmf::fuzz::fingerprint(reference);
  EXPECT_TRUE(after == expected) << "server: " << after.describe() << "\nreference: " << expected.describe();
}

}  // namespace
