// Authenticated messages end to end, in one process over
// memq://: the real lmf-server node, two lmf-agents and lmf-player (lockstep)
// each sign and verify with their own keys file (as lmf-keygen writes them),
// each on its own Bus endpoint of one shared memq:// "network". While the
// mission runs, attackers inject
//   (a) an unsigned local map,
//   (b) a local map signed as the robot but with a wrong key,
//   (c) robot 1, with its genuine key, publishing a local map for robot 0,
//   (d) a genuine local map captured on the wire and replayed verbatim,
//   (e) an unsigned local-map ack and (f) one signed by the player,
// and none of them is applied: the server node never sees them, each is
// counted under its reason, and the mission's result is lmf-offline's. The
// forged map (a) IS taken by a server without keys (the attack is real).
#include <chrono>
#include <cstdint>
#include <map>
#include <memory>
#include <optional>
#include <string>
#include <tuple>
#include <vector>

#include <gtest/gtest.h>

#include "fusion_server/server_node.hpp"
#include "lmf/mission/mission_inputs.hpp"
#include "lmf/mission/offline_mission.hpp"
#include "log_player/player_node.hpp"
#include "player_test_support.hpp"
#include "robot_agent/agent_node.hpp"
#include "runtime/auth.hpp"
#include "runtime/bus.hpp"
#include "runtime/event_loop.hpp"
#include "system_test_support.hpp"

