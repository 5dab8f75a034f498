// AgentNode over memq:// in one process: scan handling (bad, duplicate, stale,
// future and lost scans), shipping and resending until acked, simulated loss,
// corrected frames, mission end and status.
#include <cmath>
#include <cstdint>
#include <limits>
#include <map>
#include <memory>
#include <numbers>
#include <optional>
#include <set>
#include <string>
#include <vector>

#include <gtest/gtest.h>

#include "lmf/mission/mission_inputs.hpp"
#include "player_test_support.hpp"
#include "robot_agent/agent_node.hpp"
#include "runtime/bus.hpp"
#include "runtime/convert.hpp"
#include "runtime/event_loop.hpp"

namespace {

using namespace std::chrono_literals;
namespace rt = lmf::runtime;
using lmf::Pose2;
using lmf::robot_agent::AgentNode;
using lmf::robot_agent::AgentOptions;
using lmf::runtime::RejectReason;
using lmf::testing::run_until;
using lmf::testing::sim_scans;

// One agent on a memq bus with a probe that records what it publishes.
struct Rig : lmf::testing::AgentProbe {
  std::unique_ptr<AgentNode> agent;
  std::vector<lmf::agent_status_t> statuses;

  explicit Rig(AgentOptions options) {
    agent = std::make_unique<AgentNode>(bus, loop, options);
    bus.subscribe(channels.agent_status(), [this](const std::string&, const void* d, std::size_t n) {
      auto status = rt::decode_message<lmf::agent_status_t>(d, n);
      ASSERT_TRUE(status.ok()) << status.rejection().describe();
      statuses.push_back(status.value());
    });
  }

