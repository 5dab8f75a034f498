// Agent restart (kill and restart one agent, the mission completes and
// nothing the server had acknowledged is lost), over memq:// in one process:
//  * the persisted state file: round trip, and every single-byte corruption,
//    truncation or foreign content is detected;
//  * an agent destroyed (as by kill -9: nothing is written on the way out) and
//    rebuilt on its state: resends the unacknowledged map, continues the chain
//    of local maps from the persisted origin with the robot at the odometric
//    displacement, re-acks the origin scan, accepts the scan the player was
//    waiting for however far ahead;
//  * a lockstep mission (player, two agents, fake server) in which robot 1's
//    agent is killed mid-mission with a map unacknowledged and restarted: every
//    local map is fused exactly once, the seqs have no hole, and robot 1's ATE
//    stays close to the uninterrupted run's.
#include <chrono>
#include <cstdint>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <map>
#include <memory>
#include <optional>
#include <set>
#include <string>
#include <utility>
#include <vector>

#include <gtest/gtest.h>

#include "lmf/eval/trajectory_error.hpp"
#include "lmf/local_map/local_map_measurements.hpp"
#include "lmf/mission/mission_inputs.hpp"
#include "lmf/mission/offline_mission.hpp"
#include "lmf/mission/trajectory_book.hpp"
#include "log_player/player_node.hpp"
#include "player_test_support.hpp"
#include "robot_agent/agent_node.hpp"
#include "robot_agent/agent_state.hpp"
#include "runtime/bus.hpp"
#include "runtime/convert.hpp"
#include "runtime/event_loop.hpp"
#include "test_support.hpp"

