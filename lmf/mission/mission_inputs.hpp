// What an offline (or replayed) mission is made of: each robot's scans, the
// robot-robot sightings, the robots that join with a known start, and the
// reference trajectories for scoring. Built from CARMEN logs (one per robot, or
// one log cut into N contiguous parts replayed as N simultaneous robots, as the
// paper did with one robot's recordings) or from an lmf-sim folder.
#pragma once

#include <cstdint>
#include <filesystem>
#include <map>
#include <string>
#include <vector>

#include <Eigen/Core>

#include "lmf/eval/map_error.hpp"
#include "lmf/geometry/pose2.hpp"
#include "lmf/geometry/stamped_pose.hpp"
#include "lmf/scan/laser_scan.hpp"

namespace lmf::mission {

struct RobotLog {
  int robot_id = 0;
  std::string name;                // e.g. the log file stem, "robot1"
  std::vector<LaserScan> scans;    // in time order
};

// Robot `observed` seen by robot `observer` at `utime`: x_AB with its noise.
struct SightingInput {
  int64_t utime = 0;
  int observer = 0;
  int observed = 0;
  Pose2 x_AB;
  Eigen::Matrix3d covariance = Eigen::Matrix3d::Zero();
};

struct MissionInputs {
  std::vector<RobotLog> robots;                        // the first one defines W
  std::vector<SightingInput> sightings;                // in time order
  std::map<int, std::vector<StampedPose>> reference;   // per robot, for scoring (may be empty)
  std::vector<eval::LineSegment> walls;                // true wall faces (simulator), for the map error
  std::string description;                             // one line for summaries
  std::vector<std::string> notes;                      // what reading found, one line each (the laser mounting)
};

// Noise added to the relation between robots (a sighting, or a start pose taken
// from the reference): Gaussian, seeded, independent per component.
struct SightingNoise {
  double sigma_xy_m = 0.05;
  double sigma_phi_rad = 0.02;
  uint64_t seed = 1;
  Eigen::Matrix3d covariance() const;
};

// One robot's recording, however it was read (a CARMEN log, a ROS bag).
struct RecordedLog {
  std::filesystem::path file;      // named in error messages
  std::string name;                // the robot's name ("belgioioso-noisy")
  std::vector<LaserScan> scans;    // in time order
  std::vector<std::string> notes;  // what reading found, one line each
};

// A CARMEN log read into a RecordedLog (notes: the laser mounting, "no return"
// readings, a cut last line). Throws the reader's errors.
RecordedLog read_carmen_recording(const std::filesystem::path& file);

// One robot per log, or `split` > 1 contiguous parts of a single log. With a
// reference (`t x y theta` or `index t x y theta`, matched to scans by time), the
// robots after the first join through a sighting by the first robot at their
// first scans (their relative start pose from the reference, plus noise), and
// the reference is kept for scoring. Throws std::invalid_argument for bad arguments and the
// readers' errors (naming file and line) for bad files.
MissionInputs load_logs(const std::vector<std::filesystem::path>& logs, int split,
                        const std::filesystem::path& reference, const SightingNoise& noise);
// The same for recordings already read.
MissionInputs load_recordings(std::vector<RecordedLog> logs, int split, const std::filesystem::path& reference,
                              const SightingNoise& noise);

// The same inputs without their sightings (--no-sightings): the first robot
// still defines W; every other one joins only when a local map of it is placed
// in the global map without one (docs/design.md §10, place recognition). A note
// says so.
void drop_sightings(MissionInputs& inputs);

// An lmf-sim folder: robotN.log, robotN.gt, sightings.json (true x_AB; noise is
// added here), for the robots mission.json lists (without mission.json: robot0,
// robot1, ... up to the first missing log). Robot 0 defines W; the others join
// through sightings.
MissionInputs load_sim_folder(const std::filesystem::path& dir, const SightingNoise& noise);

}  // namespace lmf::mission
