// The whole system in one process over memq://: lmf-player (lockstep), two
// lmf-agents and the REAL lmf-server node (fusion in its worker thread) replay
// a short simulated mission; the final global map, corrected frames and
// trajectories must equal lmf-offline's on the same inputs (DESIGN §7: FIFO
// fusion in arrival order), and every local map is acked FUSED exactly once.
#include <chrono>
#include <cstdint>
#include <filesystem>
#include <fstream>
#include <map>
#include <memory>
#include <sstream>
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
#include "runtime/bus.hpp"
#include "runtime/event_loop.hpp"

namespace {

using namespace std::chrono_literals;
namespace rt = lmf::runtime;

TEST(ServerMission, LockstepReplayThroughTheServerEqualsOffline) {
  lmf::testing::TempDir dir("lmf-server-mission");
  lmf::testing::write_sim_mission(dir.path() / "sim", 60.0, 3, 2);
  lmf::mission::MissionConfig config;
  config.local_map.ship_distance_m = 4.0;  // several local maps in a short mission
  const lmf::mission::MissionInputs inputs =
      lmf::mission::load_sim_folder(dir.path() / "sim", config.sighting_noise);
  ASSERT_EQ(inputs.robots.size(), 2u);

  rt::Bus bus("memq://");
  rt::EventLoop loop(bus, rt::EventLoopOptions{false});
  std::map<std::tuple<int, std::int64_t, std::int8_t>, int> acks;  // (robot, seq, status) -> count
  bus.subscribe_message<lmf::local_map_ack_t>(rt::Channels().local_map_ack(),
                                              [&](const std::string&, const lmf::local_map_ack_t& a) {
                                                ++acks[{a.robot_id, a.seq, a.status}];
                                              });

  lmf::server::ServerOptions server_options;
  server_options.global_map = config.global_map;
  server_options.first_robot = inputs.robots.front().robot_id;
  server_options.out_dir = dir.path() / "server";
  lmf::server::ServerNode server(bus, loop, rt::Channels(), server_options);

  std::vector<std::unique_ptr<lmf::robot_agent::AgentNode>> agents;
  for (const auto& robot : inputs.robots) {
    lmf::robot_agent::AgentOptions options;
    options.robot_id = robot.robot_id;
    options.local_map = config.local_map;
    options.resend_interval = 200ms;
    agents.push_back(std::make_unique<lmf::robot_agent::AgentNode>(bus, loop, options));
  }
  lmf::log_player::PlayerOptions player_options;
  player_options.lockstep = true;
  player_options.ack_timeout = 2000ms;
  player_options.mission_end_interval = 20ms;
  player_options.mission_end_repeats = 3;
  lmf::log_player::PlayerNode player(bus, loop, inputs, player_options);
  player.start();

  const auto all_done = [&] {
    if (!player.finished()) return false;
    for (const auto& a : agents) {
      if (!a->mission_done()) return false;
    }
    return !server.worker_busy();
  };
  ASSERT_TRUE(lmf::testing::run_until(loop, all_done, 90s)) << player.summary();
  loop.run_for(50ms);

  std::int64_t shipped = 0;
  for (const auto& agent : agents) {
    const auto& c = agent->counters();
    EXPECT_EQ(c.maps_acknowledged, c.maps_shipped);
    for (std::int64_t seq = 0; seq < c.maps_shipped; ++seq) {
      EXPECT_EQ((acks[{agent->robot_id(), seq, lmf::local_map_ack_t::FUSED}]), 1)
          << "robot " << agent->robot_id() << " map " << seq;
    }
    shipped += c.maps_shipped;
  }
  EXPECT_EQ(server.view().fusion_count, shipped);
  EXPECT_EQ(server.reject_counts().size(), 0u);
  EXPECT_EQ(server.stats().deferred_queue_full, 0);

  ASSERT_TRUE(server.shutdown(true));
  const lmf::fusion::GlobalMap* map = server.map_after_shutdown();
  ASSERT_NE(map, nullptr);

  lmf::mission::OfflineMission offline(config, lmf::testing::as_sent(inputs));
  const lmf::mission::MissionResult expected = offline.run();
  EXPECT_EQ(server.view().fusion_count, static_cast<std::int64_t>(expected.fusions.size()));
  const auto counts = map->counts();
  const auto offline_counts = offline.global_map().counts();
  EXPECT_EQ(counts.segments, offline_counts.segments);
  EXPECT_EQ(counts.submaps, offline_counts.submaps);
  EXPECT_EQ(counts.graph_edges, offline_counts.graph_edges);
  EXPECT_EQ(counts.robots_joined, offline_counts.robots_joined);
  EXPECT_EQ(counts.state_dimension, offline_counts.state_dimension);
  for (const auto& frame : offline.global_map().corrected_frames()) {
    const auto ours = map->corrected_frame(frame.robot_id);
    ASSERT_TRUE(ours.has_value());
    EXPECT_EQ(ours->seq, frame.seq);
    // Same fusions in the same order; what remains is segment_t.length being a
    // float on the wire (lmf-offline keeps doubles): ~1e-7 m here.
    EXPECT_TRUE(lmf::is_near(ours->x_WL, frame.x_WL, 1e-5, 1e-6))
        << "robot " << frame.robot_id << ": " << ours->x_WL.x << " " << ours->x_WL.y << " " << ours->x_WL.phi
        << " vs offline " << frame.x_WL.x << " " << frame.x_WL.y << " " << frame.x_WL.phi;
  }
  // The written trajectories are the offline ones (scan poses travelled in local_map_t).
  for (const auto& r : expected.robots) {
    if (!r.joined) continue;
    const auto file = server_options.out_dir / "trajectories" / ("robot" + std::to_string(r.robot_id) + ".txt");
    ASSERT_TRUE(std::filesystem::exists(file)) << file;
    std::ifstream in(file);
    std::size_t i = 0;
    for (std::string line; std::getline(in, line);) {
      if (line.empty() || line[0] == '#') continue;
      std::istringstream fields(line);
      double t = 0, x = 0, y = 0, phi = 0;
      fields >> t >> x >> y >> phi;
      ASSERT_LT(i, r.trajectory.size());
      EXPECT_NEAR(x, r.trajectory[i].pose.x, 1e-5) << "robot " << r.robot_id << " pose " << i;
      EXPECT_NEAR(y, r.trajectory[i].pose.y, 1e-5) << "robot " << r.robot_id << " pose " << i;
      ++i;
    }
    EXPECT_EQ(i, r.trajectory.size()) << "robot " << r.robot_id;
  }
  for (const char* name : {"map.json", "map.svg", "trajectory.txt", "report.json"}) {
    EXPECT_TRUE(std::filesystem::exists(server_options.out_dir / name)) << name;
  }
}

}  // namespace
