// The whole mapping mission in one process, deterministic and without LCM:
// one LocalMap per robot and the GlobalMap, fed in lockstep in time order —
// each shipped local map is fused before the next scan — so a run is exactly
// repeatable. lmf-offline wraps it; the distributed system is checked against it.
//
// The only clock read is std::chrono::steady_clock, to measure per-scan and
// per-fusion times for the report; no decision depends on it.
#pragma once

#include <cstdint>
#include <map>
#include <optional>
#include <string>
#include <utility>
#include <vector>

#include "lmf/eval/increment_chain.hpp"
#include "lmf/fusion/global_map.hpp"
#include "lmf/geometry/stamped_pose.hpp"
#include "lmf/local_map/local_map.hpp"
#include "lmf/mission/mission_inputs.hpp"
#include "lmf/mission/trajectory_book.hpp"

namespace lmf::mission {

struct MissionConfig {
  LocalMapConfig local_map;
  fusion::GlobalMapConfig global_map;
  SightingNoise sighting_noise;  // used when building the inputs
  void validate() const;         // throws std::invalid_argument naming the field
};

// Order statistics of a set of durations (ms).
struct TimingStats {
  std::size_t count = 0;
  double p50_ms = 0.0;
  double p99_ms = 0.0;
  double max_ms = 0.0;
  double mean_ms = 0.0;
};
TimingStats timing_stats(std::vector<double> durations_ms);

// One shipped local map's end pose x_LR against the reference (issue of
// consistency: the fusion trusts P_RR), when the inputs have a reference.
struct LocalMapConsistency {
  std::int64_t seq = 0;
  double error_m = 0.0;    // |translation| of x̂_LR ⊖ x_LR(true)
  double error_rad = 0.0;  // |heading| of it
  double nees = 0.0;       // with P_RR (3 dof; mean 3 when consistent)
};

// One fusion's effect on the robot's frame L_r against the reference, when the
// inputs have one: the frame's error as the map predicted it (before the
// registration and the update) and as fused, in W aligned to the reference by
// the first robot's first frame (W). Errors include the drift
// accumulated before the fusion; their difference is what the fusion did.
struct FusionFrameCheck {
  int robot_id = 0;
  std::int64_t seq = 0;
  double before_m = 0.0;
  double before_rad = 0.0;
  double after_m = 0.0;
  double after_rad = 0.0;
};

// The steps of the match chains scored per robot (RobotResult::match_chain_nees):
// about 5 m of travel at the half-metre spacing of laser logs, a few times the
// reach of one scan's own error (the last four scans the matcher keeps).
inline constexpr int kMatchChainSteps = 10;

struct RobotResult {
  int robot_id = 0;
  std::string name;
  bool joined = false;
  std::optional<fusion::RobotJoin> join;  // how and at which local map it joined
  std::size_t scans = 0;
  std::size_t local_maps_shipped = 0;
  std::size_t local_maps_fused = 0;
  std::size_t segments_seen_through = 0;  // local map segments removed on free-space evidence
  std::vector<StampedPose> trajectory;  // final estimate of every scan pose in W (joined robots)
  std::vector<double> scan_times_ms;    // per-scan local map time
  TimingStats scan_timing;
  bool covariance_always_ok = true;     // every scan's covariance check passed
  std::string first_covariance_problem;
  std::vector<LocalMapConsistency> local_map_consistency;  // shipped maps with a reference and P_RR > 0
  std::size_t scans_skipped = 0;        // scans the motion filter took as no new view (dead-reckoned)
  std::size_t scan_matches = 0;         // scans whose motion came from the scan match
  std::size_t match_fallbacks = 0;      // scans whose match was tried and failed (odometry alone)
  std::size_t match_escalations = 0;    // scans whose search escalated to its wider window ...
  std::size_t matches_from_escalation = 0;  // ... and whose match is the wider window's
  std::vector<double> match_nees;       // per match with a reference: NEES of x_AB with its covariance (3 dof)
  // Per chain of kMatchChainSteps consecutive matches with a reference at both
  // ends: NEES of the composed increments (lmf/eval/increment_chain.hpp), where
  // an error of one scan's own cancels and a drift does not.
  std::vector<double> match_chain_nees;
  OdometryErrorModel odometry_model;    // the agent's learned model at the end
  OdometryLearningStats odometry_learning;
  // The laser's point noise the registration used at the end: σ_i² =
  // point_sigma_m² + (range_noise_per_m r)², and how many registrations
  // measured range_noise_per_m (0: the configuration's value, not measured).
  double point_sigma_m = 0.0;
  double range_noise_per_m = 0.0;
  std::size_t range_noise_matches = 0;
};

struct SightingEvent {
  SightingInput input;
  fusion::SightingStatus status = fusion::SightingStatus::kPending;
};

struct MissionResult {
  std::vector<RobotResult> robots;
  std::vector<fusion::FusionReport> fusions;  // in fusion order
  std::vector<FusionFrameCheck> fusion_frame_checks;  // fusions with a reference, in fusion order
  std::vector<SightingEvent> sightings;
  TimingStats fusion_timing;
  bool global_covariance_always_ok = true;    // every fusion's health check passed
};

class OfflineMission {
 public:
  // Throws std::invalid_argument for an invalid config or inputs (no robots,
  // duplicate ids).
  OfflineMission(MissionConfig config, MissionInputs inputs);

  // Runs every scan and sighting in time order (scans before sightings at equal
  // times), ships and fuses each local map as its policy says, and at the end
  // ships the unfinished local maps too. Call once.
  MissionResult run();

  const fusion::GlobalMap& global_map() const { return global_map_; }
  const MissionInputs& inputs() const { return inputs_; }

 private:
  struct Agent {
    RobotLog* log = nullptr;
    LocalMap local_map;
    std::size_t next_scan = 0;
    // Per scan k so far: the match's x_{k−1,k} (std::nullopt where there was
    // none) and the reference pose, for RobotResult::match_chain_nees.
    std::vector<std::optional<eval::RelativePose>> matched_steps;
    std::vector<std::optional<Pose2>> reference_poses;
  };

  void process_scan(Agent& agent, RobotResult& result);
  void ship(Agent& agent, RobotResult& result);
  void check_consistency(const LocalMapSnapshot& snapshot, RobotResult& result) const;
  void check_fusion_frame(const fusion::FusionReport& report);
  // The reference pose of a robot at a scan time (nullopt without one).
  std::optional<Pose2> reference_pose(int robot_id, std::int64_t utime) const;
  void record(const std::vector<fusion::FusionReport>& reports);
  void apply_sighting(const SightingInput& sighting);

  MissionConfig config_;
  MissionInputs inputs_;
  fusion::GlobalMap global_map_;
  std::vector<Agent> agents_;
  TrajectoryBook trajectories_;
  MissionResult result_;
  // For the fusion frame checks: each shipped map's first scan time (its frame
  // L_r is the robot's pose then), and W in the reference's frame (the first
  // robot's first frame, which run() makes W).
  std::map<std::pair<int, std::int64_t>, std::int64_t> frame_utimes_;
  std::optional<Pose2> world_in_reference_;
  bool ran_ = false;
};

}  // namespace lmf::mission
