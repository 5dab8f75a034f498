// lmf-agent: one robot's local map over LCM (docs/design.md §1, §4). See --help and
// robot_agent/agent_node.hpp for the protocol.
#include <algorithm>
#include <chrono>
#include <cstdint>
#include <exception>
#include <iostream>
#include <limits>
#include <memory>
#include <sstream>
#include <string>

#include <boost/program_options.hpp>

#include "lmf/mission/config_file.hpp"
#include "lmf/mission/offline_mission.hpp"
#include "robot_agent/agent_node.hpp"
#include "runtime/bus.hpp"
#include "runtime/event_loop.hpp"
#include "runtime/options.hpp"

namespace po = boost::program_options;
namespace rt = lmf::runtime;

int main(int argc, char** argv) {
  constexpr const char* kProgram = "lmf-agent";
  rt::CommonOptions common;
  int robot_id = -1;
  std::string config_file;
  int resend_ms = 1000;
  int min_resend_ms = 5;
  int ack_hold_ms = 1000;
  double drop = 0.0;
  std::uint64_t drop_seed = 1;
  std::string state_dir;
  constexpr std::int64_t kUnset = std::numeric_limits<std::int64_t>::min();
  std::int64_t stall_after_scan = kUnset;
  po::options_description description("Options");
  rt::add_common_options(description, common);
  description.add_options()
      ("robot-id", po::value(&robot_id)->required(), "this robot's id (>= 0): listens on <prefix>SCAN_<id>")
      ("config", po::value(&config_file), "mission JSON config; its local_map section is used (default: built-in)")
      ("resend-interval-ms", po::value(&resend_ms)->default_value(resend_ms),
       "the longest wait before resending an unacknowledged local map, and the wait once the server\n"
       "answered RECEIVED")
      ("ack-hold-ms", po::value(&ack_hold_ms)->default_value(ack_hold_ms),
       "the ack of a scan that made a local map ship waits for the server's answer to that map, at most\n"
       "this many ms (so a lockstep player cannot let anything overtake the map; a server that is down\n"
       "costs this much per map)")
      ("min-resend-interval-ms", po::value(&min_resend_ms)->default_value(min_resend_ms),
       "the shortest resend wait (the wait follows the server's measured round trip in between;\n"
       "capped at --resend-interval-ms)")
      ("drop-local-maps", po::value(&drop)->default_value(drop),
       "for tests: drop this fraction in [0, 1) of local-map transmissions (first sends and resends)")
      ("drop-seed", po::value(&drop_seed)->default_value(drop_seed), "seed of the simulated loss")
      ("state", po::value(&state_dir),
       "folder of the persisted state (agent<id>.state, created if missing): written at each new local map\n"
       "origin, ship and ack; a restart on the same folder resends the unacknowledged maps and continues\n"
       "the chain of local maps (scans since the last ship are lost, bridged by odometry)")
      ("test-stall-after-scan", po::value(&stall_after_scan),
       "for crash tests: after acknowledging scan SEQ stop reacting to anything, as a hung process,\n"
       "so a test can kill -9 the agent at a known point of a lockstep replay");
  rt::parse_options_or_exit(argc, argv, description, kProgram,
                            "Runs one robot's EKF local map: scans in, local maps out (resent until acknowledged),\n"
                            "scan acks, corrected frames in, status every 200 ms.");

  lmf::robot_agent::AgentOptions options;
  try {
    if (!config_file.empty()) options.local_map = lmf::mission::load_mission_config(config_file).local_map;
    options.robot_id = robot_id;
    options.channels = rt::Channels(common.channel_prefix);
    options.resend_interval = std::chrono::milliseconds(resend_ms);
    options.min_resend_interval = std::min(std::chrono::milliseconds(min_resend_ms), options.resend_interval);
    options.ack_hold = std::chrono::milliseconds(ack_hold_ms);
    options.drop_local_maps = drop;
    options.drop_seed = drop_seed;
    options.state_dir = state_dir;
    if (stall_after_scan != kUnset) options.test_stall_after_scan = stall_after_scan;
    options.validate();
  } catch (const std::exception& e) {
    rt::exit_with_error(kProgram, e.what(), 2);
  }

  rt::Bus bus(common.lcm_url, rt::auth_config_or_exit(common, rt::auth::robot_principal(robot_id), kProgram));
  rt::simulate_loss_or_exit(bus, common, kProgram);
  if (!bus.good()) rt::exit_with_error(kProgram, "cannot open LCM at '" + bus.url() + "'");
  rt::EventLoop loop(bus);
  std::unique_ptr<lmf::robot_agent::AgentNode> node;
  try {
    node = std::make_unique<lmf::robot_agent::AgentNode>(bus, loop, options);  // loads --state
  } catch (const std::exception& e) {
    rt::exit_with_error(kProgram, e.what(), 2);
  }
  lmf::robot_agent::AgentNode& agent = *node;
  std::cerr << kProgram << " " << robot_id << ": listening on " << options.channels.scan(robot_id) << "\n";
  loop.run();
  agent.publish_status();
  const auto& c = agent.counters();
  const lmf::mission::TimingStats timing = lmf::mission::timing_stats(agent.scan_times_ms());
  std::ostringstream summary;  // one write, so agents sharing a terminal do not interleave
  summary << kProgram << " " << robot_id << ": stopped; " << c.scans_processed << " scans, " << c.maps_shipped
            << " local maps shipped, " << c.maps_acknowledged << " acknowledged, " << c.map_resends << " resends, "
            << agent.all_rejects().total() << " messages rejected"
            << (agent.mission_done() ? ", mission done" : agent.mission_ended() ? ", mission end received" : "")
            << "; " << c.scans_processed - c.scans_skipped << " scans taken (motion filter)"
            << "; scan matches " << c.scans_matched << "/" << c.scans_match_tried << " (" << c.scans_match_escalated
            << " searches escalated, " << c.scans_matched_from_escalation << " matched there); segments seen through "
            << c.segments_seen_through << "; per-scan time p50 " << timing.p50_ms << " ms, p99 " << timing.p99_ms << " ms, max " << timing.max_ms
            << " ms\n"
          << kProgram << " " << robot_id << ": odometry model: " << lmf::describe(agent.local_map().odometry_model())
          << " (" << agent.local_map().odometry_learning_stats().increments << " matched increments, "
          << agent.local_map().odometry_learning_stats().downweighted << " downweighted as glitches)\n"
          << kProgram << " " << robot_id << ": laser point noise: "
          << lmf::describe_point_noise(agent.local_map().config().scan_matching.point_sigma_m,
                                       agent.local_map().front_end().range_noise_per_m(),
                                       agent.local_map().front_end().range_noise_measured()
                                           ? agent.local_map().front_end().range_noise().matches()
                                           : 0)
          << "\n";
  const std::string bounds =
      lmf::describe_bounds(agent.local_map().odometry_model(), agent.local_map().odometry_learning_stats());
  if (!bounds.empty()) summary << kProgram << " " << robot_id << ": WARNING: " << bounds << "\n";
  std::cerr << summary.str() << std::flush;
  return 0;
}
