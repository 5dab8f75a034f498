// An occupancy grid of a finished mission, as ROS map_server reads it.
//
// Free space is what the laser saw through: every cell a beam crosses, from the
// robot to the cell of its return, cast from the scan's corrected pose (a beam
// with no return is free up to the scanner's range). Occupied cells are the
// map's wall segments, rasterised; a wall always wins over a beam that passes
// it. Every other cell is unknown. Cells are squares of `resolution_m` in the
// map frame W; cell (col, row) covers
//   [origin.x + col * res, origin.x + (col + 1) * res) x [origin.y + row * res, ...),
// row 0 at the bottom (lowest y), as the YAML's origin means it.
//
// Output (write_ros_map): NAME.pgm (binary P5, 8 bit, top row first: occupied
// 0, free 254, unknown 205) and NAME.yaml (image, resolution, origin [x, y,
// yaw], negate 0, occupied_thresh 0.65, free_thresh 0.196, mode trinary).
#pragma once

#include <cstddef>
#include <cstdint>
#include <filesystem>
#include <optional>
#include <string>
#include <vector>

#include <Eigen/Core>

#include "lmf/geometry/pose2.hpp"
#include "lmf/scan/laser_scan.hpp"

namespace lmf::io {

enum class GridCell : uint8_t { kUnknown, kFree, kOccupied };

struct OccupancyGrid {
  double resolution_m = 0.05;
  Eigen::Vector2d origin = Eigen::Vector2d::Zero();  // W position of cell (0, 0)'s lower-left corner
  int width = 0;                                     // columns (x)
  int height = 0;                                    // rows (y)
  std::vector<GridCell> cells;                       // row-major from row 0, width * height

  GridCell at(int col, int row) const { return cells[static_cast<std::size_t>(row) * width + col]; }
  // The cell holding a W point; nullopt outside the grid.
  std::optional<Eigen::Vector2i> cell_of(const Eigen::Vector2d& p) const;
  Eigen::Vector2d cell_center(int col, int row) const;
  std::size_t count(GridCell value) const;
};

// A scan with the pose it was taken at, x_WR (the corrected trajectory).
struct PosedScan {
  Pose2 x_WR;
  const LaserScan* scan = nullptr;
};

// A wall of the map in W (map.json's segment start and end).
struct WallSegment {
  Eigen::Vector2d start = Eigen::Vector2d::Zero();
  Eigen::Vector2d end = Eigen::Vector2d::Zero();
};

struct OccupancyGridConfig {
  double resolution_m = 0.05;
  double margin_m = 0.5;               // unknown border around everything drawn
  double no_return_margin_m = 0.1;     // a reading >= max_range_m - this is "no return" (as the extraction)
  std::size_t max_cells = 100'000'000; // a larger grid is refused (bad poses, or a resolution too fine)
  // Throws std::invalid_argument for a non-positive resolution or a negative margin.
  void validate() const;
};

// The grid over every scan's beams and every wall (plus the margin). Throws
// std::invalid_argument for a bad config, a scan pointer that is null, a
// non-finite pose or wall, or a grid of more than max_cells.
OccupancyGrid make_occupancy_grid(const std::vector<PosedScan>& scans, const std::vector<WallSegment>& walls,
                                  const OccupancyGridConfig& config = {});

// The P5 image (header and pixels) and the YAML text of write_ros_map.
std::string ros_map_pgm(const OccupancyGrid& grid);
std::string ros_map_yaml(const OccupancyGrid& grid, const std::string& image_file);

// Writes DIR/NAME.pgm and DIR/NAME.yaml (DIR is created). Throws std::runtime_error on I/O errors.
void write_ros_map(const OccupancyGrid& grid, const std::filesystem::path& dir, const std::string& name = "map");

// The pixel values of write_ros_map (ROS trinary: p = (255 - value) / 255).
inline constexpr uint8_t kPgmOccupied = 0;
inline constexpr uint8_t kPgmFree = 254;
inline constexpr uint8_t kPgmUnknown = 205;

}  // namespace lmf::io
