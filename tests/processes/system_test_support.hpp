// Helpers of the whole-system tests in one process: the real lmf-server node,
// lmf-agents and a lockstep lmf-player on memq://, checked against lmf-offline.
#pragma once

#include <chrono>
#include <cstdint>
#include <filesystem>
#include <map>
#include <memory>
#include <tuple>
#include <vector>

#include <gtest/gtest.h>

#include "fusion_server/server_node.hpp"
#include "lmf/fusion/global_map.hpp"
#include "lmf/local_map_ack_t.hpp"
#include "lmf/mission/offline_mission.hpp"
#include "log_player/player_node.hpp"
#include "robot_agent/agent_node.hpp"

namespace lmf::testing {

// Local-map acks seen on the bus: (robot, seq, status) -> count.
using AckCounts = std::map<std::tuple<int, std::int64_t, std::int8_t>, int>;

// The server of a mission with `config`, robot `first_robot` joined at start.
inline server::ServerOptions mission_server_options(const mission::MissionConfig& config, int first_robot,
                                                    const std::filesystem::path& out_dir) {
  server::ServerOptions options;
  options.global_map = config.global_map;
  options.first_robot = first_robot;
  options.out_dir = out_dir;
  return options;
}

// The agent of robot `robot_id` in a mission with `config`, resending every 200 ms.
inline robot_agent::AgentOptions mission_agent_options(int robot_id, const mission::MissionConfig& config) {
  robot_agent::AgentOptions options;
  options.robot_id = robot_id;
  options.local_map = config.local_map;
  options.resend_interval = std::chrono::milliseconds(200);
  return options;
}

// A lockstep player ending the mission with three MISSION_ENDs 20 ms apart.
inline log_player::PlayerOptions lockstep_player_options() {
  log_player::PlayerOptions options;
  options.lockstep = true;
  options.ack_timeout = std::chrono::milliseconds(2000);
  options.mission_end_interval = std::chrono::milliseconds(20);
  options.mission_end_repeats = 3;
  return options;
}

// The player finished, every agent is done with the mission and the server is idle.
inline bool mission_finished(const log_player::PlayerNode& player,
                             const std::vector<std::unique_ptr<robot_agent::AgentNode>>& agents,
                             const server::ServerNode& server) {
  if (!player.finished()) return false;
  for (const auto& a : agents) {
    if (!a->mission_done()) return false;
  }
  return !server.worker_busy();
}

// Every local map each agent shipped was acknowledged and acked FUSED exactly
// once; returns how many maps the agents shipped.
inline std::int64_t expect_each_map_fused_once(const std::vector<std::unique_ptr<robot_agent::AgentNode>>& agents,
                                               const AckCounts& acks) {
  std::int64_t shipped = 0;
  for (const auto& agent : agents) {
    const auto& c = agent->counters();
    EXPECT_EQ(c.maps_acknowledged, c.maps_shipped);
    for (std::int64_t seq = 0; seq < c.maps_shipped; ++seq) {
      const auto it = acks.find({agent->robot_id(), seq, local_map_ack_t::FUSED});
      EXPECT_EQ(it == acks.end() ? 0 : it->second, 1) << "robot " << agent->robot_id() << " map " << seq;
    }
    shipped += c.maps_shipped;
  }
  return shipped;
}

// The corrected frames of `map` are lmf-offline's: same fusions in the same
// order; what remains is segment_t.length being a float on the wire
// (lmf-offline keeps doubles): ~1e-7 m here.
inline void expect_frames_as_offline(const fusion::GlobalMap& map, const fusion::GlobalMap& offline,
                                     double tolerance_m = 1e-5, double tolerance_rad = 1e-6) {
  for (const auto& frame : offline.corrected_frames()) {
    const auto ours = map.corrected_frame(frame.robot_id);
    ASSERT_TRUE(ours.has_value());
    EXPECT_EQ(ours->map_seq, frame.map_seq);
    EXPECT_TRUE(is_near(ours->x_WL, frame.x_WL, tolerance_m, tolerance_rad))
        << "robot " << frame.robot_id << ": " << ours->x_WL.x << " " << ours->x_WL.y << " " << ours->x_WL.phi
        << " vs offline " << frame.x_WL.x << " " << frame.x_WL.y << " " << frame.x_WL.phi;
  }
}

}  // namespace lmf::testing