  rt::RobotScan scan(std::int64_t seq, std::size_t index) const {
    rt::RobotScan s;
    s.robot_id = agent->robot_id();
    s.seq = seq;
    s.scan = sim_scans().at(index);
    return s;
  }
  void send(const rt::RobotScan& s) { bus.publish(channels.scan(s.robot_id), rt::to_message(s)); }
  void send_raw(const std::vector<std::uint8_t>& bytes) { bus.publish_raw(channels.scan(agent->robot_id()), bytes); }
  void ack_map(std::int64_t seq, rt::LocalMapAck::Status status = rt::LocalMapAck::Status::kFused) {
    bus.publish(channels.local_map_ack(), rt::to_message(rt::LocalMapAck{1, agent->robot_id(), seq, status}));
  }
};

AgentOptions options_for(int robot_id) {
  AgentOptions options;
  options.robot_id = robot_id;
  options.resend_interval = 20ms;
  options.status_interval = 50ms;
  return options;
}

TEST(AgentNode, BadScansAreCountedAndTheAgentKeepsGoing) {
  Rig rig(options_for(0));
  for (int k = 0; k < 3; ++k) rig.send(rig.scan(k, static_cast<std::size_t>(k)));
  rig.drain();
  ASSERT_EQ(rig.acks.size(), 3u);
  EXPECT_EQ(rig.acks[2].seq, 2);
  EXPECT_EQ(rig.acks[2].utime, sim_scans()[2].utime);

  // NaN range.
  auto nan_scan = rt::to_message(rig.scan(3, 3));
  nan_scan.ranges[10] = std::numeric_limits<float>::quiet_NaN();
  rig.bus.publish(rig.channels.scan(0), nan_scan);
  // Wrong count: num_ranges claims more beams than the bytes hold.
  auto bytes = rt::encode_message(rt::to_message(rig.scan(3, 3)));
  const std::size_t count_at = bytes.size() - 4 * sim_scans()[3].ranges_m.size() - 4;
  bytes[count_at + 2] ^= 0x10;
  rig.send_raw(bytes);
  // Garbage.
  rig.send_raw(std::vector<std::uint8_t>(100, 0xAB));
  rig.send_raw({});
  // Another robot's scan on our channel.
  auto foreign = rig.scan(3, 3);
  foreign.robot_id = 7;
  rig.bus.publish(rig.channels.scan(0), rt::to_message(foreign));
  // Far future and old seq numbers.
  rig.send(rig.scan(1'000'000, 3));
  rig.send(rig.scan(0, 5));  // seq 0 was another scan (another log)
  // Next seq but older than the last scan.
  rig.send(rig.scan(3, 1));
  rig.drain();

  const auto& rejects = rig.agent->rejects();
  EXPECT_EQ(rejects.count(RejectReason::kNonFinite), 1);
  EXPECT_EQ(rejects.count(RejectReason::kDecodeFailed), 3);
  EXPECT_EQ(rejects.count(RejectReason::kUnknownRobot), 1);
  EXPECT_EQ(rejects.count(RejectReason::kStaleSequence), 1);
  EXPECT_EQ(rejects.count(RejectReason::kOutOfRange), 2);
  EXPECT_EQ(rig.acks.size(), 3u) << "a refused scan is not acked";
  EXPECT_EQ(rig.agent->counters().scans_processed, 3);

  // A duplicate of the last scan (a lockstep resend) is re-acked, not reprocessed.
  rig.send(rig.scan(2, 2));
  rig.drain();
  ASSERT_EQ(rig.acks.size(), 4u);
  EXPECT_EQ(rig.acks[3].seq, 2);
  EXPECT_EQ(rig.acks[3].local_map_seq, rig.acks[2].local_map_seq);
  EXPECT_TRUE(lmf::is_near(rig.acks[3].x_LR, rig.acks[2].x_LR, 0.0, 0.0));
  EXPECT_EQ(rig.agent->counters().scans_duplicate, 1);
  EXPECT_EQ(rig.agent->counters().scans_processed, 3);
  // So is an earlier one sent again (a player restarted on the same log): with
  // the answer it had then.
  rig.send(rig.scan(0, 0));
  rig.drain();
  ASSERT_EQ(rig.acks.size(), 5u);
  EXPECT_EQ(rig.acks[4].seq, 0);
  EXPECT_EQ(rig.acks[4].utime, rig.acks[0].utime);
  EXPECT_TRUE(lmf::is_near(rig.acks[4].x_LR, rig.acks[0].x_LR, 0.0, 0.0));
  EXPECT_EQ(rig.agent->counters().scans_duplicate, 2);
  EXPECT_EQ(rig.agent->counters().scans_processed, 3);
  EXPECT_EQ(rejects.count(RejectReason::kStaleSequence), 1);

  // Good scans go on; a gap (a lost scan) is processed and counted.
  rig.send(rig.scan(3, 3));
  rig.send(rig.scan(5, 5));
  rig.drain();
  ASSERT_EQ(rig.acks.size(), 7u);
  EXPECT_EQ(rig.acks[6].seq, 5);
  EXPECT_EQ(rig.agent->counters().scans_processed, 5);
  EXPECT_EQ(rig.agent->counters().scans_missed, 1);
  EXPECT_EQ(rig.agent->next_scan_seq(), 6);
  EXPECT_EQ(rig.agent->local_map().seq(), 0);
  EXPECT_EQ(rig.agent->local_map().snapshot().scan_poses.size(), 5u);

  // The status carries the reject counts and the per-scan timing.
  rig.statuses.clear();
  ASSERT_TRUE(run_until(rig.loop, [&] { return !rig.statuses.empty(); }, 2s));
  const lmf::agent_status_t& status = rig.statuses.back();
  EXPECT_EQ(status.scans, 5);
  EXPECT_GE(status.scan_time_max_ms, status.scan_time_p50_ms);
  EXPECT_FALSE(status.joined);
  std::int64_t total = 0;
  for (const auto c : status.reject_counts) total += c;
  EXPECT_EQ(total, rejects.total());
}

TEST(AgentNode, ShipsBeforeTheAckResendsUntilAckedAndChainsCorrectedFrames) {
  AgentOptions options = options_for(2);
  options.local_map.ship_distance_m = 2.0;
  Rig rig(options);
  // Order on the bus: a shipped map's first transmission comes before the ack
  // of the scan that shipped it, with only resends in between (that ack waits
  // for the map's answer: here none, so ack_hold or the next scan ends it).
  std::vector<std::int64_t> order;  // map seq, or -1 for a scan ack
  rig.bus.subscribe(rig.channels.local_map(), [&](const std::string&, const void* d, std::size_t n) {
    order.push_back(rt::decode<lmf::LocalMapSnapshot>(d, n).value().seq);
  });
  rig.bus.subscribe(rig.channels.scan_ack(), [&](const std::string&, const void*, std::size_t) {
    order.push_back(-1);
  });
  const std::size_t n = 60;  // 12 s at 0.5 m/s: a few maps of 2 m
  for (std::size_t k = 0; k < n; ++k) {
    rig.send(rig.scan(static_cast<std::int64_t>(k), k));
    rig.drain();
  }
  const std::int64_t shipped = rig.agent->counters().maps_shipped;
  ASSERT_GE(shipped, 2);
  ASSERT_EQ(rig.acks.size(), n);
  for (std::size_t k = 1; k < rig.acks.size(); ++k) {
    if (rig.acks[k].local_map_seq != rig.acks[k - 1].local_map_seq) {
      // The scan that shipped: the ack reports the fresh map, at its origin, exactly known.
      EXPECT_EQ(rig.acks[k].local_map_seq, rig.acks[k - 1].local_map_seq + 1);
      EXPECT_TRUE(lmf::is_near(rig.acks[k].x_LR, Pose2(), 0.0, 0.0));
      EXPECT_EQ(rig.acks[k].covariance.norm(), 0.0);
    }
  }
  std::set<std::int64_t> maps_seen;
  for (std::size_t i = 0; i < order.size(); ++i) {
    if (order[i] < 0 || !maps_seen.insert(order[i]).second) continue;
    std::size_t j = i + 1;
    for (; j < order.size() && order[j] >= 0; ++j) {
      EXPECT_TRUE(maps_seen.count(order[j]) != 0) << "map " << order[j] << " went out before the ack of map "
                                                  << order[i] << "'s scan";
    }
    EXPECT_LT(j, order.size()) << "map " << order[i] << " is followed by its scan's ack";
  }
  EXPECT_EQ(maps_seen.size(), static_cast<std::size_t>(shipped));
  ASSERT_EQ(rig.by_seq.size(), static_cast<std::size_t>(shipped));
  std::size_t scans_in_maps = 0;
  for (const auto& [seq, m] : rig.by_seq) scans_in_maps += m.scan_poses.size();
  EXPECT_EQ(scans_in_maps + rig.agent->local_map().snapshot().scan_poses.size(), n);

  // Unacknowledged maps are resent; an ack (any status) stops that map's resends.
  rig.maps.clear();
  ASSERT_TRUE(run_until(rig.loop, [&] { return rig.maps.size() >= 2 * static_cast<std::size_t>(shipped); }, 2s));
  EXPECT_GE(rig.agent->counters().map_resends, shipped);
  rig.ack_map(0, rt::LocalMapAck::Status::kQueued);
  rig.ack_map(0);  // a second ack of the same map changes nothing
  rig.ack_map(99); // never shipped: refused
  rig.drain();
  EXPECT_EQ(rig.agent->counters().maps_acknowledged, 1);
  EXPECT_EQ(rig.agent->counters().maps_queued, 1);
  EXPECT_EQ(rig.agent->rejects().count(RejectReason::kOutOfRange), 1);
  ASSERT_FALSE(rig.agent->unacknowledged_maps().empty());
  EXPECT_EQ(rig.agent->unacknowledged_maps().front(), 1);
  rig.maps.clear();
  ASSERT_TRUE(run_until(rig.loop, [&] { return rig.maps.size() >= 3; }, 2s));
  for (const auto& m : rig.maps) EXPECT_NE(m.seq, 0) << "map 0 was acked";

  // A corrected frame of map 1 while the agent is further on: the agent chains
  // the final poses of the maps it shipped since.
  const Pose2 x_WL1(10.0, -2.0, 0.5 * std::numbers::pi);
  rt::CorrectedFrames frames;
  frames.fusion_count = 4;
  frames.frames.push_back({2, 1, x_WL1, Eigen::Matrix3d::Identity() * 1e-4});  // robot 2, map 1
  frames.frames.push_back({5, 3, Pose2(), Eigen::Matrix3d::Zero()});  // another robot's
  rig.bus.publish(rig.channels.corrected_frames(), rt::to_message(frames).value());
  rig.drain();
  ASSERT_TRUE(rig.agent->joined());
  const auto pose = rig.agent->global_pose();
  ASSERT_TRUE(pose.has_value());
  Pose2 expected = x_WL1;
  for (std::int64_t k = 1; k < shipped; ++k) expected = lmf::compose(expected, rig.by_seq.at(k).x_LR);
  expected = lmf::compose(expected, rig.agent->local_map().x_LR());
  EXPECT_TRUE(lmf::is_near(*pose, expected, 1e-12, 1e-12));

  // An older fusion's frames are ignored; frames for a map not begun are refused.
  frames.fusion_count = 2;
  frames.frames[0].x_WL = Pose2(-50.0, 0.0, 0.0);
  rig.bus.publish(rig.channels.corrected_frames(), rt::to_message(frames).value());
  frames.fusion_count = 9;
  frames.frames[0].map_seq = shipped + 4;
  rig.bus.publish(rig.channels.corrected_frames(), rt::to_message(frames).value());
  rig.drain();
  EXPECT_TRUE(lmf::is_near(*rig.agent->global_pose(), expected, 1e-12, 1e-12));
  EXPECT_EQ(rig.agent->rejects().count(RejectReason::kOutOfRange), 2);

  // The frame of the current map: global pose = x_WL ⊕ x_LR.
  frames.fusion_count = 10;
  frames.frames[0].map_seq = shipped;
  frames.frames[0].x_WL = Pose2(1.0, 2.0, 3.0);
  rig.bus.publish(rig.channels.corrected_frames(), rt::to_message(frames).value());
  rig.drain();
  EXPECT_TRUE(lmf::is_near(*rig.agent->global_pose(),
                           lmf::compose(Pose2(1.0, 2.0, 3.0), rig.agent->local_map().x_LR()), 1e-12, 1e-12));
}

TEST(AgentNode, AScanThatShippedAMapIsAckedOnceTheServerAnsweredTheMap) {
  AgentOptions options = options_for(2);
  options.local_map.ship_distance_m = 2.0;
  options.resend_interval = 1000ms;
  options.min_resend_interval = 5ms;
  options.ack_hold = 1000ms;
  Rig rig(options);
  std::int64_t k = 0;
  // Sends scans one at a time, as a lockstep player, until one makes a map
  // ship; returns that map's seq.
  const auto scan_until_ship = [&] {
    const std::int64_t shipped = rig.agent->counters().maps_shipped;
    while (rig.agent->counters().maps_shipped == shipped) {
      rig.send(rig.scan(k, static_cast<std::size_t>(k)));
      ++k;
      rig.drain();
    }
    return rig.by_seq.rbegin()->first;
  };

  // The ack of the scan that ships waits for the map's answer.
  const std::int64_t first = scan_until_ship();
  EXPECT_EQ(rig.acks.size(), static_cast<std::size_t>(k - 1));
  rig.ack_map(first, rt::LocalMapAck::Status::kFused);
  rig.drain();
  ASSERT_EQ(rig.acks.size(), static_cast<std::size_t>(k));

  const std::int64_t second = scan_until_ship();
  EXPECT_EQ(rig.acks.size(), static_cast<std::size_t>(k - 1)) << "held";
  EXPECT_EQ(rig.agent->counters().scan_acks_held, 2);
  rig.send(rig.scan(k - 1, static_cast<std::size_t>(k - 1)));  // a lockstep resend meanwhile
  rig.drain();
  EXPECT_EQ(rig.acks.size(), static_cast<std::size_t>(k - 1)) << "a resend of the held scan gets nothing yet";
  rig.ack_map(second, rt::LocalMapAck::Status::kReceived);
  rig.drain();
  ASSERT_EQ(rig.acks.size(), static_cast<std::size_t>(k));
  EXPECT_EQ(rig.acks.back().seq, k - 1);
  EXPECT_EQ(rig.acks.back().local_map_seq, second + 1);
  // Received: still pending, now resent only every resend_interval.
  EXPECT_EQ(rig.agent->unacknowledged_maps(), std::vector<std::int64_t>{second});
  const std::size_t copies = rig.maps.size();
  rig.loop.run_for(200ms);
  EXPECT_EQ(rig.maps.size(), copies) << "no resend within 200 ms of RECEIVED (resend interval 1 s)";
  rig.ack_map(second, rt::LocalMapAck::Status::kFused);
  rig.drain();
  EXPECT_TRUE(rig.agent->unacknowledged_maps().empty());

  // The resend wait follows the answers' round trip (a few ms on memq), not
  // the 1 s interval: a map that gets no answer goes again within 200 ms, and
  // after ack_hold its scan's ack goes out without an answer.
  const auto shipped_at = std::chrono::steady_clock::now();
  const std::int64_t third = scan_until_ship();
  EXPECT_EQ(rig.acks.size(), static_cast<std::size_t>(k - 1));
  ASSERT_TRUE(run_until(rig.loop, [&] { return rig.agent->counters().map_resends >= 1; }, 200ms))
      << "the learned wait is far below the 1 s resend interval";
  ASSERT_TRUE(run_until(rig.loop, [&] { return rig.acks.size() == static_cast<std::size_t>(k); }, 3s));
  EXPECT_GE(std::chrono::steady_clock::now() - shipped_at, 900ms) << "held for ack_hold";
  EXPECT_EQ(rig.agent->counters().scan_ack_holds_expired, 1);
  rig.ack_map(third, rt::LocalMapAck::Status::kFused);
  rig.drain();

  // A --rate player does not wait: the next scan releases the held ack first.
  const std::int64_t fourth = scan_until_ship();
  (void)fourth;
  const std::size_t before = rig.acks.size();
  rig.send(rig.scan(k, static_cast<std::size_t>(k)));
  ++k;
  rig.drain();
  ASSERT_EQ(rig.acks.size(), before + 2);
  EXPECT_EQ(rig.acks[before].seq, k - 2);
  EXPECT_EQ(rig.acks[before + 1].seq, k - 1);
  EXPECT_EQ(rig.agent->counters().scan_acks_held, 4);
}

TEST(AgentNode, MissionEndShipsTheUnfinishedMapAndResendsUntilAcked) {
  Rig rig(options_for(1));
  for (std::size_t k = 0; k < 10; ++k) rig.send(rig.scan(static_cast<std::int64_t>(k), k));
  rig.drain();
  ASSERT_EQ(rig.agent->counters().maps_shipped, 0);

  // Not for this robot: nothing happens.
  rig.bus.publish(rig.channels.mission_end(), rt::to_message(rt::MissionEnd{1, {0, 2}}).value());
  rig.send_raw({1, 2, 3});  // and garbage on the scan channel changes nothing either
  rig.drain();
  EXPECT_FALSE(rig.agent->mission_ended());
  rig.bus.publish(rig.channels.mission_end(), rt::to_message(rt::MissionEnd{1, {0, 1}}).value());
  rig.bus.publish(rig.channels.mission_end(), rt::to_message(rt::MissionEnd{1, {0, 1}}).value());  // repeated
  rig.drain();
  EXPECT_TRUE(rig.agent->mission_ended());
  EXPECT_FALSE(rig.agent->mission_done());
  ASSERT_EQ(rig.agent->counters().maps_shipped, 1);
  ASSERT_FALSE(rig.maps.empty());
  EXPECT_EQ(rig.maps.front().seq, 0);
  EXPECT_EQ(rig.maps.front().scan_poses.size(), 10u);
  EXPECT_EQ(rig.maps.front().scan_poses.front().utime, sim_scans()[0].utime);
  EXPECT_EQ(rig.maps.front().last_utime, sim_scans()[9].utime);

  ASSERT_TRUE(run_until(rig.loop, [&] { return rig.maps.size() >= 3; }, 2s)) << "resent until acked";
  rig.ack_map(0);
  rig.drain();
  EXPECT_TRUE(rig.agent->mission_done());
  rig.statuses.clear();
  ASSERT_TRUE(run_until(rig.loop, [&] { return !rig.statuses.empty(); }, 2s));
  EXPECT_TRUE(rig.statuses.back().mission_done);
  EXPECT_EQ(rig.statuses.back().maps_acknowledged, 1);

  // A second agent with no scan ships nothing at the end and is done at once.
  AgentNode idle(rig.bus, rig.loop, options_for(0));
  rig.bus.publish(rig.channels.mission_end(), rt::to_message(rt::MissionEnd{1, {0, 1}}).value());
  rig.drain();
  EXPECT_TRUE(idle.mission_done());
  EXPECT_EQ(idle.counters().maps_shipped, 0);
}

TEST(AgentNode, SimulatedLossStillDeliversEveryMap) {
  AgentOptions options = options_for(0);
  options.local_map.ship_distance_m = 1.0;
  options.drop_local_maps = 0.5;
  options.drop_seed = 7;
  Rig rig(options);
  // A server that acks every map it receives.
  rig.bus.subscribe(rig.channels.local_map(), [&](const std::string&, const void* d, std::size_t n) {
    auto map = rt::decode<lmf::LocalMapSnapshot>(d, n);
    if (map) rig.ack_map(map.value().seq);
  });
  for (std::size_t k = 0; k < 60; ++k) {
    rig.send(rig.scan(static_cast<std::int64_t>(k), k));
    rig.drain();
  }
  const auto& c = rig.agent->counters();
  ASSERT_GE(c.maps_shipped, 4);
  ASSERT_TRUE(run_until(rig.loop, [&] { return rig.agent->unacknowledged_maps().empty(); }, 3s));
  EXPECT_EQ(c.maps_acknowledged, c.maps_shipped);
  EXPECT_GT(c.map_transmissions_dropped, 0);
  EXPECT_EQ(c.map_transmissions, c.maps_shipped + c.map_resends);
}

TEST(AgentNode, OptionsAreValidated) {
  rt::Bus bus("memq://");
  rt::EventLoop loop(bus, rt::EventLoopOptions{false});
  AgentOptions bad = options_for(-1);
  EXPECT_THROW(AgentNode(bus, loop, bad), std::invalid_argument);
  bad = options_for(0);
  bad.drop_local_maps = 1.0;
  EXPECT_THROW(AgentNode(bus, loop, bad), std::invalid_argument);
  bad = options_for(0);
  bad.resend_interval = 0ms;
  EXPECT_THROW(AgentNode(bus, loop, bad), std::invalid_argument);
  bad = options_for(0);
  bad.min_resend_interval = bad.resend_interval + 1ms;
  EXPECT_THROW(AgentNode(bus, loop, bad), std::invalid_argument);
  bad = options_for(0);
  bad.ack_hold = 0ms;
  EXPECT_THROW(AgentNode(bus, loop, bad), std::invalid_argument);
  bad = options_for(0);
  bad.local_map.ship_distance_m = -1.0;
  EXPECT_THROW(AgentNode(bus, loop, bad), std::invalid_argument);
}

}  // namespace
