// What the server's fusion worker owns: the global map, the trajectory book,
// the records that report.json lists and what the status says of the fusions.
// Synchronous, no LCM and no threads: ServerNode calls it from its worker only
// (and from recovery, before the worker starts), and sends the loop thread a
// MapView copy after each task. The outputs are written by lmf-offline's
// writers (lmf/mission), so a distributed run's files read like an offline one's.
#pragma once

#include <array>
#include <cstdint>
#include <filesystem>
#include <optional>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "lmf/fusion/global_map.hpp"
#include "lmf/fusion/robot_sighting.hpp"
#include "lmf/local_map/local_map_snapshot.hpp"
#include "lmf/mission/trajectory_book.hpp"
#include "runtime/messages.hpp"

namespace lmf::server {

struct FusionRecord {
  fusion::FusionReport report;
  double queue_wait_ms = 0.0;  // from arrival to the start of the task that fused it
};

struct SightingRecord {
  fusion::RobotSighting sighting;
  std::string status;  // mission::sighting_status_name, or "rejected"
};

// What report.json and the status say of the fusions so far.
struct FusionRecords {
  std::vector<FusionRecord> fusions;
  std::vector<SightingRecord> sightings;
  double fusion_ms_sum = 0.0;
  bool last_covariance_ok = true;    // the last fusion's health check of P
  bool covariance_always_ok = true;  // every fusion's
  std::optional<double> last_min_pivot;  // of the last fusion that computed one (eigenvalue or LDLT pivot)
  std::int64_t latest_utime = 0;     // newest local map time fused (data time, us)
};

// What the loop thread knows of the map: a copy made by the worker after each task.
struct MapView {
  fusion::MapCounts counts;
  std::int64_t fusion_count = 0;
  std::int64_t latest_utime = 0;  // newest local map time fused (data time, us)
  runtime::CorrectedFrames frames;
  std::vector<std::array<float, 4>> endpoints;  // x1 y1 x2 y2 in W, m
  double last_fusion_ms = 0.0;
  double mean_fusion_ms = 0.0;
  bool covariance_ok = true;                    // the last fusion's health check
  std::optional<double> min_pivot;              // of the last fusion (LDLT pivot or eigenvalue)
};

class FusionContext {
 public:
  explicit FusionContext(fusion::GlobalMap map, mission::TrajectoryBook book = {}, FusionRecords records = {});

  // GlobalMap::fuse, then the book and the records learn what the map took.
  // Throws as GlobalMap::fuse does (fusion::InvalidInput, std::invalid_argument);
  // nothing is recorded then.
  std::vector<fusion::FusionReport> fuse(const LocalMapSnapshot& snapshot, double queue_wait_ms);
  // GlobalMap::add_sighting, recorded with its status; one that throws is
  // recorded as "rejected" and the exception goes on.
  fusion::SightingResult add_sighting(const fusion::RobotSighting& sighting, double queue_wait_ms);
  // The first robot joins with L = W (docs/design.md §5).
  void join_first_robot(int robot_id);

  MapView view() const;

  // trajectories/robot<N>.txt, trajectory.txt, map.json and map.svg (the graph
  // drawn when svg_graph) into out_dir, with lmf-offline's writers; returns the
  // fusion side of report.json ("source", "map", "global_covariance_always_ok",
  // "fusion_timing", "queue_wait_timing", "fusions", "sightings", "robots").
  // Throws std::runtime_error (or a filesystem error) when a file cannot be written.
  nlohmann::json write_outputs(const std::filesystem::path& out_dir, bool svg_graph) const;

  const fusion::GlobalMap& map() const { return map_; }
  const mission::TrajectoryBook& book() const { return book_; }
  const FusionRecords& records() const { return records_; }

 private:
  void record(const std::vector<fusion::FusionReport>& reports, double queue_wait_ms);

  fusion::GlobalMap map_;
  mission::TrajectoryBook book_;
  FusionRecords records_;
};

}  // namespace lmf::server
