// lmf-server: the fusion server process (docs/design.md §1, §5, §7). Parses flags,
// loads the global_map section of a mission config, runs ServerNode on the
// event loop; SIGUSR1 writes the outputs now, SIGINT/SIGTERM finish the
// fusion in progress, write them and exit 0. With --replay CAPTURE it fuses an
// lcm-logger capture's local maps and sightings on a private memq:// bus
// instead (fusion_server/capture_replay.hpp), writes the outputs and exits.
#include <csignal>
#include <iostream>
#include <optional>
#include <sstream>
#include <string>

#include <boost/asio/signal_set.hpp>
#include <boost/program_options.hpp>

#include "fusion_server/capture_replay.hpp"
#include "fusion_server/server_node.hpp"
#include "lmf/mission/config_file.hpp"
#include "runtime/bus.hpp"
#include "runtime/event_loop.hpp"
#include "runtime/options.hpp"

namespace po = boost::program_options;

namespace {

int replay_capture_and_exit(const char* program, const std::string& capture, const lmf::runtime::CommonOptions& common,
                            const lmf::server::ServerOptions& options) {
  lmf::runtime::Bus bus("memq://", lmf::runtime::auth_config_or_exit(common, "server", program));
  lmf::runtime::EventLoop loop(bus, lmf::runtime::EventLoopOptions{false});
  const lmf::runtime::Channels channels(common.channel_prefix);
  try {
    lmf::server::ServerNode node(bus, loop, channels, options);
    const lmf::server::CaptureReplayStats stats = lmf::server::replay_capture(capture, bus, loop, node, channels);
    const bool written = node.shutdown(true);
    std::cerr << program << ": replayed " << capture << ": " << stats.events << " events, " << stats.local_maps
              << " local maps and " << stats.sightings << " sightings fed; " << node.view().fusion_count
              << " fusions, " << node.stats().acks_duplicate << " duplicates; outputs "
              << (written ? "written to " : "NOT written to ") << options.out_dir << '\n';
    if (stats.unread_bytes > 0) {
      std::cerr << program << ": the last " << stats.unread_bytes
                << " bytes of the capture are not a complete event (cut short?) and were not read\n";
    }
    for (const auto& [reason, count] : node.reject_counts()) {
      std::cerr << "  rejected (" << reason << "): " << count << '\n';
    }
    return written ? 0 : 1;
  } catch (const std::exception& e) {
    lmf::runtime::exit_with_error(program, e.what());
  }
}

}  // namespace

