// lmf-offline: the whole multi-robot mapping mission in one deterministic
// process, without LCM (lockstep: each shipped local map is fused before the
// next scan). See --help.
#include <exception>
#include <filesystem>
#include <iostream>
#include <string>
#include <vector>

#include <boost/program_options.hpp>

#include "lmf/mission/config_file.hpp"
#include "lmf/mission/mission_inputs.hpp"
#include "lmf/mission/mission_report.hpp"
#include "lmf/mission/offline_mission.hpp"
#include "tools/recording_options.hpp"

namespace po = boost::program_options;


int main(int argc, char** argv) {
  po::options_description options(
      "lmf-offline: runs one local map per robot and the global map over recorded or simulated\n"
      "robots in one deterministic process, then writes trajectories, the map and a report.\n\n"
      "Usage: lmf-offline (--log FILE... | --bag FILE...) [--split N] [--gt FILE] [--no-sightings] [--config FILE] --out DIR\n"
      "       lmf-offline --sim DIR [--no-sightings] [--config FILE] --out DIR\n\n"
      "Options");
  lmf::tools::RecordingOptions recordings;
  int split = 1;
  std::string gt;
  std::string sim_dir;
  std::string config_file;
  std::string out;
  uint64_t seed = 0;
  options.add_options()("help,h", "print this help")(
      "split", po::value(&split)->default_value(1),
      "cut the single --log or --bag into N contiguous parts replayed as N simultaneous robots")(
      "gt", po::value(&gt),
      "reference poses (`t x y theta` or `index t x y theta`): joins robots after the first at their "
      "reference start plus sighting noise, and scores ATE/RPE")(
      "sim", po::value(&sim_dir), "an lmf-sim output folder (logs, ground truth, sightings)")(
      "config", po::value(&config_file), "JSON config (sections local_map, global_map, sighting_noise)")(
      "seed", po::value(&seed), "seed of the sighting noise (overrides the config's)")(
      "out", po::value(&out), "output folder (created)")(
      "map-graph", "draw the environment graph (submap nodes, consecutive and paired edges) in map.svg")(
      "no-sightings",
      "drop every sighting (and, with --gt, the start poses taken as sightings): robots after the first "
      "join only by place recognition (global_map.place_recognition.enabled; off by default: they wait)");
  recordings.add_to(options);
  po::variables_map vm;
  try {
    po::store(po::parse_command_line(argc, argv, options), vm);
    po::notify(vm);
  } catch (const std::exception& e) {
    std::cerr << "lmf-offline: " << e.what() << "\n(see --help)\n";
    return 2;
  }
  if (vm.count("help") != 0u) {
    std::cout << options << "\n";
    return 0;
  }
  if (out.empty() || recordings.kinds_given() + (!sim_dir.empty()) != 1) {
    std::cerr << "lmf-offline: give --out and exactly one of --log, --bag or --sim (see --help)\n";
    return 2;
  }
  try {
    lmf::mission::MissionConfig config =
        config_file.empty() ? lmf::mission::MissionConfig{} : lmf::mission::load_mission_config(config_file);
    if (vm.count("seed") != 0u) config.sighting_noise.seed = seed;
    recordings.finish(vm);
    if (recordings.no_odometry) config.local_map.scans_have_odometry = false;
    lmf::mission::MissionInputs inputs =
        sim_dir.empty() ? lmf::mission::load_recordings(recordings.read(), split, gt, config.sighting_noise)
                        : lmf::mission::load_sim_folder(sim_dir, config.sighting_noise);
    if (vm.count("no-sightings") != 0u) lmf::mission::drop_sightings(inputs);
    lmf::mission::OfflineMission mission(config, std::move(inputs));
    const lmf::mission::MissionResult result = mission.run();
    const auto score = lmf::mission::score_mission(result, mission.inputs(), mission.global_map());
    lmf::fusion::MapSvgOptions svg;
    svg.graph = vm.count("map-graph") != 0u;
    lmf::mission::write_mission_outputs(out, mission, result, score, svg);
    std::cout << lmf::mission::summarize(mission, result, score) << "wrote " << out
              << "/{trajectory.txt, trajectories/, map.json, map.svg, report.json}\n";
  } catch (const std::exception& e) {
    std::cerr << "lmf-offline: " << e.what() << "\n";
    return 1;
  }
  return 0;
}
