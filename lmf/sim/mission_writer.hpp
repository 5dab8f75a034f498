// Writing a simulated mission to a folder (the `lmf-sim` output):
//   robotN.log      CARMEN FLASER lines, N = robot id from 0; pose fields = noisy odometry;
//                   no-return beams read max_range_m (in mission.json and a `#` header line)
//   robotN.gt       `t x y theta`: the true pose x_WR at each scan's time (same timestamps)
//   walls.json      every wall face [x1, y1, x2, y2] (free space on the left), rooms, tables,
//                   the ring loop and its length, the seed
//   sightings.json  robot-robot sightings: time, observer, observed, true x_AB, range
//   world.svg       walls, rooms, each robot's true path in its own colour, start markers
//   mission.json    every parameter used and a per-robot summary
// Numbers are written with fixed precision (6 decimals; ranges 3), so the same mission
// gives byte-identical files.
#pragma once

#include <filesystem>

#include "lmf/sim/mission.hpp"

namespace lmf::sim {

// Creates `dir` if needed and writes the files above (overwriting them).
// Throws std::runtime_error when a file cannot be written.
void write_mission(const Mission& mission, const std::filesystem::path& dir);

// Only world.svg (also used by write_mission).
void write_world_svg(const Mission& mission, const std::filesystem::path& file);

}  // namespace lmf::sim
