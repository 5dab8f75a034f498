// lmf-player: replays CARMEN logs, ROS bags or an lmf-sim folder as live robots over LCM
// (docs/design.md §1). See --help and log_player/player_node.hpp.
#include <unistd.h>

#include <chrono>
#include <cstdint>
#include <exception>
#include <filesystem>
#include <iostream>
#include <string>
#include <vector>

#include <boost/program_options.hpp>

#include "lmf/mission/config_file.hpp"
#include "lmf/mission/mission_inputs.hpp"
#include "log_player/player_node.hpp"
#include "tools/recording_options.hpp"
#include "runtime/bus.hpp"
#include "runtime/event_loop.hpp"
#include "runtime/options.hpp"

namespace po = boost::program_options;
namespace rt = lmf::runtime;

int main(int argc, char** argv) {
  constexpr const char* kProgram = "lmf-player";
  rt::CommonOptions common;
  lmf::tools::RecordingOptions recordings;
  int split = 1;
  std::string gt;
  std::string sim_dir;
  double rate = 1.0;
  int ack_timeout_ms = 2000;
  int min_ack_timeout_ms = 5;
  int max_attempts = 10;
  std::size_t max_pending_sightings = 1000;
  int end_wait_ms = 0;
  std::uint64_t seed = 0;
  std::string config_file;
  int start_delay_ms = 500;
  po::options_description description("Options");
  rt::add_common_options(description, common);
  description.add_options()
      ("split", po::value(&split)->default_value(split),
       "cut the single --log or --bag into N contiguous parts replayed as N simultaneous robots")
      ("gt", po::value(&gt), "reference poses of the log(s): robots after the first join by a sighting at their start")
      ("sim", po::value(&sim_dir), "an lmf-sim output folder instead of --log")
      ("rate", po::value(&rate)->default_value(rate), "replay speed: log time / R (R > 0)")
      ("lockstep", "send one scan at a time in time order, each after the previous one was acknowledged")
      ("ack-timeout-ms", po::value(&ack_timeout_ms)->default_value(ack_timeout_ms),
       "lockstep: the longest wait before resending a scan not acknowledged (the wait follows the measured "
       "round trip, down to --min-ack-timeout-ms, doubles per resend, and starts at 200 ms before the first ack); "
       "rate: how long a sighting waits for acks; both: resend a sighting lmf-server has not answered within this time")
      ("min-ack-timeout-ms", po::value(&min_ack_timeout_ms)->default_value(min_ack_timeout_ms),
       "lockstep: the shortest wait before resending a scan (> 0; at most --ack-timeout-ms)")
      ("max-attempts", po::value(&max_attempts)->default_value(max_attempts),
       "lockstep: sends of one scan before going on without its ack; 0: no limit")
      ("max-pending-sightings", po::value(&max_pending_sightings)->default_value(max_pending_sightings),
       "sightings are resent until lmf-server answers, however long it is down; at most this many wait at once "
       "(beyond, the oldest is given up)")
      ("end-wait-ms", po::value(&end_wait_ms)->default_value(end_wait_ms),
       "after the last scan, how long sightings lmf-server has not answered may still wait before they are given "
       "up and the mission end is sent; 0: until answered")
      ("seed", po::value(&seed), "seed of the sighting noise (overrides the config's sighting_noise.seed)")
      ("config", po::value(&config_file), "mission JSON config; its sighting_noise section is used")
      ("start-delay-ms", po::value(&start_delay_ms)->default_value(start_delay_ms),
       "wait this long before the first scan (for subscribers to start)")
      ("no-sightings", "send no sightings (nor the start poses --gt gives as sightings): robots after the first "
                       "join only where a local map of theirs is placed without one")
      ("quiet", "no progress output");
  recordings.add_to(description);
  po::variables_map vm;
  rt::parse_options_or_exit(argc, argv, description, kProgram,
                            "Replays recorded or simulated robots over LCM: scans, sightings, then mission_end_t.\n"
                            "Give --log FILE... or --bag FILE... [--split N] [--gt FILE], or --sim DIR. With\n"
                            "--no-odometry the agents need local_map.scans_have_odometry false in their config.",
                            &vm);
  if (recordings.kinds_given() + (!sim_dir.empty()) != 1) {
    rt::exit_with_error(kProgram, "give exactly one of --log, --bag or --sim", 2);
  }
  if (!sim_dir.empty() && (vm["split"].as<int>() != 1 || !gt.empty())) {
    rt::exit_with_error(kProgram, "--split and --gt go with --log or --bag, not --sim", 2);
  }

  lmf::log_player::PlayerOptions options;
  lmf::mission::MissionInputs inputs;
  try {
    lmf::mission::MissionConfig config =
        config_file.empty() ? lmf::mission::MissionConfig{} : lmf::mission::load_mission_config(config_file);
    if (vm.count("seed") != 0u) config.sighting_noise.seed = seed;
    recordings.finish(vm);
    inputs = sim_dir.empty() ? lmf::mission::load_recordings(recordings.read(), split, gt, config.sighting_noise)
                             : lmf::mission::load_sim_folder(sim_dir, config.sighting_noise);
    if (vm.count("no-sightings") != 0u) lmf::mission::drop_sightings(inputs);
    options.channels = rt::Channels(common.channel_prefix);
    options.lockstep = vm.count("lockstep") != 0u;
    options.rate = rate;
    options.ack_timeout = std::chrono::milliseconds(ack_timeout_ms);
    options.min_ack_timeout = std::chrono::milliseconds(min_ack_timeout_ms);
    options.max_attempts = max_attempts;
    options.max_pending_sightings = max_pending_sightings;
    options.end_wait = std::chrono::milliseconds(end_wait_ms);
    options.start_delay = std::chrono::milliseconds(start_delay_ms);
    if (vm.count("quiet") == 0u) {
      options.progress = ::isatty(STDERR_FILENO) != 0 ? lmf::log_player::PlayerOptions::Progress::kLine
                                                      : lmf::log_player::PlayerOptions::Progress::kSteps;
      options.progress_stream = &std::cerr;
    }
    options.validate();
  } catch (const std::exception& e) {
    rt::exit_with_error(kProgram, e.what(), 2);
  }

  rt::Bus bus(common.lcm_url, rt::auth_config_or_exit(common, "player", kProgram));
  rt::simulate_loss_or_exit(bus, common, kProgram);
  if (!bus.good()) rt::exit_with_error(kProgram, "cannot open LCM at '" + bus.url() + "'");
  rt::EventLoop loop(bus);
  options.on_finished = [&loop] { loop.stop(); };
  lmf::log_player::PlayerNode player(bus, loop, std::move(inputs), options);
  if (options.progress != lmf::log_player::PlayerOptions::Progress::kNone) {
    std::cerr << kProgram << ": " << player.inputs().description << "; " << player.counters().scans_total
              << " scans, " << player.counters().sightings_total << " sightings, "
              << (options.lockstep ? std::string("lockstep") : "rate " + std::to_string(rate)) << "\n";
  }
  player.start();
  loop.run();
  std::cerr << kProgram << ": " << player.summary() << "\n";
  if (!player.finished()) {
    std::cerr << kProgram << ": interrupted before the end of the replay\n";
    return 1;
  }
  return 0;
}
