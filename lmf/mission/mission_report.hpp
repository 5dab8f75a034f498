// Scoring and reporting of a finished mission: ATE/RPE against the reference,
// the odometry-only baseline, per-scan and per-fusion timings, the output files
// of lmf-offline (trajectories, map, report.json) and its one-screen summary.
#pragma once

#include <filesystem>
#include <map>
#include <optional>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "lmf/eval/trajectory_error.hpp"
#include "lmf/fusion/map_export.hpp"
#include "lmf/mission/offline_mission.hpp"

namespace lmf::mission {

struct RobotScore {
  int robot_id = 0;
  eval::AbsoluteError ate;         // this robot alone, aligned on its own
  eval::RelativeError rpe_1m;
  eval::RelativeError rpe_10m;
  eval::AbsoluteError odometry_ate;  // the raw odometry of its scans, aligned on its own
};

struct MissionScore {
  eval::AbsoluteError ate;   // all joined robots together, one rigid alignment (one map frame)
  eval::RelativeError rpe_1m;   // pooled over robots
  eval::RelativeError rpe_10m;
  std::vector<RobotScore> robots;
  std::optional<eval::MapError> map;  // against the true walls, when the inputs have them
};

// An agent's odometry model (learned or configured) as a JSON object.
nlohmann::json odometry_model_json(const OdometryErrorModel& model, const OdometryLearningStats& stats);

// One fusion's report as a JSON object (report.json of lmf-offline and lmf-server).
nlohmann::json fusion_report_json(const fusion::FusionReport& report);

// The pieces of report.json that lmf-offline and lmf-server share.
nlohmann::json timing_json(const TimingStats& timing);
nlohmann::json map_counts_json(const fusion::MapCounts& counts);
nlohmann::json sighting_json(std::int64_t utime, int observer, int observed, const char* status);

// "joined", "joined_approximately", "pending", "ignored".
const char* sighting_status_name(fusion::SightingStatus status);

// FusionReport::covariance_ok: false when the fusion's covariance check saw a
// negative eigenvalue (or, without one, LDLT pivot) beyond rounding (-1e-9).
bool covariance_ok(const fusion::FusionReport& report);

// Scores the joined robots that have a reference; nullopt when none has.
std::optional<MissionScore> score_mission(const MissionResult& result, const MissionInputs& inputs,
                                          const fusion::GlobalMap& map);

// Writes OUT/trajectory.txt (all robots, time order) and OUT/trajectories/NAME.txt.
void write_trajectories(const std::filesystem::path& out,
                        const std::map<std::string, std::vector<StampedPose>>& trajectories);

// Writes OUT/map.json and OUT/map.svg (with the trajectories drawn, in `svg`'s layers).
void write_map_files(const std::filesystem::path& out, const fusion::GlobalMap& map,
                     const std::map<std::string, std::vector<StampedPose>>& trajectories,
                     const fusion::MapSvgOptions& svg = {});

// Writes OUT/trajectory.txt, OUT/trajectories/NAME.txt, OUT/map.json,
// OUT/map.svg and OUT/report.json. Throws std::runtime_error on I/O errors.
void write_mission_outputs(const std::filesystem::path& out, const OfflineMission& mission,
                           const MissionResult& result, const std::optional<MissionScore>& score,
                           const fusion::MapSvgOptions& svg = {});

// One line: how many fusions moved their robot's frame noticeably (0.1 m or
// 1°) closer to the reference or farther from it, and the farthest.
std::string describe_fusion_frame_checks(const std::vector<FusionFrameCheck>& checks);

// The one-screen summary.
std::string summarize(const OfflineMission& mission, const MissionResult& result,
                      const std::optional<MissionScore>& score);

}  // namespace lmf::mission
