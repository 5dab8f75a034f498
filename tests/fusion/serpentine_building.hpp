// A synthetic building for the fusion and server-state benchmarks: 12 m cells
// along a serpentine of 20 cells per row, 30 walls of 1.2 m in each cell (a
// 6 x 5 grid, 2 m apart, in four directions). A robot fusing one local map per
// cell (the new cell's walls plus 3 of the previous one seen again) grows a
// global map whose covariance is dense and correlated, as in a real run.
#pragma once

#include <cmath>
#include <cstdint>
#include <random>
#include <vector>

#include <Eigen/Core>

#include "fusion/synthetic_maps.hpp"
#include "lmf/geometry/pose2.hpp"
#include "lmf/local_map/local_map_snapshot.hpp"

namespace lmf::fusion::synthetic {

inline constexpr double kSerpentineCell = 12.0;
inline constexpr int kSerpentineColumns = 20;
inline constexpr int kWallsPerCell = 30;

// Cell i of the serpentine: its centre, and the heading towards cell i + 1.
inline Pose2 serpentine_cell_frame(int i) {
  auto centre = [](int c) {
    const int row = c / kSerpentineColumns;
    const int col = row % 2 == 0 ? c % kSerpentineColumns : kSerpentineColumns - 1 - c % kSerpentineColumns;
    return Eigen::Vector2d(kSerpentineCell * col, kSerpentineCell * row);
  };
  const Eigen::Vector2d a = centre(i);
  const Eigen::Vector2d b = centre(i + 1);
  return {a.x(), a.y(), std::atan2(b.y() - a.y(), b.x() - a.x())};
}

// The kWallsPerCell walls of cell i, in W.
inline std::vector<Wall> serpentine_cell_walls(int i) {
  const Pose2 c = serpentine_cell_frame(i);
  std::vector<Wall> walls;
  for (int w = 0; w < kWallsPerCell; ++w) {
    const double x = -5.0 + 2.0 * (w % 6);
    const double y = -4.0 + 2.0 * (w / 6);
    const double phi = (M_PI / 2) * ((w * 7 + i * 3) % 4) - M_PI / 2;
    walls.push_back({Pose2(c.x + x, c.y + y, wrap_angle(phi)), 1.2});
  }
  return walls;
}

// The walls robot 0 sees in cell `cell` while the map grows: all of the
// cell's, then the first 3 of the previous cell's again.
inline std::vector<Wall> serpentine_growth_walls(int cell) {
  std::vector<Wall> seen = serpentine_cell_walls(cell);
  if (cell > 0) {
    const std::vector<Wall> previous = serpentine_cell_walls(cell - 1);
    seen.insert(seen.end(), previous.begin(), previous.begin() + 3);
  }
  return seen;
}

// Robot 0's local map number `cell` of the walls `seen`: frame L at the cell's
// centre, the robot ending at the next cell's centre, estimates drawn from the
// snapshot's covariance with `rng`.
inline LocalMapSnapshot serpentine_snapshot(int cell, const std::vector<Wall>& seen, std::mt19937& rng) {
  const Pose2 x_WL = serpentine_cell_frame(cell);
  return make_snapshot(0, cell, x_WL, between(x_WL, serpentine_cell_frame(cell + 1)), seen, {}, &rng);
}

// The local map of cell `cell` while the map grows.
inline LocalMapSnapshot serpentine_growth_snapshot(int cell, std::mt19937& rng) {
  return serpentine_snapshot(cell, serpentine_growth_walls(cell), rng);
}

}  // namespace lmf::fusion::synthetic
