// The simulated laser scanner: a SICK-like 180° planar scanner at the robot's centre.
//
// Beam i points at angle_min_rad + i * increment in the robot frame R, with
// angle_min_rad = -pi/2 and increment = beam_increment_for_180deg(num_beams)
// (pi/360 for the default 361 beams, as in the datasets). Each range is the exact
// distance r to the first wall or disc plus Gaussian noise of variance
// range_noise_sigma_m² + (range_noise_per_m r)² (many lasers state their accuracy
// as a constant or a share of the range, whichever is larger),
// clamped to [0, max_range_m]; a beam that hits nothing within max_range_m reads
// exactly max_range_m, which LaserScan treats as "no return".
#pragma once

#include <cstddef>
#include <vector>

#include "lmf/geometry/pose2.hpp"
#include "lmf/scan/laser_scan.hpp"
#include "lmf/sim/random.hpp"
#include "lmf/sim/ray_cast.hpp"

namespace lmf::sim {

struct LaserConfig {
  std::size_t num_beams = 361;       // over 180°, >= 2
  double range_noise_sigma_m = 0.05; // the paper's ±5 cm, >= 0
  double range_noise_per_m = 0.0;    // the range-proportional part (m per m), in [0, 0.1]
  double max_range_m = 80.0;         // > 0; SICK LMS-like long range: the world is closed, so every beam returns
  // Throws std::invalid_argument when out of range.
  void validate() const;
};

// One scan from the true robot pose x_WR. `obstacles` are discs in the world frame
// (other robots, people). The returned scan has utime 0 and an identity odometry pose;
// the caller fills them in. Draws num_beams normals from `rng` when the noise is non-zero
// (one per beam, hit or not, so the noise stream does not depend on the geometry).
LaserScan simulate_scan(const WallIndex& walls, const Pose2& x_WR, const LaserConfig& config,
                        const std::vector<Circle>& obstacles, Rng& rng);

}  // namespace lmf::sim
