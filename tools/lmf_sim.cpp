// lmf-sim: simulates a multi-robot mission in a seeded indoor world and writes it to a
// folder (CARMEN logs with noisy odometry, true poses, walls, sightings, an SVG, the
// parameters). Same options -> byte-identical files.
#include <cstdint>
#include <cstdio>
#include <exception>
#include <iostream>
#include <sstream>
#include <string>

#include <boost/program_options.hpp>

#include "lmf/io/config.hpp"
#include "lmf/sim/mission.hpp"
#include "lmf/sim/mission_writer.hpp"

namespace po = boost::program_options;

namespace {

constexpr const char* kAbout =
    "lmf-sim: deterministic multi-robot indoor simulator.\n"
    "\n"
    "Generates a university-like floor (a 40 m x 20 m ring corridor = 120 m loop, a cross corridor,\n"
    "dead-end side corridors, rooms with doors; the seed changes the layout details), drives N robots\n"
    "along corridor centrelines at constant speed (smooth corners, in-place turns at dead ends and in\n"
    "rooms), simulates a 180 deg laser (ray cast, Gaussian range noise; other robots and optional\n"
    "people appear as discs) and odometry (--odometry proportional: noise proportional to the motion,\n"
    "the paper's model; --odometry real: like a real robot's wheel odometry, with per-robot scale errors\n"
    "of translation and rotation, a heading bias, lateral slip, heading noise per metre and per step and\n"
    "occasional glitches, see lmf/sim/odometry.hpp; --odometry-config FILE overrides its parameters from\n"
    "a JSON object with the RealOdometryConfig field names), and records\n"
    "robot-robot sightings (within range, in the observer's 180 deg view, no wall in between; at most\n"
    "one per ordered pair per interval).\n"
    "\n"
    "Writes into --out: robotN.log (CARMEN FLASER, pose fields = noisy odometry, N from 0),\n"
    "robotN.gt (t x y theta true pose per scan), walls.json, sightings.json, world.svg, mission.json.\n"
    "\n"
    "Usage: lmf-sim --out DIR [options]\n";

// A default value as the help shows it (0.05, not 0.050000000000000003).
template <typename T>
std::string text(const T& value) {
  std::ostringstream out;
  out << value;
  return out.str();
}

// A JSON object of RealOdometryConfig fields (every key optional, unknown keys are errors).
lmf::sim::RealOdometryConfig read_real_odometry_config(const std::string& file) {
  lmf::io::JsonReader r = lmf::io::JsonReader::from_file(file);
  lmf::sim::RealOdometryConfig c;
  r.read("translation_scale_sigma", c.translation_scale_sigma);
  r.read("rotation_scale_sigma", c.rotation_scale_sigma);
  r.read("heading_bias_sigma_rad_per_m", c.heading_bias_sigma_rad_per_m);
  r.read("translation_noise_fraction", c.translation_noise_fraction);
  r.read("rotation_noise_fraction", c.rotation_noise_fraction);
  r.read("heading_noise_rad2_per_m", c.heading_noise_rad2_per_m);
  r.read("heading_noise_per_step_rad", c.heading_noise_per_step_rad);
  r.read("slip_per_m", c.slip_per_m);
  r.read("slip_per_rad", c.slip_per_rad);
  r.read("heading_glitch_rate_per_m", c.heading_glitch_rate_per_m);
  r.read("heading_glitch_min_rad", c.heading_glitch_min_rad);
  r.read("heading_glitch_max_rad", c.heading_glitch_max_rad);
  r.read("translation_glitch_rate_per_m", c.translation_glitch_rate_per_m);
  r.read("translation_glitch_min_m", c.translation_glitch_min_m);
  r.read("translation_glitch_max_m", c.translation_glitch_max_m);
  lmf::io::finish_and_validate(r, c);
  return c;
}

struct Options {
  lmf::sim::MissionConfig config;
  std::string out;
};

// Returns false when --help was asked for (and printed).
bool parse(int argc, char** argv, Options& o) {
  lmf::sim::MissionConfig& c = o.config;
  double odometry_noise = c.odometry.translation_fraction;
  uint64_t seed = c.seed;
  std::size_t beams = c.laser.num_beams;
  std::string odometry_model = lmf::sim::odometry_model_name(c.odometry_model);
  std::string odometry_config;
  po::options_description desc("Options");
  desc.add_options()
      ("help,h", "print this help and exit")
      ("out", po::value(&o.out)->required(), "output folder (created if missing; files are overwritten) [required]")
      ("robots", po::value(&c.num_robots)->default_value(c.num_robots, text(c.num_robots)), "number of robots, 1..8")
      ("seed", po::value(&seed)->default_value(seed, text(seed)), "random seed (world layout, routes, noise)")
      ("duration-s", po::value(&c.duration_s)->default_value(c.duration_s, text(c.duration_s)), "mission length in seconds")
      ("speed-mps", po::value(&c.motion.speed_mps)->default_value(c.motion.speed_mps, text(c.motion.speed_mps)), "robot speed (m/s)")
      ("scan-rate-hz", po::value(&c.scan_rate_hz)->default_value(c.scan_rate_hz, text(c.scan_rate_hz)), "laser scans per second per robot")
      ("beams", po::value(&beams)->default_value(beams, text(beams)), "beams per scan over 180 deg")
      ("range-noise-m", po::value(&c.laser.range_noise_sigma_m)->default_value(c.laser.range_noise_sigma_m, text(c.laser.range_noise_sigma_m)),
       "standard deviation of the range noise (m)")
      ("range-noise-per-m", po::value(&c.laser.range_noise_per_m)->default_value(c.laser.range_noise_per_m, text(c.laser.range_noise_per_m)),
       "the range noise's part proportional to the range (m per m; the two add in quadrature, as a laser's \"5 cm or 1 % of "
       "the range\")")
      ("max-range-m", po::value(&c.laser.max_range_m)->default_value(c.laser.max_range_m, text(c.laser.max_range_m)),
       "laser max range (m); a beam with no wall within it reads exactly this (\"no return\")")
      ("odometry", po::value(&odometry_model)->default_value(odometry_model),
       "odometry model: proportional (the paper's) or real (a real robot's wheel odometry)")
      ("odometry-config", po::value(&odometry_config),
       "JSON file of the real model's parameters (RealOdometryConfig fields; with --odometry real)")
      ("odometry-noise", po::value(&odometry_noise)->default_value(odometry_noise, text(odometry_noise)),
       "proportional odometry noise: standard deviation per metre of translation and per radian of rotation (fraction)")
      ("odometry-drift-rad-per-m",
       po::value(&c.odometry.heading_drift_rad_per_m)->default_value(c.odometry.heading_drift_rad_per_m, text(c.odometry.heading_drift_rad_per_m)),
       "extra heading noise standard deviation per metre travelled")
      ("people", po::value(&c.people.count)->default_value(c.people.count, text(c.people.count)),
       "people walking in the corridors (clutter in the scans); 0 = none (the default)")
      ("hide-robots", po::bool_switch(), "robots do not appear in each other's scans (they do by default)")
      ("robot-gap-m", po::value(&c.robot_gap_m)->default_value(c.robot_gap_m, text(c.robot_gap_m)),
       "a robot waits rather than come closer than this (m, body to body) to another one; 0 = robots drive through each other")
      ("max-wait-s", po::value(&c.max_wait_s)->default_value(c.max_wait_s, text(c.max_wait_s)),
       "longest wait for another robot (s); then it drives on regardless (robots meeting head-on)")
      ("sighting-range-m", po::value(&c.sightings.max_range_m)->default_value(c.sightings.max_range_m, text(c.sightings.max_range_m)),
       "a robot is seen within this distance")
      ("sighting-interval-s", po::value(&c.sightings.min_interval_s)->default_value(c.sightings.min_interval_s, text(c.sightings.min_interval_s)),
       "at most one sighting per observer/observed pair per this many seconds");
  po::variables_map vm;
  po::store(po::parse_command_line(argc, argv, desc), vm);
  if (vm.count("help") != 0u) {
    std::cout << kAbout << "\n" << desc << "\n";
    return false;
  }
  po::notify(vm);
  c.seed = seed;
  c.laser.num_beams = beams;
  c.odometry.translation_fraction = odometry_noise;
  c.odometry.rotation_fraction = odometry_noise;
  c.robots_visible_in_scans = !vm["hide-robots"].as<bool>();
  c.odometry_model = lmf::sim::parse_odometry_model(odometry_model);
  if (!odometry_config.empty()) {
    if (c.odometry_model != lmf::sim::OdometryModel::kReal) {
      throw std::invalid_argument("--odometry-config needs --odometry real");
    }
    c.real_odometry = read_real_odometry_config(odometry_config);
  }
  c.validate();
  return true;
}

void print_summary(const lmf::sim::Mission& m, const std::string& out) {
  std::printf("lmf-sim: seed %llu, %d robot(s), %.0f s -> %s\n", static_cast<unsigned long long>(m.config.seed),
              m.config.num_robots, m.config.duration_s, out.c_str());
  std::printf("  odometry: %s\n", lmf::sim::odometry_model_name(m.config.odometry_model));
  std::printf("  world: loop %.1f m, %zu wall faces, %zu rooms\n", m.world.loop_length_m, m.world.walls.size(),
              m.world.rooms.size());
  for (const auto& r : m.robots) {
    std::printf("  robot%d: %zu scans, %.1f m travelled (odometry %.1f m) -> robot%d.log, robot%d.gt\n", r.id,
                r.scans.size(), r.distance_m, r.odometry_distance_m, r.id, r.id);
    if (m.config.odometry_model == lmf::sim::OdometryModel::kReal) {
      std::printf("          systematic odometry errors: translation scale %.4f, rotation scale %.4f, heading bias "
                  "%.4f rad/m\n",
                  r.odometry_errors.translation_scale, r.odometry_errors.rotation_scale,
                  r.odometry_errors.heading_bias_rad_per_m);
    }
  }
  std::printf("  sightings: %zu -> sightings.json; also walls.json, world.svg, mission.json\n", m.sightings.size());
}

}  // namespace

int main(int argc, char** argv) {
  Options options;
  try {
    if (!parse(argc, argv, options)) return 0;
  } catch (const std::exception& e) {
    std::cerr << "lmf-sim: " << e.what() << "\n(see lmf-sim --help)\n";
    return 2;
  }
  try {
    const lmf::sim::Mission mission = lmf::sim::simulate_mission(options.config);
    lmf::sim::write_mission(mission, options.out);
    print_summary(mission, options.out);
  } catch (const std::exception& e) {
    std::cerr << "lmf-sim: " << e.what() << "\n";
    return 1;
  }
  return 0;
}