int main(int argc, char** argv) {
  constexpr const char* kProgram = "lmf-server";
  lmf::runtime::CommonOptions common;
  lmf::server::ServerOptions options;
  std::string config_file;
  std::string out_dir = options.out_dir.string();
  int first_robot = 0;
  int queue_capacity = static_cast<int>(options.queue_capacity);
  int status_ms = static_cast<int>(options.status_interval.count());
  int frames_ms = static_cast<int>(options.frames_interval.count());
  int map_ms = static_cast<int>(options.map_interval.count());
  int write_s = 0;
  std::string state_dir;
  int snapshot_ms = static_cast<int>(options.snapshot_interval.count());
  std::string state_test_pause;
  std::string replay;

  po::options_description description("Options");
  description.add_options()
      ("config", po::value<std::string>(&config_file),
       "mission config JSON; its global_map section configures the fusion (default: built-in defaults)")
      ("out", po::value<std::string>(&out_dir)->default_value(out_dir),
       "folder for map.json, map.svg, trajectory.txt, trajectories/robotN.txt, report.json")
      ("map-graph", po::bool_switch(&options.map_svg_graph),
       "draw the environment graph (submap nodes, consecutive and paired edges) in map.svg")
      ("first-robot", po::value<int>(&first_robot)->default_value(first_robot),
       "robot that joins at start with L = W; -1: the first local map received defines W")
      ("max-robots", po::value<int>(&options.max_robots)->default_value(options.max_robots),
       "robot ids 0 .. N-1 are accepted; others are rejected as unknown_robot")
      ("queue-capacity", po::value<int>(&queue_capacity)->default_value(queue_capacity),
       "local maps waiting for the fusion worker; when full, new ones are not acked (agents resend)")
      ("status-interval-ms", po::value<int>(&status_ms)->default_value(status_ms), "server_status_t period, ms")
      ("frames-interval-ms", po::value<int>(&frames_ms)->default_value(frames_ms),
       "corrected_frames_t period, ms (also sent after each fusion)")
      ("map-interval-ms", po::value<int>(&map_ms)->default_value(map_ms),
       "global_map_t period, ms (also sent after fusions, at most every 250 ms)")
      ("write-interval-s", po::value<int>(&write_s)->default_value(write_s),
       "write the outputs every N s; 0: only on SIGUSR1 and at exit")
      ("state", po::value<std::string>(&state_dir),
       "durable state directory: snapshot + journal of every accepted local map and sighting (fsync'ed before "
       "it is acked); at start the snapshot is loaded and the journal replayed (default: no durable state)")
      ("snapshot-interval-ms", po::value<int>(&snapshot_ms)->default_value(snapshot_ms),
       "with --state: write a snapshot after a fusion once this long since the last one (and when idle); "
       "0: after every fusion and sighting")
      ("state-test-pause", po::value<std::string>(&state_test_pause),
       "testing only, K,MS: in the K-th snapshot this process writes (1: the one at start), sleep MS ms "
       "between syncing snapshot.tmp and renaming it (crash tests kill the server there)")
      ("replay", po::value<std::string>(&replay),
       "fuse the local maps and sightings of this lcm-logger capture, in its order, instead of listening (on a "
       "private memq:// bus: nothing is sent), write the outputs to --out and exit; e.g. to re-fuse a recorded "
       "mission with another --config");
  lmf::runtime::add_common_options(description, common);
  lmf::runtime::parse_options_or_exit(
      argc, argv, description, kProgram,
      "Fuses the robots' local maps (LMF_LOCAL_MAP, LMF_SIGHTING) into the global map in a background thread,\n"
      "acks them, publishes corrected frames, the map and its status. SIGUSR1 writes the outputs now;\n"
      "SIGINT/SIGTERM finish the fusion in progress, write them and exit.");

  try {
    if (!config_file.empty()) options.global_map = lmf::mission::load_mission_config(config_file).global_map;
    options.out_dir = out_dir;
    options.first_robot = first_robot < 0 ? std::nullopt : std::optional<int>(first_robot);
    if (queue_capacity < 1) throw std::invalid_argument("--queue-capacity must be >= 1");
    if (write_s < 0) throw std::invalid_argument("--write-interval-s must be >= 0");
    options.queue_capacity = static_cast<std::size_t>(queue_capacity);
    options.status_interval = std::chrono::milliseconds(status_ms);
    options.frames_interval = std::chrono::milliseconds(frames_ms);
    options.map_interval = std::chrono::milliseconds(map_ms);
    options.write_interval = std::chrono::seconds(write_s);
    options.state_dir = state_dir;
    if (snapshot_ms < 0) throw std::invalid_argument("--snapshot-interval-ms must be >= 0");
    options.snapshot_interval = std::chrono::milliseconds(snapshot_ms);
    if (!state_test_pause.empty()) {
      int at = 0;
      int ms = 0;
      char comma = 0;
      std::istringstream in(state_test_pause);
      if (!(in >> at >> comma >> ms) || comma != ',' || !in.eof() || at < 1 || ms < 0) {
        throw std::invalid_argument("--state-test-pause must be K,MS with K >= 1 and MS >= 0, got '" +
                                    state_test_pause + "'");
      }
      options.state_test_pause_at = at;
      options.state_test_pause = std::chrono::milliseconds(ms);
    }
    if (!replay.empty() && !state_dir.empty()) throw std::invalid_argument("--replay and --state exclude each other");
    if (!replay.empty() && !common.lcm_url.empty()) {
      throw std::invalid_argument("--replay runs on a private memq:// bus; --lcm-url does not apply");
    }
    options.validate();
  } catch (const std::exception& e) {
    lmf::runtime::exit_with_error(kProgram, e.what(), 2);
  }
  if (!replay.empty()) return replay_capture_and_exit(kProgram, replay, common, options);

  lmf::runtime::Bus bus(common.lcm_url, lmf::runtime::auth_config_or_exit(common, "server", kProgram));
  lmf::runtime::simulate_loss_or_exit(bus, common, kProgram);
  if (!bus.good()) lmf::runtime::exit_with_error(kProgram, "cannot open LCM at '" + bus.url() + "'");
  lmf::runtime::EventLoop loop(bus);
  std::optional<lmf::server::ServerNode> node;
  try {
    node.emplace(bus, loop, lmf::runtime::Channels(common.channel_prefix), options);
  } catch (const std::exception& e) {
    lmf::runtime::exit_with_error(kProgram, e.what());
  }

  boost::asio::signal_set usr1(loop.context(), SIGUSR1);
  std::function<void()> wait_usr1 = [&] {
    usr1.async_wait([&](const boost::system::error_code& error, int) {
      if (error) return;
      node->request_write();
      wait_usr1();
    });
  };
  wait_usr1();

  std::cerr << kProgram << ": running on " << (bus.url().empty() ? "LCM default URL" : bus.url()) << ", prefix '"
            << common.channel_prefix << "', output " << options.out_dir << '\n';
  loop.run();
  usr1.cancel();
  const bool written = node->shutdown(true);
  std::cerr << kProgram << ": stopped"
            << (loop.stopped_by_signal() ? " by signal " + std::to_string(*loop.stopped_by_signal()) : std::string())
            << "; " << node->view().fusion_count << " fusions, outputs " << (written ? "written to " : "NOT written to ")
            << options.out_dir << '\n';
  return written ? 0 : 1;
}
