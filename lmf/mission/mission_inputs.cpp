#include "lmf/mission/mission_inputs.hpp"

#include <algorithm>
#include <fstream>
#include <optional>
#include <stdexcept>

#include <nlohmann/json.hpp>

#include "lmf/io/carmen.hpp"
#include "lmf/io/config.hpp"
#include "lmf/io/trajectory.hpp"
#include "lmf/sim/random.hpp"

namespace lmf::mission {
namespace {

// Reference poses at the scans' times (exact or nearest within 1 ms). Throws if a scan has none.
std::vector<StampedPose> reference_for(const std::vector<LaserScan>& scans, const std::vector<StampedPose>& reference,
                                       const std::filesystem::path& file) {
  std::vector<StampedPose> out;
  out.reserve(scans.size());
  for (const LaserScan& scan : scans) {
    const auto it = std::lower_bound(reference.begin(), reference.end(), scan.utime,
                                     [](const StampedPose& p, int64_t t) { return p.utime < t; });
    const StampedPose* best = nullptr;
    if (it != reference.end()) best = &*it;
    if (it != reference.begin() && (best == nullptr || scan.utime - std::prev(it)->utime < best->utime - scan.utime)) {
      best = &*std::prev(it);
    }
    if (best == nullptr || std::abs(best->utime - scan.utime) > 1000) {
      throw std::invalid_argument(file.string() + ": no reference pose within 1 ms of the scan at t = " +
                                  std::to_string(static_cast<double>(scan.utime) * 1e-6) + " s");
    }
    out.push_back({scan.utime, best->pose});
  }
  return out;
}

// "belgioioso-noisy" for ".../belgioioso-noisy.log.gz".
std::string log_name(const std::filesystem::path& file) {
  std::filesystem::path name = file.filename();
  if (name.extension() == ".gz") name = name.stem();
  if (name.extension() == ".log") name = name.stem();
  return name.string();
}

Pose2 add_noise(const Pose2& x, const SightingNoise& noise, sim::Rng& rng) {
  // The perturbation is in the frame of x (SPmap convention): x ⊕ p.
  const Pose2 p(rng.normal(0.0, noise.sigma_xy_m), rng.normal(0.0, noise.sigma_xy_m),
                rng.normal(0.0, noise.sigma_phi_rad));
  return compose(x, p);
}

}  // namespace

Eigen::Matrix3d SightingNoise::covariance() const {
  return Eigen::Vector3d(sigma_xy_m * sigma_xy_m, sigma_xy_m * sigma_xy_m, sigma_phi_rad * sigma_phi_rad)
      .asDiagonal();
}

RecordedLog read_carmen_recording(const std::filesystem::path& file) {
  io::CarmenLog log = io::read_carmen_log(file);
  RecordedLog recording;
  recording.file = file;
  recording.name = log_name(file);
  recording.scans = std::move(log.scans);
  recording.notes.push_back(log.laser_mounting.note);
  if (log.flaser_no_return.range_m) recording.notes.push_back(io::describe(log.flaser_no_return));
  if (log.no_return_readings > 0) {
    recording.notes.push_back(std::to_string(log.no_return_readings) + " NaN or infinite ranges read as \"no return\"");
  }
  if (log.cut_short) recording.notes.push_back("CUT SHORT: " + *log.cut_short);
  return recording;
}

MissionInputs load_logs(const std::vector<std::filesystem::path>& logs, int split,
                        const std::filesystem::path& reference, const SightingNoise& noise) {
  std::vector<RecordedLog> recordings;
  for (const auto& file : logs) recordings.push_back(read_carmen_recording(file));
  return load_recordings(std::move(recordings), split, reference, noise);
}

void drop_sightings(MissionInputs& inputs) {
  const std::size_t dropped = inputs.sightings.size();
  inputs.sightings.clear();
  inputs.notes.push_back("no sightings (" + std::to_string(dropped) +
                         " dropped): the robots after the first join only by place recognition "
                         "(global_map.place_recognition.enabled; off by default: their local maps wait)");
}

MissionInputs load_recordings(std::vector<RecordedLog> logs, int split, const std::filesystem::path& reference,
                              const SightingNoise& noise) {
  if (logs.empty()) throw std::invalid_argument("load_logs: no log given");
  if (split < 1) throw std::invalid_argument("load_logs: split must be >= 1, got " + std::to_string(split));
  if (split > 1 && logs.size() != 1) throw std::invalid_argument("load_logs: --split needs exactly one log");

  MissionInputs inputs;
  std::vector<std::vector<StampedPose>> references;
  const std::vector<StampedPose> reference_poses =
      reference.empty() ? std::vector<StampedPose>{} : io::read_trajectory(reference);

  int next_id = 0;
  for (auto& log : logs) {
    const std::filesystem::path& file = log.file;
    if (log.scans.empty()) throw std::invalid_argument(file.string() + ": no laser scans");
    for (const auto& note : log.notes) inputs.notes.push_back(log.name + ": " + note);
    const std::size_t parts = static_cast<std::size_t>(split);
    if (log.scans.size() < 2 * parts) {
      throw std::invalid_argument(file.string() + ": " + std::to_string(log.scans.size()) +
                                  " scans are too few to split into " + std::to_string(split));
    }
    for (std::size_t part = 0; part < parts; ++part) {
      const std::size_t begin = log.scans.size() * part / parts;
      const std::size_t end = log.scans.size() * (part + 1) / parts;
      RobotLog robot;
      robot.robot_id = next_id++;
      robot.name = log.name + (split > 1 ? "-part" + std::to_string(part + 1) : "");
      robot.scans.assign(log.scans.begin() + static_cast<std::ptrdiff_t>(begin),
                         log.scans.begin() + static_cast<std::ptrdiff_t>(end));
      if (split > 1) {
        // Simultaneous robots: every part starts at the time of the first.
        const int64_t shift = robot.scans.front().utime - log.scans.front().utime;
        std::vector<StampedPose> ref;
        if (!reference_poses.empty()) ref = reference_for(robot.scans, reference_poses, reference);
        for (auto& scan : robot.scans) scan.utime -= shift;
        for (auto& pose : ref) pose.utime -= shift;
        references.push_back(std::move(ref));
      } else {
        references.push_back(reference_poses.empty() ? std::vector<StampedPose>{}
                                                     : reference_for(robot.scans, reference_poses, reference));
      }
      inputs.robots.push_back(std::move(robot));
    }
  }

  sim::Rng rng(sim::derive_seed(noise.seed, 0x5167));
  for (std::size_t i = 0; i < inputs.robots.size(); ++i) {
    const int id = inputs.robots[i].robot_id;
    if (!references[i].empty()) inputs.reference[id] = references[i];
    if (i == 0 || references[i].empty() || references[0].empty()) continue;
    // Robot i seen by the first robot when both have scanned once: its start in
    // the first robot's start frame (= W), with sighting noise.
    SightingInput sighting;
    sighting.utime = std::max(inputs.robots[0].scans.front().utime, inputs.robots[i].scans.front().utime);
    sighting.observer = inputs.robots[0].robot_id;
    sighting.observed = id;
    // The first robot's reference pose at its last scan not after the sighting.
    const auto& ref0 = references[0];
    const auto at = std::upper_bound(ref0.begin(), ref0.end(), sighting.utime,
                                     [](int64_t t, const StampedPose& p) { return t < p.utime; });
    const Pose2& x_WA = std::prev(at)->pose;
    sighting.x_AB = add_noise(between(x_WA, references[i].front().pose), noise, rng);
    sighting.covariance = noise.covariance();
    inputs.sightings.push_back(sighting);
  }
  inputs.description = std::to_string(inputs.robots.size()) + " robot(s) from " + std::to_string(logs.size()) +
                       " log(s)" + (split > 1 ? " (split " + std::to_string(split) + ")" : "");
  return inputs;
}

MissionInputs load_sim_folder(const std::filesystem::path& dir, const SightingNoise& noise) {
  if (!std::filesystem::is_directory(dir)) throw std::invalid_argument(dir.string() + ": not a folder");
  MissionInputs inputs;
  // mission.json (lmf-sim writes it) says how many robots the mission has, so
  // robotN files left in the folder by an earlier, larger mission are not
  // replayed as extra robots; without it, robot0, robot1, ... up to the first gap.
  std::optional<int> robots;
  const auto mission_file = dir / "mission.json";
  if (std::filesystem::exists(mission_file)) {
    const nlohmann::json doc = io::read_json_file(mission_file);
    if (!doc.contains("robots") || !doc["robots"].is_array()) {
      throw std::invalid_argument(mission_file.string() + ": no \"robots\" array");
    }
    robots = static_cast<int>(doc["robots"].size());
  }
  for (int id = 0; !robots || id < *robots; ++id) {
    const auto log_file = dir / ("robot" + std::to_string(id) + ".log");
    if (!std::filesystem::exists(log_file)) {
      if (robots) {
        throw std::invalid_argument(mission_file.string() + " lists " + std::to_string(*robots) + " robots but " +
                                    log_file.string() + " is missing");
      }
      break;
    }
    RobotLog robot;
    robot.robot_id = id;
    robot.name = "robot" + std::to_string(id);
    io::CarmenLog log = io::read_carmen_log(log_file);
    if (log.flaser_no_return.range_m) inputs.notes.push_back(robot.name + ": " + io::describe(log.flaser_no_return));
    robot.scans = std::move(log.scans);
    const auto gt_file = dir / ("robot" + std::to_string(id) + ".gt");
    if (std::filesystem::exists(gt_file)) inputs.reference[id] = reference_for(robot.scans, io::read_trajectory(gt_file), gt_file);
    inputs.robots.push_back(std::move(robot));
  }
  if (inputs.robots.empty()) throw std::invalid_argument(dir.string() + ": no robot0.log");

  const auto walls_file = dir / "walls.json";
  if (std::filesystem::exists(walls_file)) {
    const nlohmann::json doc = io::read_json_file(walls_file);
    if (!doc.contains("walls") || !doc["walls"].is_array()) {
      throw std::invalid_argument(walls_file.string() + ": no \"walls\" array");
    }
    for (const auto& w : doc["walls"]) {
      if (!w.is_array() || w.size() != 4) throw std::invalid_argument(walls_file.string() + ": a wall is not [x1, y1, x2, y2]");
      inputs.walls.push_back({{w[0].get<double>(), w[1].get<double>()}, {w[2].get<double>(), w[3].get<double>()}});
    }
    // Tables are boxes the laser sees too: their four faces.
    for (const auto& t : doc.value("tables", nlohmann::json::array())) {
      const Eigen::Vector2d lo(t["min"][0].get<double>(), t["min"][1].get<double>());
      const Eigen::Vector2d hi(t["max"][0].get<double>(), t["max"][1].get<double>());
      const Eigen::Vector2d c1(hi.x(), lo.y());
      const Eigen::Vector2d c2(lo.x(), hi.y());
      inputs.walls.insert(inputs.walls.end(), {{lo, c1}, {c1, hi}, {hi, c2}, {c2, lo}});
    }
  }

  const auto sightings_file = dir / "sightings.json";
  if (std::filesystem::exists(sightings_file)) {
    const nlohmann::json doc = io::read_json_file(sightings_file);
    sim::Rng rng(sim::derive_seed(noise.seed, 0x5167));
    const auto fail = [&](const std::string& what) {
      throw std::invalid_argument(sightings_file.string() + ": " + what);
    };
    if (!doc.contains("sightings") || !doc["sightings"].is_array()) fail("no \"sightings\" array");
    for (const auto& s : doc["sightings"]) {
      if (!s.contains("utime") || !s.contains("observer") || !s.contains("observed") || !s.contains("x_AB") ||
          !s["x_AB"].is_array() || s["x_AB"].size() != 3) {
        fail("a sighting lacks utime, observer, observed or x_AB [x, y, phi]");
      }
      SightingInput in;
      in.utime = s["utime"].get<int64_t>();
      in.observer = s["observer"].get<int>();
      in.observed = s["observed"].get<int>();
      const Pose2 x_AB(s["x_AB"][0].get<double>(), s["x_AB"][1].get<double>(), s["x_AB"][2].get<double>());
      in.x_AB = add_noise(x_AB, noise, rng);
      in.covariance = noise.covariance();
      inputs.sightings.push_back(in);
    }
    std::stable_sort(inputs.sightings.begin(), inputs.sightings.end(),
                     [](const SightingInput& a, const SightingInput& b) { return a.utime < b.utime; });
  }
  inputs.description = std::to_string(inputs.robots.size()) + " simulated robot(s) from " + dir.string();
  return inputs;
}

}  // namespace lmf::mission