namespace {

using namespace std::chrono_literals;
namespace rt = lmf::runtime;
namespace auth = lmf::runtime::auth;
using Bytes = std::vector<std::uint8_t>;
using rt::RejectReason;

auth::Config config_of(const std::map<std::string, auth::KeyRing>& files, const std::string& principal) {
  return auth::Config{principal, std::make_shared<const auth::KeyRing>(files.at(principal))};
}

// A local map as found on the wire (payload + trailer), with a new seq.
Bytes with_seq(const Bytes& wire, std::int64_t seq) {
  auto map = rt::decode_message<lmf::local_map_t>(wire.data(), auth::unverified_payload_size(wire.data(), wire.size()));
  EXPECT_TRUE(map.ok());
  map.value().seq = seq;
  return rt::encode_message(map.value());
}

std::int64_t count(const rt::Bus& bus, RejectReason reason) { return bus.rejects().count(reason); }

TEST(SecureMission, ForgedAndReplayedMessagesAreNotApplied) {
  lmf::testing::TempDir dir("lmf-secure-mission");
  const lmf::mission::MissionConfig config = lmf::testing::short_mission_config();
  const lmf::mission::MissionInputs inputs = lmf::testing::load_short_sim_mission(dir.path() / "sim", config);
  ASSERT_EQ(inputs.robots.size(), 2u);
  const int victim = inputs.robots[0].robot_id;  // joins at start: its maps are fused at once
  const int other = inputs.robots[1].robot_id;

  std::vector<int> robot_ids;
  for (const auto& robot : inputs.robots) robot_ids.push_back(robot.robot_id);
  const auto files = auth::make_system_keys(robot_ids);
  ASSERT_EQ(files.at(auth::robot_principal(other)).find(auth::robot_principal(victim)), nullptr);

  // The wire, as an eavesdropper sees it: the victim's first local map.
  struct Capture {
    int robot_id;
    std::optional<Bytes> wire;
  } capture{victim, std::nullopt};  // declared before the network: outlives its LCM
  std::optional<Bytes>& captured = capture.wire;

  const rt::Channels channels;
  rt::Bus network("memq://");
  rt::EventLoop loop(network, rt::EventLoopOptions{false});
  rt::Bus server_bus(network, config_of(files, "server"));
  rt::Bus player_bus(network, config_of(files, "player"));
  rt::Bus monitor_bus(network, config_of(files, "monitor"));
  std::map<int, std::unique_ptr<rt::Bus>> agent_bus;
  for (const int id : robot_ids) {
    agent_bus[id] = std::make_unique<rt::Bus>(network, config_of(files, auth::robot_principal(id)));
  }
  rt::Bus unsigned_attacker(network, std::nullopt);
  auth::KeyRing wrong;
  wrong.add(auth::robot_principal(victim), auth::random_key());
  rt::Bus wrong_key_attacker(network, auth::Config{auth::robot_principal(victim),
                                                   std::make_shared<const auth::KeyRing>(wrong)});

  lmf::testing::AckCounts acks;  // verified by the monitor's keys
  monitor_bus.subscribe_message<lmf::local_map_ack_t>(channels.local_map_ack(),
                                                      [&](const std::string&, const lmf::local_map_ack_t& a) {
                                                        ++acks[{a.robot_id, a.seq, a.status}];
                                                      });
  network.lcm().subscribeFunction(
      channels.local_map(),
      +[](const lcm::ReceiveBuffer* b, const std::string&, Capture* into) {
        if (into->wire.has_value()) return;
        const auto* p = static_cast<const std::uint8_t*>(b->data);
        Bytes wire(p, p + b->data_size);
        const auto map = rt::decode_message<lmf::local_map_t>(
            wire.data(), auth::unverified_payload_size(wire.data(), wire.size()));
        if (map.ok() && map.value().robot_id == into->robot_id) into->wire = std::move(wire);
      },
      &capture);

  const lmf::server::ServerOptions server_options =
      lmf::testing::mission_server_options(config, victim, dir.path() / "server");
  lmf::server::ServerNode server(server_bus, loop, channels, server_options);
  std::vector<std::unique_ptr<lmf::robot_agent::AgentNode>> agents;
  for (const int id : robot_ids) {
    agents.push_back(std::make_unique<lmf::robot_agent::AgentNode>(*agent_bus[id], loop,
                                                                   lmf::testing::mission_agent_options(id, config)));
  }
  lmf::log_player::PlayerNode player(player_bus, loop, inputs, lmf::testing::lockstep_player_options());

  std::int64_t fusions_before_attack = -1;
  std::int64_t captured_seq = -1;
  int attack_timer = -1;
  attack_timer = loop.every(5ms, [&] {
    if (!captured || fusions_before_attack >= 0) return;
    const auto map = rt::decode_message<lmf::local_map_t>(
        captured->data(), auth::unverified_payload_size(captured->data(), captured->size()));
    ASSERT_TRUE(map.ok());
    captured_seq = map.value().seq;
    fusions_before_attack = server.view().fusion_count;
    // Never shipped in this mission: what the server would take as the victim's next maps.
    const Bytes forged = with_seq(*captured, captured_seq + 1000);
    ASSERT_TRUE(unsigned_attacker.publish_raw(channels.local_map(), forged));                 // (a)
    ASSERT_TRUE(wrong_key_attacker.publish_raw(channels.local_map(), forged));                // (b)
    ASSERT_TRUE(agent_bus[other]->publish_raw(channels.local_map(), with_seq(*captured, captured_seq + 2000)));  // (c)
    ASSERT_EQ(network.lcm().publish(channels.local_map(), captured->data(),
                                    static_cast<unsigned>(captured->size())), 0);             // (d)
    lmf::local_map_ack_t ack{};
    ack.robot_id = victim;
    ack.seq = captured_seq + 1;  // "your next map is fused": the agent would stop resending it
    ack.status = lmf::local_map_ack_t::FUSED;
    ASSERT_TRUE(unsigned_attacker.publish(channels.local_map_ack(), ack));                   // (e)
    ASSERT_TRUE(player_bus.publish(channels.local_map_ack(), ack));                          // (f)
    loop.cancel(attack_timer);
  });
  player.start();

  const auto all_done = [&] { return lmf::testing::mission_finished(player, agents, server); };
  ASSERT_TRUE(lmf::testing::run_until(loop, all_done, 90s)) << player.summary();
  loop.run_for(50ms);
  ASSERT_GE(fusions_before_attack, 0) << "the attack never ran";

  // Every rejection where it belongs, with its reason.
  EXPECT_EQ(count(server_bus, RejectReason::kAuthMissing), 1);        // (a)
  EXPECT_EQ(count(server_bus, RejectReason::kAuthBadTag), 1);         // (b)
  EXPECT_EQ(count(server_bus, RejectReason::kAuthNotAllowed), 1);     // (c)
  EXPECT_EQ(count(server_bus, RejectReason::kAuthReplayed), 1);       // (d)
  EXPECT_EQ(count(server_bus, RejectReason::kAuthUnknownSender), 0);
  EXPECT_EQ(server_bus.rejects().total(), 4);
  for (const int id : robot_ids) {
    EXPECT_EQ(count(*agent_bus[id], RejectReason::kAuthMissing), 1) << "robot " << id;     // (e)
    EXPECT_EQ(count(*agent_bus[id], RejectReason::kAuthNotAllowed), 1) << "robot " << id;  // (f)
    EXPECT_EQ(agent_bus[id]->rejects().total(), 2) << "robot " << id;
    EXPECT_GT(agent_bus[id]->messages_verified(), 0);
  }
  EXPECT_EQ(player_bus.rejects().total(), 0);
  EXPECT_EQ(count(monitor_bus, RejectReason::kAuthMissing), 1);
  EXPECT_EQ(count(monitor_bus, RejectReason::kAuthNotAllowed), 1);
  // The server node never saw a forged message: nothing unknown or undecodable.
  // (A genuine resend that crossed its ack, which a loaded machine makes more
  // likely, is answered DUPLICATE and counted stale_sequence.)
  EXPECT_EQ(server.rejects().total() - server.rejects().count(RejectReason::kStaleSequence), 0) << [&] {
    std::string reasons;
    for (const auto& [name, n] : server.rejects().nonzero()) reasons += " " + name + " " + std::to_string(n);
    return reasons;
  }();
  EXPECT_EQ(acks.count({victim, captured_seq + 1000, lmf::local_map_ack_t::FUSED}), 0u);
  EXPECT_EQ(acks.count({victim, captured_seq + 1000, lmf::local_map_ack_t::QUEUED}), 0u);

  // The genuine mission completed as if nothing happened.
  const std::int64_t shipped = lmf::testing::expect_each_map_fused_once(agents, acks);
  EXPECT_GT(captured_seq + 1, 0);
  EXPECT_EQ(server.view().fusion_count, shipped);
  ASSERT_TRUE(server.shutdown(false));
  const lmf::fusion::GlobalMap* map = server.map_after_shutdown();
  ASSERT_NE(map, nullptr);
  lmf::mission::OfflineMission offline(config, lmf::testing::as_sent(inputs));
  const lmf::mission::MissionResult expected = offline.run();
  EXPECT_EQ(server.view().fusion_count, static_cast<std::int64_t>(expected.fusions.size()));
  EXPECT_EQ(map->counts().segments, offline.global_map().counts().segments);
  // The same frames as lmf-offline (as in ServerMission).
  lmf::testing::expect_frames_as_offline(*map, offline.global_map(), 1e-9, 1e-9);

  // Control: the same unsigned forgery (a) is taken by a server without keys.
  rt::Bus open_network("memq://");
  rt::EventLoop open_loop(open_network, rt::EventLoopOptions{false});
  lmf::server::ServerOptions open_options = server_options;
  open_options.out_dir = dir.path() / "open-server";
  lmf::server::ServerNode open_server(open_network, open_loop, channels, open_options);
  rt::Bus open_attacker(open_network, std::nullopt);
  std::vector<std::int8_t> open_acks;
  open_network.subscribe_message<lmf::local_map_ack_t>(
      channels.local_map_ack(), [&](const std::string&, const lmf::local_map_ack_t& a) {
        if (a.status != lmf::local_map_ack_t::RECEIVED) open_acks.push_back(a.status);  // the final answer
      });
  ASSERT_TRUE(open_attacker.publish_raw(channels.local_map(), with_seq(*captured, captured_seq + 1000)));
  ASSERT_TRUE(lmf::testing::run_until(open_loop, [&] { return !open_acks.empty() && !open_server.worker_busy(); }, 10s));
  EXPECT_TRUE(open_acks.front() == lmf::local_map_ack_t::FUSED || open_acks.front() == lmf::local_map_ack_t::QUEUED)
      << "status " << int{open_acks.front()};
  EXPECT_EQ(open_server.rejects().total(), 0);
  open_server.shutdown(false);
}

}  // namespace