namespace {

using namespace std::chrono_literals;
namespace rt = lmf::runtime;
using lmf::Pose2;
using lmf::robot_agent::AgentNode;
using lmf::robot_agent::AgentOptions;
using lmf::robot_agent::AgentState;
using lmf::robot_agent::AgentStateError;
using lmf::testing::run_until;
using lmf::testing::TempDir;
using lmf::testing::sim_scans;

std::vector<std::uint8_t> encoded_map(int robot_id, std::int64_t seq) {
  lmf::LocalMapSnapshot snapshot;
  snapshot.robot_id = robot_id;
  snapshot.seq = seq;
  snapshot.first_utime = 1000 * seq;
  snapshot.last_utime = 1000 * seq + 500;
  snapshot.x_LR = Pose2(1.0 + static_cast<double>(seq), 0.5, 0.1);
  snapshot.segments.push_back({Pose2(2.0, 1.0, 0.3), 1.5});
  snapshot.covariance = Eigen::MatrixXd::Identity(5, 5) * 1e-3;
  snapshot.scan_poses.push_back({snapshot.last_utime, snapshot.x_LR});
  auto msg = rt::to_message(snapshot);
  EXPECT_TRUE(msg.ok());
  return rt::encode_message(msg.value());
}

AgentState sample_state() {
  AgentState s;
  s.robot_id = 3;
  s.local_map_seq = 5;
  AgentState::Origin o;
  o.scan_seq = 42;
  o.utime = 123456789;
  o.odometry = Pose2(1.0, -2.0, 0.3);
  o.ack.utime = o.utime;
  o.ack.robot_id = 3;
  o.ack.seq = 42;
  o.ack.local_map_seq = 5;
  o.ack.x_LR = Pose2(0.0, 0.0, 0.0);
  o.ack.covariance = Eigen::Matrix3d::Identity() * 2e-4;
  s.origin = o;
  s.unacknowledged[3] = encoded_map(3, 3);
  s.unacknowledged[4] = encoded_map(3, 4);
  s.shipped_final_x_LR[3] = Pose2(4.0, 0.1, -0.2);
  s.shipped_final_x_LR[4] = Pose2(3.5, -0.1, 0.25);
  s.frame = AgentState::Frame{3, 17, Pose2(10.0, 5.0, 1.0)};
  s.mission_ended = true;
  s.maps_shipped = 5;
  s.maps_acknowledged = 3;
  return s;
}

void expect_equal(const AgentState& a, const AgentState& b) {
  EXPECT_EQ(a.robot_id, b.robot_id);
  EXPECT_EQ(a.local_map_seq, b.local_map_seq);
  ASSERT_EQ(a.origin.has_value(), b.origin.has_value());
  if (a.origin) {
    EXPECT_EQ(a.origin->scan_seq, b.origin->scan_seq);
    EXPECT_EQ(a.origin->utime, b.origin->utime);
    EXPECT_TRUE(lmf::is_near(a.origin->odometry, b.origin->odometry, 0.0, 0.0));
    EXPECT_EQ(a.origin->ack.seq, b.origin->ack.seq);
    EXPECT_EQ(a.origin->ack.utime, b.origin->ack.utime);
    EXPECT_EQ(a.origin->ack.robot_id, b.origin->ack.robot_id);
    EXPECT_EQ(a.origin->ack.local_map_seq, b.origin->ack.local_map_seq);
    EXPECT_TRUE(lmf::is_near(a.origin->ack.x_LR, b.origin->ack.x_LR, 0.0, 0.0));
    EXPECT_EQ(a.origin->ack.covariance, b.origin->ack.covariance);
  }
  EXPECT_EQ(a.unacknowledged, b.unacknowledged);
  ASSERT_EQ(a.shipped_final_x_LR.size(), b.shipped_final_x_LR.size());
  for (const auto& [seq, x] : a.shipped_final_x_LR) {
    ASSERT_EQ(b.shipped_final_x_LR.count(seq), 1u);
    EXPECT_TRUE(lmf::is_near(x, b.shipped_final_x_LR.at(seq), 0.0, 0.0));
  }
  ASSERT_EQ(a.frame.has_value(), b.frame.has_value());
  if (a.frame) {
    EXPECT_EQ(a.frame->map_seq, b.frame->map_seq);
    EXPECT_EQ(a.frame->fusion_count, b.frame->fusion_count);
    EXPECT_TRUE(lmf::is_near(a.frame->x_WL, b.frame->x_WL, 0.0, 0.0));
  }
  EXPECT_EQ(a.mission_ended, b.mission_ended);
  EXPECT_EQ(a.maps_shipped, b.maps_shipped);
  EXPECT_EQ(a.maps_acknowledged, b.maps_acknowledged);
}

std::vector<std::uint8_t> read_bytes(const std::filesystem::path& file) {
  std::ifstream in(file, std::ios::binary);
  return {std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>()};
}

void write_bytes(const std::filesystem::path& file, const std::vector<std::uint8_t>& bytes) {
  std::ofstream out(file, std::ios::binary | std::ios::trunc);
  out.write(reinterpret_cast<const char*>(bytes.data()), static_cast<std::streamsize>(bytes.size()));
}

TEST(AgentState, RoundTripsAndEveryCorruptionIsDetected) {
  const AgentState state = sample_state();
  const std::vector<std::uint8_t> bytes = lmf::robot_agent::encode_agent_state(state);
  expect_equal(lmf::robot_agent::decode_agent_state(bytes), state);
  AgentState fresh;  // before the first scan: no origin, nothing shipped
  expect_equal(lmf::robot_agent::decode_agent_state(lmf::robot_agent::encode_agent_state(fresh)), fresh);

  // Every byte changed (CRC-32 catches every error burst up to 32 bits).
  int detected = 0;
  for (std::size_t i = 0; i < bytes.size(); ++i) {
    std::vector<std::uint8_t> bad = bytes;
    bad[i] ^= static_cast<std::uint8_t>(0x01 + (i % 255));
    EXPECT_THROW(lmf::robot_agent::decode_agent_state(bad), AgentStateError) << "byte " << i;
    ++detected;
  }
  EXPECT_EQ(detected, static_cast<int>(bytes.size()));
  // Every truncation, and a byte too many.
  for (std::size_t n = 0; n < bytes.size(); ++n) {
    const std::vector<std::uint8_t> cut(bytes.begin(), bytes.begin() + static_cast<std::ptrdiff_t>(n));
    EXPECT_THROW(lmf::robot_agent::decode_agent_state(cut), AgentStateError) << n << " bytes";
  }
  std::vector<std::uint8_t> longer = bytes;
  longer.push_back(0);
  EXPECT_THROW(lmf::robot_agent::decode_agent_state(longer), AgentStateError);

  // Well framed but inconsistent: another robot's map, a map from the future,
  // a local map past 0 without an origin.
  AgentState foreign = state;
  foreign.unacknowledged[4] = encoded_map(2, 4);
  EXPECT_THROW(lmf::robot_agent::decode_agent_state(lmf::robot_agent::encode_agent_state(foreign)), AgentStateError);
  AgentState future = state;
  future.unacknowledged.erase(4);
  future.unacknowledged[6] = encoded_map(3, 6);
  EXPECT_THROW(lmf::robot_agent::decode_agent_state(lmf::robot_agent::encode_agent_state(future)), AgentStateError);
  AgentState orphan = state;
  orphan.origin.reset();
  EXPECT_THROW(lmf::robot_agent::decode_agent_state(lmf::robot_agent::encode_agent_state(orphan)), AgentStateError);
}

TEST(AgentState, FilesAreReplacedAtomicallyAndBadOnesNamed) {
  TempDir dir("lmf-agent-state");
  const auto file = lmf::robot_agent::agent_state_file(dir.path(), 3);
  EXPECT_EQ(file.filename(), "agent3.state");
  EXPECT_FALSE(lmf::robot_agent::load_agent_state(file).has_value());

  AgentState state = sample_state();
  lmf::robot_agent::save_agent_state(file, state);
  auto loaded = lmf::robot_agent::load_agent_state(file);
  ASSERT_TRUE(loaded.has_value());
  expect_equal(*loaded, state);
  state.unacknowledged.erase(3);
  state.maps_acknowledged = 4;
  lmf::robot_agent::save_agent_state(file, state);
  loaded = lmf::robot_agent::load_agent_state(file);
  ASSERT_TRUE(loaded.has_value());
  expect_equal(*loaded, state);
  std::size_t files = 0;
  for (const auto& entry : std::filesystem::directory_iterator(dir.path())) {
    ++files;
    EXPECT_EQ(entry.path(), file) << "left behind: " << entry.path();
  }
  EXPECT_EQ(files, 1u);

  std::vector<std::uint8_t> bytes = read_bytes(file);
  bytes.resize(bytes.size() / 2);
  write_bytes(file, bytes);
  try {
    lmf::robot_agent::load_agent_state(file);
    ADD_FAILURE() << "a truncated file loaded";
  } catch (const AgentStateError& e) {
    EXPECT_NE(std::string(e.what()).find(file.string()), std::string::npos) << e.what();
  }
  EXPECT_THROW(lmf::robot_agent::save_agent_state(dir.path() / "missing" / "agent3.state", state), AgentStateError);
}

// ---- one agent, killed and restarted -------------------------------------------------------

// A bus with a probe of what agents publish; the agent itself comes and goes.
struct Rig : lmf::testing::AgentProbe {
  void send(std::int64_t seq) {
    rt::RobotScan s;
    s.robot_id = 0;
    s.seq = seq;
    s.scan = sim_scans().at(static_cast<std::size_t>(seq));
    bus.publish(channels.scan(0), rt::to_message(s));
  }
  void ack_map(std::int64_t seq, rt::LocalMapAck::Status status = rt::LocalMapAck::Status::kFused) {
    bus.publish(channels.local_map_ack(), rt::to_message(rt::LocalMapAck{1, 0, seq, status}));
  }
  std::vector<std::int64_t> transmitted_since(std::size_t first) const {
    std::vector<std::int64_t> seqs;
    for (std::size_t k = first; k < maps.size(); ++k) seqs.push_back(maps[k].seq);
    return seqs;
  }
};

TEST(AgentRestart, ResendsUnacknowledgedMapsAndContinuesFromThePersistedOrigin) {
  TempDir state_dir("lmf-agent-restart");
  AgentOptions options;
  options.robot_id = 0;
  options.local_map.ship_distance_m = 2.0;
  // No resend unless restarted, however slowly the scans go through (a
  // sanitizer build under load): the test sees each transmission.
  options.resend_interval = 10s;
  options.min_resend_interval = 10s;
  options.status_interval = 1s;
  options.max_seq_gap = 3;
  options.state_dir = state_dir.path();
  Rig rig;

  auto agent = std::make_unique<AgentNode>(rig.bus, rig.loop, options);
  EXPECT_FALSE(agent->counters().resumed);
  std::int64_t seq = 0;
  std::optional<std::int64_t> origin_seq;  // the scan that made map 1 ship: map 2's origin
  for (; seq < static_cast<std::int64_t>(sim_scans().size()) && !origin_seq; ++seq) {
    rig.send(seq);
    rig.drain();
    if (agent->counters().maps_shipped == 2) origin_seq = seq;
  }
  ASSERT_TRUE(origin_seq.has_value()) << "the mission is too short to ship two maps";
  rig.ack_map(0);
  rig.ack_map(1, rt::LocalMapAck::Status::kReceived);  // releases its scan's ack; map 1 stays unacknowledged
  rig.drain();
  const rt::ScanAck origin_ack = rig.acks.back();
  ASSERT_EQ(origin_ack.seq, *origin_seq);
  EXPECT_EQ(origin_ack.local_map_seq, 2);
  ASSERT_EQ(agent->unacknowledged_maps(), std::vector<std::int64_t>{1});
  const lmf::LocalMapSnapshot map1 = rig.maps.back();
  ASSERT_EQ(map1.seq, 1);
  for (int k = 0; k < 4; ++k, ++seq) {  // into map 2: lost with the process
    rig.send(seq);
    rig.drain();
  }
  ASSERT_EQ(agent->local_map().seq(), 2);
  ASSERT_GT(agent->local_map().num_segments(), 0u);
  EXPECT_GE(agent->counters().state_writes, 4);  // first scan, two ships, one ack
  EXPECT_EQ(agent->counters().state_write_failures, 0);

  agent.reset();  // kill: nothing is written on the way out
  ASSERT_TRUE(std::filesystem::exists(lmf::robot_agent::agent_state_file(state_dir.path(), 0)));
  const std::size_t sent_before = rig.maps.size();
  agent = std::make_unique<AgentNode>(rig.bus, rig.loop, options);
  rig.drain();
  EXPECT_TRUE(agent->counters().resumed);
  EXPECT_EQ(agent->local_map().seq(), 2);
  EXPECT_EQ(agent->local_map().num_segments(), 0u);
  EXPECT_EQ(agent->next_scan_seq(), *origin_seq + 1);
  EXPECT_EQ(agent->counters().maps_shipped, 2);
  EXPECT_EQ(agent->counters().maps_acknowledged, 1);
  // Map 1 goes out again at once, the same bytes; map 0 (acked) does not.
  ASSERT_EQ(rig.transmitted_since(sent_before), std::vector<std::int64_t>{1});
  const lmf::LocalMapSnapshot& resent = rig.maps.back();
  EXPECT_TRUE(lmf::is_near(resent.x_LR, map1.x_LR, 0.0, 0.0));
  EXPECT_EQ(resent.segments.size(), map1.segments.size());
  EXPECT_TRUE(lmf::testing::matrices_near(resent.covariance, map1.covariance, 0.0));

  // The player resends the origin scan (its ack was lost with the process):
  // re-acked as before, not reprocessed.
  const std::size_t acks_before = rig.acks.size();
  rig.send(*origin_seq);
  rig.drain();
  ASSERT_EQ(rig.acks.size(), acks_before + 1);
  EXPECT_EQ(rig.acks.back().seq, origin_ack.seq);
  EXPECT_EQ(rig.acks.back().local_map_seq, origin_ack.local_map_seq);
  EXPECT_TRUE(lmf::is_near(rig.acks.back().x_LR, origin_ack.x_LR, 0.0, 0.0));
  EXPECT_EQ(agent->counters().scans_duplicate, 1);

  // The scan the player was waiting for, further ahead than max_seq_gap: the
  // robot starts map 2 at the odometric displacement from the origin, with the
  // odometry noise of that displacement (the new map has no segment yet to correct it).
  const std::int64_t awaited = *origin_seq + 8;
  rig.send(awaited);
  rig.drain();
  ASSERT_EQ(rig.acks.size(), acks_before + 2);
  const rt::ScanAck& first = rig.acks.back();
  EXPECT_EQ(first.seq, awaited);
  EXPECT_EQ(first.local_map_seq, 2);
  const Pose2 u = lmf::between(sim_scans().at(static_cast<std::size_t>(*origin_seq)).odometry,
                               sim_scans().at(static_cast<std::size_t>(awaited)).odometry);
  EXPECT_TRUE(lmf::is_near(first.x_LR, u, 1e-9, 1e-9))
      << first.x_LR.x << " " << first.x_LR.y << " " << first.x_LR.phi << " vs " << u.x << " " << u.y << " " << u.phi;
  const auto pj = lmf::local_map::prediction_jacobians(Pose2(), u);
  const Eigen::Matrix3d Q = lmf::local_map::odometry_noise(u, options.local_map);
  EXPECT_TRUE(lmf::testing::matrices_near(first.covariance, pj.J_u * Q * pj.J_u.transpose(), 1e-9));
  EXPECT_EQ(agent->counters().scans_missed, 7);
  EXPECT_EQ(agent->rejects().total(), 0);
  // From then on the gap limit holds again.
  rig.send(awaited + 5);
  rig.drain();
  EXPECT_EQ(agent->rejects().count(rt::RejectReason::kOutOfRange), 1);

  // Map 2 ships with its origin at the persisted scan and its first pose at the awaited one.
  rig.ack_map(1);
  rig.drain();
  EXPECT_TRUE(agent->unacknowledged_maps().empty());
  std::int64_t next = awaited + 1;
  while (agent->counters().maps_shipped < 3 && next < static_cast<std::int64_t>(sim_scans().size())) {
    rig.send(next++);
    rig.drain();
  }
  ASSERT_EQ(agent->counters().maps_shipped, 3);
  const lmf::LocalMapSnapshot& map2 = rig.maps.back();
  ASSERT_EQ(map2.seq, 2);
  EXPECT_EQ(map2.first_utime, sim_scans().at(static_cast<std::size_t>(*origin_seq)).utime);
  ASSERT_FALSE(map2.scan_poses.empty());
  EXPECT_EQ(map2.scan_poses.front().utime, sim_scans().at(static_cast<std::size_t>(awaited)).utime);

  // A second restart: map 1 was acked (not resent), map 2 is not.
  agent.reset();
  const std::size_t sent_before_second = rig.maps.size();
  agent = std::make_unique<AgentNode>(rig.bus, rig.loop, options);
  rig.drain();
  EXPECT_EQ(rig.transmitted_since(sent_before_second), std::vector<std::int64_t>{2});
  EXPECT_EQ(agent->local_map().seq(), 3);
  EXPECT_EQ(agent->counters().maps_acknowledged, 2);
}

TEST(AgentRestart, UntrustedStateStopsTheAgent) {
  TempDir state_dir("lmf-agent-restart-bad");
  AgentOptions options;
  options.robot_id = 0;
  options.state_dir = state_dir.path();
  Rig rig;
  {
    AgentNode agent(rig.bus, rig.loop, options);
    rig.send(0);
    rig.drain();
    ASSERT_EQ(agent.counters().state_writes, 1);
  }
  const auto file0 = lmf::robot_agent::agent_state_file(state_dir.path(), 0);
  // Another robot's state under robot 1's name.
  std::filesystem::copy_file(file0, lmf::robot_agent::agent_state_file(state_dir.path(), 1));
  AgentOptions other = options;
  other.robot_id = 1;
  EXPECT_THROW(AgentNode(rig.bus, rig.loop, other), AgentStateError);
  // A damaged file.
  std::vector<std::uint8_t> bytes = read_bytes(file0);
  bytes[bytes.size() / 2] ^= 0x40;
  write_bytes(file0, bytes);
  EXPECT_THROW(AgentNode(rig.bus, rig.loop, options), AgentStateError);
  // A state folder that cannot be made.
  AgentOptions unusable = options;
  unusable.state_dir = file0 / "sub";
  EXPECT_THROW(AgentNode(rig.bus, rig.loop, unusable), AgentStateError);
}

// Killed after the mission end with the last map unacknowledged: the restarted
// agent knows the mission ended, resends that map and is done once it is acked.
TEST(AgentRestart, AfterTheMissionEndTheLastMapIsStillDelivered) {
  TempDir state_dir("lmf-agent-restart-end");
  AgentOptions options;
  options.robot_id = 0;
  options.resend_interval = 10s;
  options.state_dir = state_dir.path();
  Rig rig;
  auto agent = std::make_unique<AgentNode>(rig.bus, rig.loop, options);
  for (std::int64_t seq = 0; seq < 10; ++seq) rig.send(seq);
  rig.bus.publish(rig.channels.mission_end(), rt::to_message(rt::MissionEnd{1, {0}}).value());
  rig.drain();
  ASSERT_TRUE(agent->mission_ended());
  ASSERT_EQ(agent->unacknowledged_maps(), std::vector<std::int64_t>{0});
  agent.reset();

  const std::size_t sent_before = rig.maps.size();
  agent = std::make_unique<AgentNode>(rig.bus, rig.loop, options);
  rig.drain();
  EXPECT_TRUE(agent->mission_ended());
  EXPECT_FALSE(agent->mission_done());
  EXPECT_EQ(rig.transmitted_since(sent_before), std::vector<std::int64_t>{0});
  EXPECT_EQ(agent->local_map().seq(), 1);
  rig.ack_map(0);
  rig.drain();
  EXPECT_TRUE(agent->mission_done());
}

// The crash tests' hook: after the given scan the agent is deaf, as if hung.
TEST(AgentRestart, StallHookStopsReactingAfterTheGivenScan) {
  AgentOptions options;
  options.robot_id = 0;
  options.test_stall_after_scan = 2;
  Rig rig;
  AgentNode agent(rig.bus, rig.loop, options);
  for (std::int64_t seq = 0; seq < 5; ++seq) rig.send(seq);
  rig.drain();
  EXPECT_TRUE(agent.stalled());
  ASSERT_EQ(rig.acks.size(), 3u);
  EXPECT_EQ(rig.acks.back().seq, 2);
  EXPECT_EQ(agent.counters().scans_processed, 3);
  options.test_stall_after_scan = -1;
  EXPECT_THROW(AgentNode(rig.bus, rig.loop, options), std::invalid_argument);
}

// ---- a mission with one agent killed and restarted --------------------------------------------

TEST(AgentRestart, LockstepMissionCompletesWithNothingLost) {
  TempDir dir("lmf-agent-restart-mission");
  lmf::testing::write_sim_mission(dir.path() / "sim", 60.0, 3, 2);
  lmf::mission::MissionConfig config;
  config.local_map.ship_distance_m = 4.0;  // several local maps in a short mission
  const lmf::mission::MissionInputs inputs = lmf::mission::load_sim_folder(dir.path() / "sim", config.sighting_noise);
  ASSERT_EQ(inputs.robots.size(), 2u);
  constexpr int kVictim = 1;

  rt::Bus bus("memq://");
  rt::EventLoop loop(bus, rt::EventLoopOptions{false});
  lmf::testing::FakeServer server(bus, config.global_map, rt::Channels());
  lmf::mission::TrajectoryBook book;     // what the server received, for the final trajectories
  bus.subscribe(rt::Channels().local_map(), [&](const std::string&, const void* d, std::size_t n) {
    auto map = rt::decode<lmf::LocalMapSnapshot>(d, n);
    ASSERT_TRUE(map.ok());
    book.add(map.value());
  });
  std::set<std::int64_t> acked_before_kill;  // FUSED / DUPLICATE / QUEUED seen by anyone for the victim
  bool killed = false;
  bus.subscribe(rt::Channels().local_map_ack(), [&](const std::string&, const void* d, std::size_t n) {
    auto ack = rt::decode<rt::LocalMapAck>(d, n);
    ASSERT_TRUE(ack.ok());
    if (ack.value().robot_id == kVictim && !killed) acked_before_kill.insert(ack.value().seq);
  });

  auto agent_options = [&](int robot_id) {
    AgentOptions options;
    options.robot_id = robot_id;
    options.local_map = config.local_map;
    options.resend_interval = 100ms;
    options.state_dir = dir.path() / "state";
    return options;
  };
  // The victim's first life, deterministic: it goes deaf (as hung) after 60 %
  // of its scans, and its map transmissions are lost with a seeded 50 % and no
  // resend is due (seed 3: the first gets through, the second is dropped; the
  // scan that shipped it is acked after a short hold), so it dies mid-map with
  // a map acknowledged and one the server never received.
  const auto& victim_scans = inputs.robots.at(kVictim).scans;
  AgentOptions first_life = agent_options(kVictim);
  first_life.test_stall_after_scan = static_cast<std::int64_t>(victim_scans.size() * 3 / 5);
  first_life.drop_local_maps = 0.5;
  first_life.drop_seed = 3;
  first_life.resend_interval = 600s;
  first_life.min_resend_interval = 600s;
  first_life.ack_hold = 50ms;
  std::map<int, std::unique_ptr<AgentNode>> agents;
  for (const auto& robot : inputs.robots) {
    agents[robot.robot_id] = std::make_unique<AgentNode>(
        bus, loop, robot.robot_id == kVictim ? first_life : agent_options(robot.robot_id));
  }
  lmf::log_player::PlayerOptions player_options;
  player_options.lockstep = true;
  player_options.ack_timeout = 200ms;
  player_options.max_attempts = 100;
  player_options.mission_end_interval = 20ms;
  player_options.mission_end_repeats = 3;
  lmf::log_player::PlayerNode player(bus, loop, inputs, player_options);
  player.start();

  ASSERT_TRUE(run_until(loop, [&] { return agents.at(kVictim)->stalled(); }, 60s)) << player.summary();
  EXPECT_GT(agents.at(kVictim)->local_map().span_m(), 0.5) << "the kill is meant to land mid-map";
  EXPECT_GE(agents.at(kVictim)->counters().maps_acknowledged, 1);
  const std::int64_t shipped_at_kill = agents.at(kVictim)->counters().maps_shipped;
  const std::int64_t scans_at_kill = agents.at(kVictim)->next_scan_seq();
  const std::vector<std::int64_t> unacked_at_kill = agents.at(kVictim)->unacknowledged_maps();
  agents.at(kVictim).reset();
  killed = true;
  loop.run_for(700ms);  // the player resends the awaited scan to nobody
  EXPECT_GE(player.counters().scan_resends, 2);
  agents[kVictim] = std::make_unique<AgentNode>(bus, loop, agent_options(kVictim));
  EXPECT_TRUE(agents.at(kVictim)->counters().resumed);

  const auto all_done = [&] {
    if (!player.finished()) return false;
    for (const auto& [id, a] : agents) {
      if (!a->mission_done()) return false;
    }
    return true;
  };
  ASSERT_TRUE(run_until(loop, all_done, 90s)) << player.summary();
  loop.run_for(50ms);

  const auto& pc = player.counters();
  EXPECT_EQ(pc.scans_given_up, 0);
  EXPECT_EQ(pc.scans_acked, pc.scans_total);
  const AgentNode& victim = *agents.at(kVictim);
  std::printf("robot %d killed after %lld scans, %lld maps shipped, %zu unacknowledged; restarted: %lld scans "
              "bridged by odometry, %lld maps shipped in all\n",
              kVictim, static_cast<long long>(scans_at_kill), static_cast<long long>(shipped_at_kill),
              unacked_at_kill.size(), static_cast<long long>(victim.counters().scans_missed),
              static_cast<long long>(victim.counters().maps_shipped));
  EXPECT_FALSE(unacked_at_kill.empty());
  EXPECT_GT(victim.counters().maps_shipped, shipped_at_kill);
  // Every map of every robot fused exactly once, seqs 0..shipped-1 without a hole.
  std::int64_t shipped = 0;
  for (const auto& [id, a] : agents) {
    const auto& c = a->counters();
    EXPECT_EQ(c.maps_acknowledged, c.maps_shipped) << "robot " << id;
    EXPECT_EQ(c.ship_failures, 0);
    EXPECT_EQ(c.state_write_failures, 0);
    for (std::int64_t seq = 0; seq < c.maps_shipped; ++seq) {
      const auto it = server.fused().find({id, seq});
      ASSERT_NE(it, server.fused().end()) << "robot " << id << " map " << seq << " not fused";
      EXPECT_EQ(it->second, 1) << "robot " << id << " map " << seq;
    }
    shipped += c.maps_shipped;
  }
  EXPECT_EQ(static_cast<std::int64_t>(server.fused().size()), shipped) << "no other map was fused";
  EXPECT_EQ(server.map().queued_count(), 0);
  EXPECT_EQ(server.rejected(), 0);
  for (const std::int64_t seq : acked_before_kill) {
    EXPECT_EQ(server.fused().count({kVictim, seq}), 1u) << "acked map " << seq << " lost";
  }

  // Robot 1's final trajectory against the simulator's truth, next to the
  // uninterrupted run's (lmf-offline equals a lockstep run).
  lmf::mission::OfflineMission offline(config, lmf::testing::as_sent(inputs));
  const lmf::mission::MissionResult expected = offline.run();
  const auto ate = [&](const std::vector<lmf::StampedPose>& trajectory) {
    return lmf::eval::absolute_trajectory_error(
        lmf::eval::associate_by_time(trajectory, inputs.reference.at(kVictim)));
  };
  const auto restarted = ate(book.final_trajectory(server.map(), kVictim));
  const auto uninterrupted = ate(expected.robots.at(kVictim).trajectory);
  std::printf("robot %d ATE: restarted %.3f m over %zu poses, uninterrupted %.3f m over %zu poses\n", kVictim,
              restarted.position_rmse_m, restarted.count, uninterrupted.position_rmse_m, uninterrupted.count);
  EXPECT_EQ(restarted.count + static_cast<std::size_t>(victim.counters().scans_missed), uninterrupted.count)
      << "every scan processed has its pose; the bridged ones have none";
  EXPECT_LT(restarted.position_rmse_m, 3.0 * uninterrupted.position_rmse_m + 0.1);
}

}  // namespace
