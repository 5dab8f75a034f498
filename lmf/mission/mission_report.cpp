#include "lmf/mission/mission_report.hpp"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <fstream>
#include <map>
#include <numbers>
#include <sstream>
#include <stdexcept>

#include <nlohmann/json.hpp>

#include "lmf/front_end/range_noise_estimate.hpp"
#include "lmf/fusion/map_export.hpp"
#include "lmf/io/trajectory.hpp"

namespace lmf::mission {
namespace {

using nlohmann::json;

// Pooled RPE over robots: RMSE over all their relative motions.
eval::RelativeError pool(const std::vector<eval::RelativeError>& parts, double distance_m) {
  eval::RelativeError pooled;
  pooled.distance_m = distance_m;
  double sum_t2 = 0.0;
  double sum_r2 = 0.0;
  for (const auto& p : parts) {
    pooled.count += p.count;
    sum_t2 += static_cast<double>(p.count) * p.translation_rmse_m * p.translation_rmse_m;
    sum_r2 += static_cast<double>(p.count) * p.rotation_rmse_deg * p.rotation_rmse_deg;
  }
  if (pooled.count > 0) {
    pooled.translation_rmse_m = std::sqrt(sum_t2 / static_cast<double>(pooled.count));
    pooled.rotation_rmse_deg = std::sqrt(sum_r2 / static_cast<double>(pooled.count));
  }
  return pooled;
}

json to_json(const eval::AbsoluteError& e) {
  return {{"count", e.count},
          {"position_rmse_m", e.position_rmse_m},
          {"heading_rmse_deg", e.heading_rmse_deg},
          {"position_max_m", e.position_max_m}};
}

json to_json(const eval::RelativeError& e) {
  return {{"distance_m", e.distance_m},
          {"count", e.count},
          {"translation_rmse_m", e.translation_rmse_m},
          {"rotation_rmse_deg", e.rotation_rmse_deg}};
}

std::vector<StampedPose> odometry_of(const RobotLog& log) {
  std::vector<StampedPose> poses;
  poses.reserve(log.scans.size());
  for (const LaserScan& s : log.scans) poses.push_back({s.utime, s.odometry});
  return poses;
}

const RobotLog* log_of(const MissionInputs& inputs, int robot_id) {
  for (const RobotLog& log : inputs.robots) {
    if (log.robot_id == robot_id) return &log;
  }
  return nullptr;
}

json mean_or_null(const std::vector<double>& values) {
  if (values.empty()) return nullptr;
  double sum = 0.0;
  for (const double v : values) sum += v;
  return sum / static_cast<double>(values.size());
}

}  // namespace

json odometry_model_json(const OdometryErrorModel& m, const OdometryLearningStats& stats) {
  return {{"translation_scale", m.translation_scale},
          {"rotation_scale", m.rotation_scale},
          {"heading_bias_rad_per_m", m.heading_bias_rad_per_m},
          {"x_step_m", m.x_step_m},
          {"x_per_m", m.x_per_m},
          {"y_step_m", m.y_step_m},
          {"y_per_m", m.y_per_m},
          {"phi_step_rad", m.phi_step_rad},
          {"phi_per_m", m.phi_per_m},
          {"phi_per_rad", m.phi_per_rad},
          {"phi_turn_distance", m.phi_turn_distance},
          {"increments_learned", stats.increments},
          {"increments_downweighted", stats.downweighted},
          {"at_bounds", stats.at_bounds}};
}

json consistency_json(const std::vector<LocalMapConsistency>& maps) {
  json list = json::array();
  for (const LocalMapConsistency& c : maps) {
    list.push_back({{"seq", c.seq}, {"error_m", c.error_m}, {"error_rad", c.error_rad}, {"nees", c.nees}});
  }
  return list;
}

json timing_json(const TimingStats& t) {
  return {{"count", t.count}, {"p50_ms", t.p50_ms}, {"p99_ms", t.p99_ms}, {"max_ms", t.max_ms}, {"mean_ms", t.mean_ms}};
}

json map_counts_json(const fusion::MapCounts& c) {
  return {{"segments", c.segments},
          {"submaps", c.submaps},
          {"robots_joined", c.robots_joined},
          {"graph_edges", c.graph_edges},
          {"queued_local_maps", c.queued_local_maps},
          {"state_dimension", c.state_dimension}};
}

json sighting_json(std::int64_t utime, int observer, int observed, const char* status) {
  return {{"utime", utime}, {"observer", observer}, {"observed", observed}, {"status", status}};
}

json fusion_report_json(const fusion::FusionReport& r) {
  json j = {{"robot_id", r.robot_id},
            {"seq", r.seq},
            {"local_segments", r.local_segments},
            {"anchored_backward", r.anchored_backward},
            {"registration", fusion::to_string(r.registration)},
            {"registration_offset", {r.registration_offset.x, r.registration_offset.y, r.registration_offset.phi}},
            {"registration_distance2", r.registration_distance2},
            {"registration_score", r.registration_score},
            {"registration_unresolved", r.registration_unresolved},
            {"pairs_considered", r.pairs_considered},
            {"gate_rejected", r.gate_rejected},
            {"unconfirmed_pairs", r.unconfirmed_pairs},
            {"chi2_rejected", r.chi2_rejected},
            {"overlap_rejected", r.overlap_rejected},
            {"jc_candidates", r.jc_candidates},
            {"jc_rejected", r.jc_rejected},
            {"pairings_accepted", r.pairings_accepted},
            {"update_rows", r.update_rows},
            {"rows_dropped", r.rows_dropped},
            {"rows_kept", r.rows_kept},
            {"segments_extended", r.segments_extended},
            {"global_segments_fused", r.global_segments_fused},
            {"new_segments", r.new_segments},
            {"footprint_segments_removed", r.footprint_segments_removed},
            {"crossing_segments_removed", r.crossing_segments_removed},
            {"segments_after", r.size_after.segments},
            {"submaps_after", r.size_after.submaps},
            {"graph_edges_after", r.size_after.graph_edges},
            {"state_dimension_after", r.size_after.state_dimension},
            {"time_ms", r.time.total_s * 1e3},
            {"update_ms", r.time.update_s * 1e3}};
  if (r.min_ldlt_pivot) j["min_ldlt_pivot"] = *r.min_ldlt_pivot;
  if (r.min_eigenvalue) j["min_eigenvalue"] = *r.min_eigenvalue;
  return j;
}

const char* sighting_status_name(fusion::SightingStatus s) {
  switch (s) {
    case fusion::SightingStatus::kJoined: return "joined";
    case fusion::SightingStatus::kJoinedApproximately: return "joined_approximately";
    case fusion::SightingStatus::kPending: return "pending";
    case fusion::SightingStatus::kIgnored: return "ignored";
  }
  return "unknown";
}

bool covariance_ok(const fusion::FusionReport& r) { return r.covariance_ok(); }

std::optional<MissionScore> score_mission(const MissionResult& result, const MissionInputs& inputs,
                                          const fusion::GlobalMap& map) {
  MissionScore score;
  std::vector<eval::PosePair> all_pairs;
  std::vector<eval::RelativeError> rpe1;
  std::vector<eval::RelativeError> rpe10;
  for (const RobotResult& robot : result.robots) {
    const auto ref = inputs.reference.find(robot.robot_id);
    if (ref == inputs.reference.end() || robot.trajectory.empty()) continue;
    RobotScore s;
    s.robot_id = robot.robot_id;
    const std::vector<eval::PosePair> pairs = eval::associate_by_time(robot.trajectory, ref->second);
    if (pairs.size() < 2) continue;
    s.ate = eval::absolute_trajectory_error(pairs);
    s.rpe_1m = eval::relative_pose_error(pairs, 1.0);
    s.rpe_10m = eval::relative_pose_error(pairs, 10.0);
    if (const RobotLog* log = log_of(inputs, robot.robot_id)) {
      s.odometry_ate = eval::absolute_trajectory_error(eval::associate_by_time(odometry_of(*log), ref->second));
    }
    all_pairs.insert(all_pairs.end(), pairs.begin(), pairs.end());
    rpe1.push_back(s.rpe_1m);
    rpe10.push_back(s.rpe_10m);
    score.robots.push_back(s);
  }
  if (score.robots.empty()) return std::nullopt;
  score.ate = eval::absolute_trajectory_error(all_pairs);
  score.rpe_1m = pool(rpe1, 1.0);
  score.rpe_10m = pool(rpe10, 10.0);
  if (!inputs.walls.empty()) {
    std::vector<eval::LineSegment> mapped;
    for (const fusion::SegmentView& s : map.segments()) mapped.push_back({s.start_W, s.end_W});
    score.map = eval::map_error(mapped, inputs.walls, score.ate.alignment);
  }
  return score;
}

void write_trajectories(const std::filesystem::path& out,
                        const std::map<std::string, std::vector<StampedPose>>& trajectories) {
  std::filesystem::create_directories(out / "trajectories");
  std::vector<StampedPose> all;
  for (const auto& [name, trajectory] : trajectories) {
    io::write_trajectory(out / "trajectories" / (name + ".txt"), trajectory);
    all.insert(all.end(), trajectory.begin(), trajectory.end());
  }
  std::stable_sort(all.begin(), all.end(), [](const StampedPose& a, const StampedPose& b) { return a.utime < b.utime; });
  io::write_trajectory(out / "trajectory.txt", all);
}

void write_map_files(const std::filesystem::path& out, const fusion::GlobalMap& map,
                     const std::map<std::string, std::vector<StampedPose>>& trajectories,
                     const fusion::MapSvgOptions& svg) {
  std::filesystem::create_directories(out);
  fusion::write_map_json(map, out / "map.json");
  std::vector<fusion::MapTrajectory> paths;
  for (const auto& [name, trajectory] : trajectories) {
    fusion::MapTrajectory path;
    path.label = name;
    for (const StampedPose& p : trajectory) path.poses.push_back(p.pose);
    paths.push_back(std::move(path));
  }
  fusion::write_map_svg(map, out / "map.svg", paths, svg);
}

void write_mission_outputs(const std::filesystem::path& out, const OfflineMission& mission,
                           const MissionResult& result, const std::optional<MissionScore>& score,
                           const fusion::MapSvgOptions& svg) {
  std::map<std::string, std::vector<StampedPose>> trajectories;
  for (const RobotResult& robot : result.robots) {
    if (!robot.trajectory.empty()) trajectories[robot.name] = robot.trajectory;
  }
  write_trajectories(out, trajectories);
  write_map_files(out, mission.global_map(), trajectories, svg);

  json report;
  report["inputs"] = mission.inputs().description;
  report["input_notes"] = mission.inputs().notes;
  report["map"] = map_counts_json(mission.global_map().counts());
  const fusion::PlaceRecognitionCounts& places = mission.global_map().place_recognition_counts();
  report["place_recognition"] = {{"placed", places.placed},
                                 {"not_found", places.not_found},
                                 {"ambiguous", places.ambiguous},
                                 {"degenerate", places.degenerate}};
  json robots = json::array();
  for (const RobotResult& r : result.robots) {
    robots.push_back({{"robot_id", r.robot_id},
                      {"name", r.name},
                      {"joined", r.joined},
                      {"joined_by", r.join ? json(fusion::to_string(r.join->how)) : json(nullptr)},
                      {"joined_at_seq", r.join ? json(r.join->seq) : json(nullptr)},
                      {"scans", r.scans},
                      {"local_maps_shipped", r.local_maps_shipped},
                      {"local_maps_fused", r.local_maps_fused},
                      {"segments_seen_through", r.segments_seen_through},
                      {"scan_timing", timing_json(r.scan_timing)},
                      {"covariance_always_ok", r.covariance_always_ok},
                      {"first_covariance_problem", r.first_covariance_problem},
                      {"odometry_model", odometry_model_json(r.odometry_model, r.odometry_learning)},
                      {"point_noise",
                       {{"sigma_m", r.point_sigma_m},
                        {"range_noise_per_m", r.range_noise_per_m},
                        {"measured_over_matches", r.range_noise_matches}}},
                      {"local_map_consistency", consistency_json(r.local_map_consistency)},
                      {"scans_skipped", r.scans_skipped},
                      {"scan_matches", r.scan_matches},
                      {"match_fallbacks", r.match_fallbacks},
                      {"match_escalations", r.match_escalations},
                      {"matches_from_escalation", r.matches_from_escalation},
                      {"match_nees", {{"count", r.match_nees.size()}, {"mean", mean_or_null(r.match_nees)}}},
                      {"match_chain_nees",
                       {{"steps", kMatchChainSteps},
                        {"count", r.match_chain_nees.size()},
                        {"mean", mean_or_null(r.match_chain_nees)}}}});
  }
  report["robots"] = robots;
  report["fusion_timing"] = timing_json(result.fusion_timing);
  report["global_covariance_always_ok"] = result.global_covariance_always_ok;
  json fusions = json::array();
  for (const auto& f : result.fusions) fusions.push_back(fusion_report_json(f));
  report["fusions"] = fusions;
  json frame_checks = json::array();
  for (const FusionFrameCheck& c : result.fusion_frame_checks) {
    frame_checks.push_back({{"robot_id", c.robot_id},
                            {"seq", c.seq},
                            {"before_m", c.before_m},
                            {"before_rad", c.before_rad},
                            {"after_m", c.after_m},
                            {"after_rad", c.after_rad}});
  }
  report["fusion_frame_checks"] = frame_checks;
  json sightings = json::array();
  for (const auto& s : result.sightings) {
    sightings.push_back(sighting_json(s.input.utime, s.input.observer, s.input.observed, sighting_status_name(s.status)));
  }
  report["sightings"] = sightings;
  if (score) {
    json per_robot = json::array();
    for (const RobotScore& s : score->robots) {
      per_robot.push_back({{"robot_id", s.robot_id},
                           {"ate", to_json(s.ate)},
                           {"rpe_1m", to_json(s.rpe_1m)},
                           {"rpe_10m", to_json(s.rpe_10m)},
                           {"odometry_ate", to_json(s.odometry_ate)}});
    }
    if (score->map) {
      report["map_error"] = {{"segments", score->map->segments},
                             {"unmatched_segments", score->map->unmatched_segments},
                             {"points", score->map->points},
                             {"rms_m", score->map->rms_m},
                             {"max_m", score->map->max_m}};
    }
    report["score"] = {{"ate", to_json(score->ate)},
                       {"rpe_1m", to_json(score->rpe_1m)},
                       {"rpe_10m", to_json(score->rpe_10m)},
                       {"robots", per_robot}};
  }
  std::ofstream file(out / "report.json");
  file << report.dump(1) << '\n';
  if (!file) throw std::runtime_error((out / "report.json").string() + ": cannot write");
}

std::string describe_fusion_frame_checks(const std::vector<FusionFrameCheck>& checks) {
  // A fusion that changes the frame's error by less than this moved it within
  // the reference's own accuracy (a reporting threshold, not a parameter).
  constexpr double kNoticeable_m = 0.1;
  constexpr double kNoticeable_rad = std::numbers::pi / 180.0;
  int closer = 0;
  int farther = 0;
  const FusionFrameCheck* worst = nullptr;
  for (const FusionFrameCheck& c : checks) {
    const double gain_m = c.before_m - c.after_m;
    const double gain_rad = c.before_rad - c.after_rad;
    if (gain_m <= -kNoticeable_m || gain_rad <= -kNoticeable_rad) {
      ++farther;
      if (!worst || c.after_m - c.before_m > worst->after_m - worst->before_m) worst = &c;
    } else if (gain_m >= kNoticeable_m || gain_rad >= kNoticeable_rad) {
      ++closer;
    }
  }
  char line[320];
  std::snprintf(line, sizeof line,
                "fusions vs reference (the robot's frame before and after each of %zu): %d moved it 0.1 m or 1 deg "
                "closer, %d farther",
                checks.size(), closer, farther);
  std::string out = line;
  if (worst) {
    std::snprintf(line, sizeof line, "; the farthest: robot %d map %lld, %.2f m %.1f deg -> %.2f m %.1f deg",
                  worst->robot_id, static_cast<long long>(worst->seq), worst->before_m,
                  worst->before_rad * 180.0 / std::numbers::pi, worst->after_m,
                  worst->after_rad * 180.0 / std::numbers::pi);
    out += line;
  }
  return out;
}

std::string summarize(const OfflineMission& mission, const MissionResult& result,
                      const std::optional<MissionScore>& score) {
  std::ostringstream s;
  char line[256];
  s << "lmf-offline: " << mission.inputs().description << "\n";
  for (const std::string& note : mission.inputs().notes) s << "  " << note << "\n";
  s << "robot                      joined  scans  maps  p50 ms  p99 ms  max ms   ATE m  odom ATE m\n";
  for (const RobotResult& r : result.robots) {
    const RobotScore* rs = nullptr;
    if (score) {
      for (const auto& x : score->robots) {
        if (x.robot_id == r.robot_id) rs = &x;
      }
    }
    std::snprintf(line, sizeof line, "%-26s %6s %6zu %5zu %7.2f %7.2f %7.2f %7s %11s\n", r.name.c_str(),
                  r.joined ? "yes" : "NO", r.scans, r.local_maps_fused, r.scan_timing.p50_ms, r.scan_timing.p99_ms,
                  r.scan_timing.max_ms, rs ? std::to_string(rs->ate.position_rmse_m).substr(0, 6).c_str() : "-",
                  rs ? std::to_string(rs->odometry_ate.position_rmse_m).substr(0, 6).c_str() : "-");
    s << line;
  }
  for (const RobotResult& r : result.robots) {
    if (r.join && r.join->how == fusion::JoinKind::kPlace) {
      s << "  " << r.name << " joined by place recognition at its local map " << r.join->seq << " (score "
        << std::to_string(r.join->place_score).substr(0, 4) << ")\n";
    }
  }
  const fusion::PlaceRecognitionCounts& places = mission.global_map().place_recognition_counts();
  if (places.placed + places.not_found + places.ambiguous + places.degenerate > 0) {
    s << "place recognition: " << places.placed << " placed, " << places.not_found << " not found, "
      << places.ambiguous << " ambiguous, " << places.degenerate << " degenerate\n";
  }
  for (const RobotResult& r : result.robots) {
    if (r.local_map_consistency.empty()) continue;
    std::vector<double> nees;
    double worst_m = 0.0;
    double worst_rad = 0.0;
    for (const LocalMapConsistency& c : r.local_map_consistency) {
      nees.push_back(c.nees);
      worst_m = std::max(worst_m, c.error_m);
      worst_rad = std::max(worst_rad, c.error_rad);
    }
    std::sort(nees.begin(), nees.end());
    double mean = 0.0;
    for (const double v : nees) mean += v / static_cast<double>(nees.size());
    std::snprintf(line, sizeof line,
                  "%s local maps vs reference: end-pose NEES mean %.1f, median %.1f (3 if consistent) over %zu "
                  "maps; worst end error %.3f m, %.2f deg\n",
                  r.name.c_str(), mean, nees[nees.size() / 2], nees.size(), worst_m, worst_rad * 180.0 / 3.14159265358979);
    s << line;
  }
  for (const RobotResult& r : result.robots) {
    if (r.scan_matches + r.match_fallbacks == 0) continue;
    s << r.name << " scans taken: " << r.scans - r.scans_skipped << " of " << r.scans << " (motion filter)"
      << "; scan matches: " << r.scan_matches << ", fallbacks to odometry: " << r.match_fallbacks
      << ", searches escalated: " << r.match_escalations << " (" << r.matches_from_escalation << " matched there)";
    if (!r.match_nees.empty()) {
      std::snprintf(line, sizeof line, "; match NEES mean %.1f (3 if consistent) over %zu matches with a reference",
                    mean_or_null(r.match_nees).get<double>(), r.match_nees.size());
      s << line;
    }
    if (!r.match_chain_nees.empty()) {
      std::snprintf(line, sizeof line, "; over chains of %d matches %.1f (%zu chains)", kMatchChainSteps,
                    mean_or_null(r.match_chain_nees).get<double>(), r.match_chain_nees.size());
      s << line;
    }
    s << "\n";
  }
  for (const RobotResult& r : result.robots) {
    s << r.name << " odometry model: " << describe(r.odometry_model) << " (" << r.odometry_learning.increments
      << " matched increments, " << r.odometry_learning.downweighted << " downweighted as glitches)\n";
    const std::string bounds = describe_bounds(r.odometry_model, r.odometry_learning);
    if (!bounds.empty()) s << "WARNING: " << r.name << ": " << bounds << "\n";
    s << r.name << " laser point noise: "
      << describe_point_noise(r.point_sigma_m, r.range_noise_per_m, r.range_noise_matches) << "\n";
  }
  std::size_t seen_through = 0;
  for (const RobotResult& r : result.robots) seen_through += r.segments_seen_through;
  s << "local maps: " << seen_through << " segments removed as seen through (free-space evidence)\n";
  if (mission.global_map().config().footprint_radius_m > 0.0) {
    int in_footprints = 0;
    for (const fusion::FusionReport& f : result.fusions) in_footprints += f.footprint_segments_removed;
    s << "global map: " << in_footprints << " segments removed inside robot footprints (footprint_radius_m "
      << mission.global_map().config().footprint_radius_m << "; " << mission.global_map().footprint_positions()
      << " robot positions recorded)\n";
  }
  if (mission.global_map().config().crossing_margin_m > 0.0) {
    int crossing = 0;
    for (const fusion::FusionReport& f : result.fusions) crossing += f.crossing_segments_removed;
    s << "global map: " << crossing << " segments removed as the less certain of two that cross\n";
  }
  if (mission.global_map().config().registration.enabled) {
    std::map<fusion::RegistrationOutcome, int> outcomes;
    for (const fusion::FusionReport& f : result.fusions) ++outcomes[f.registration];
    using fusion::RegistrationOutcome;
    s << "frame registration: " << outcomes[RegistrationOutcome::kRelocated] << " frames relocated, "
      << outcomes[RegistrationOutcome::kAmbiguous] << " ambiguous and " << outcomes[RegistrationOutcome::kDegenerate]
      << " degenerate disagreements left alone, " << outcomes[RegistrationOutcome::kAgrees] << " agreed, "
      << outcomes[RegistrationOutcome::kNothingNearby] << " with nothing nearby\n";
    if (mission.global_map().config().registration.confirm_pairings) {
      int fusions = 0;
      int pairs = 0;
      for (const fusion::FusionReport& f : result.fusions) {
        fusions += f.unconfirmed_pairs > 0 ? 1 : 0;
        pairs += f.unconfirmed_pairs;
      }
      s << "unconfirmed pairings refused: " << pairs << " pairs with the established map in " << fusions
        << " fusions whose registration found nothing there\n";
    }
  }
  if (!result.fusion_frame_checks.empty()) s << describe_fusion_frame_checks(result.fusion_frame_checks) << "\n";
  const fusion::MapCounts counts = mission.global_map().counts();
  std::snprintf(line, sizeof line,
                "map: %d segments, %d submaps, %d graph edges; %zu fusions (median %.1f ms, max %.1f ms); "
                "P PSD throughout: %s\n",
                counts.segments, counts.submaps, counts.graph_edges, result.fusions.size(),
                result.fusion_timing.p50_ms, result.fusion_timing.max_ms,
                result.global_covariance_always_ok ? "yes" : "NO");
  s << line;
  if (score) {
    std::snprintf(line, sizeof line,
                  "ATE (all robots, one alignment): %.3f m, %.2f deg over %zu poses; RPE 1 m: %.3f m %.2f deg; "
                  "RPE 10 m: %.3f m %.2f deg\n",
                  score->ate.position_rmse_m, score->ate.heading_rmse_deg, score->ate.count,
                  score->rpe_1m.translation_rmse_m, score->rpe_1m.rotation_rmse_deg, score->rpe_10m.translation_rmse_m,
                  score->rpe_10m.rotation_rmse_deg);
    s << line;
    if (score->map) {
      std::snprintf(line, sizeof line,
                    "map vs true walls: %.3f m RMS (max %.3f m) over %zu segments; %zu segments match no wall\n",
                    score->map->rms_m, score->map->max_m, score->map->segments - score->map->unmatched_segments,
                    score->map->unmatched_segments);
      s << line;
    }
  }
  return s.str();
}

}  // namespace lmf::mission
