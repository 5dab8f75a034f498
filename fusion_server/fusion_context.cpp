#include "fusion_server/fusion_context.hpp"

#include <algorithm>
#include <map>
#include <utility>

#include "lmf/fusion/map_export.hpp"
#include "lmf/mission/mission_report.hpp"

namespace lmf::server {
namespace {

using nlohmann::json;

std::string trajectory_name(int robot_id) { return "robot" + std::to_string(robot_id); }

}  // namespace

FusionContext::FusionContext(fusion::GlobalMap map, mission::TrajectoryBook book, FusionRecords records)
    : map_(std::move(map)), book_(std::move(book)), records_(std::move(records)) {}

std::vector<fusion::FusionReport> FusionContext::fuse(const LocalMapSnapshot& snapshot, double queue_wait_ms) {
  std::vector<fusion::FusionReport> reports = map_.fuse(snapshot);
  book_.add(snapshot);  // only what the map accepted
  records_.latest_utime = std::max(records_.latest_utime, snapshot.last_utime);
  record(reports, queue_wait_ms);
  return reports;
}

fusion::SightingResult FusionContext::add_sighting(const fusion::RobotSighting& sighting, double queue_wait_ms) {
  try {
    fusion::SightingResult result = map_.add_sighting(sighting);
    record(result.fused, queue_wait_ms);
    records_.sightings.push_back({sighting, mission::sighting_status_name(result.status)});
    return result;
  } catch (...) {
    records_.sightings.push_back({sighting, "rejected"});
    throw;
  }
}

void FusionContext::join_first_robot(int robot_id) { record(map_.join_robot(robot_id, Pose2()), 0.0); }

void FusionContext::record(const std::vector<fusion::FusionReport>& reports, double queue_wait_ms) {
  for (const auto& r : reports) {
    records_.fusions.push_back({r, queue_wait_ms});
    records_.fusion_ms_sum += r.time.total_s * 1e3;
    records_.last_covariance_ok = mission::covariance_ok(r);
    records_.covariance_always_ok = records_.covariance_always_ok && records_.last_covariance_ok;
    // The eigenvalue when the check computed one (it decides: FusionReport::covariance_ok).
    if (r.min_eigenvalue) {
      records_.last_min_pivot = r.min_eigenvalue;
    } else if (r.min_ldlt_pivot) {
      records_.last_min_pivot = r.min_ldlt_pivot;
    }
  }
}

MapView FusionContext::view() const {
  MapView v;
  v.counts = map_.counts();
  v.fusion_count = static_cast<std::int64_t>(records_.fusions.size());
  v.latest_utime = records_.latest_utime;
  v.frames.utime = records_.latest_utime;
  v.frames.fusion_count = v.fusion_count;
  for (fusion::CorrectedFrame f : map_.corrected_frames()) {
    f.covariance = 0.5 * (f.covariance + f.covariance.transpose());
    v.frames.frames.push_back(f);
  }
  for (const fusion::SegmentView& s : map_.segments()) {
    v.endpoints.push_back({static_cast<float>(s.start_W.x()), static_cast<float>(s.start_W.y()),
                           static_cast<float>(s.end_W.x()), static_cast<float>(s.end_W.y())});
  }
  if (!records_.fusions.empty()) {
    v.last_fusion_ms = records_.fusions.back().report.time.total_s * 1e3;
    v.mean_fusion_ms = records_.fusion_ms_sum / static_cast<double>(records_.fusions.size());
  }
  v.covariance_ok = records_.last_covariance_ok;
  v.min_pivot = records_.last_min_pivot;
  return v;
}

json FusionContext::write_outputs(const std::filesystem::path& out_dir, bool svg_graph) const {
  std::filesystem::create_directories(out_dir);
  // The robots named as in a simulated mission.
  std::map<std::string, std::vector<StampedPose>> trajectories;
  for (auto& [robot_id, poses] : book_.final_trajectories(map_)) {
    trajectories[trajectory_name(robot_id)] = std::move(poses);
  }
  mission::write_trajectories(out_dir, trajectories);
  fusion::MapSvgOptions svg;
  svg.graph = svg_graph;
  mission::write_map_files(out_dir, map_, trajectories, svg);

  json report;
  report["source"] = "lmf-server";
  report["map"] = mission::map_counts_json(map_.counts());
  report["global_covariance_always_ok"] = records_.covariance_always_ok;
  std::vector<double> fusion_ms;
  std::vector<double> wait_ms;
  json fusions = json::array();
  for (const FusionRecord& f : records_.fusions) {
    json j = mission::fusion_report_json(f.report);
    j["queue_wait_ms"] = f.queue_wait_ms;
    fusions.push_back(std::move(j));
    fusion_ms.push_back(f.report.time.total_s * 1e3);
    wait_ms.push_back(f.queue_wait_ms);
  }
  report["fusion_timing"] = mission::timing_json(mission::timing_stats(std::move(fusion_ms)));
  report["queue_wait_timing"] = mission::timing_json(mission::timing_stats(std::move(wait_ms)));
  report["fusions"] = std::move(fusions);
  json sightings = json::array();
  for (const SightingRecord& s : records_.sightings) {
    sightings.push_back(mission::sighting_json(s.sighting.utime, s.sighting.observer_id, s.sighting.observed_id,
                                               s.status.c_str()));
  }
  report["sightings"] = std::move(sightings);
  json robots = json::array();
  for (int robot_id : map_.robots()) {
    std::size_t fused = 0;
    for (const FusionRecord& f : records_.fusions) fused += f.report.robot_id == robot_id ? 1 : 0;
    const auto t = trajectories.find(trajectory_name(robot_id));
    robots.push_back({{"robot_id", robot_id},
                      {"local_maps_fused", fused},
                      {"trajectory_poses", t == trajectories.end() ? 0 : t->second.size()}});
  }
  report["robots"] = std::move(robots);
  return report;
}

}  // namespace lmf::server
