// The occupancy grid: beams free what they cross, walls are occupied (and win
// over beams), no-return beams free up to the range, the ROS PGM/YAML files.
#include "lmf/io/occupancy_grid.hpp"

#include <cmath>
#include <filesystem>
#include <fstream>
#include <limits>
#include <sstream>
#include <stdexcept>
#include <string>

#include <gtest/gtest.h>

namespace lmf::io {
namespace {

// A scan of `n` beams over +-spread around the robot's x axis, all of one range.
LaserScan fan(double range_m, int n = 5, double spread_rad = 0.1, double max_range_m = 8.0) {
  LaserScan scan;
  scan.utime = 1;
  scan.angle_min_rad = -spread_rad;
  scan.angle_increment_rad = n > 1 ? 2.0 * spread_rad / (n - 1) : 0.0;
  scan.max_range_m = max_range_m;
  scan.ranges_m.assign(static_cast<std::size_t>(n), range_m);
  return scan;
}

GridCell cell_at(const OccupancyGrid& grid, const Eigen::Vector2d& p) {
  const auto c = grid.cell_of(p);
  EXPECT_TRUE(c.has_value()) << "(" << p.x() << ", " << p.y() << ") is outside the grid";
  return c ? grid.at(c->x(), c->y()) : GridCell::kUnknown;
}

TEST(OccupancyGrid, BeamsFreeTheWayToTheWallAndTheWallIsOccupied) {
  const LaserScan scan = fan(2.0);
  const OccupancyGrid grid =
      make_occupancy_grid({{Pose2(0.0, 0.0, 0.0), &scan}}, {{{2.0, -1.0}, {2.0, 1.0}}}, {.resolution_m = 0.1});
  for (double x = 0.05; x < 1.9; x += 0.1) EXPECT_EQ(cell_at(grid, {x, 0.02}), GridCell::kFree) << x;
  for (double y = -0.95; y < 1.0; y += 0.1) EXPECT_EQ(cell_at(grid, {2.02, y}), GridCell::kOccupied) << y;
  EXPECT_EQ(cell_at(grid, {2.35, 0.0}), GridCell::kUnknown);  // behind the wall
  EXPECT_EQ(cell_at(grid, {0.5, 0.9}), GridCell::kUnknown);   // beside the fan
  // Origin on the lattice, 0.5 m margin around the robot, the beam ends and the wall.
  EXPECT_NEAR(grid.origin.x(), -0.5, 1e-9);
  EXPECT_NEAR(grid.origin.y(), -1.5, 1e-9);
  EXPECT_EQ(grid.width, 30);
  EXPECT_EQ(grid.height, 30);
}

TEST(OccupancyGrid, BeamsAreCastFromTheScanPose) {
  const LaserScan scan = fan(1.0, 1, 0.0);
  // The robot at (5, 5) facing +y: the beam frees (5, 5.1 .. 5.9), not along +x.
  const OccupancyGrid grid = make_occupancy_grid({{Pose2(5.0, 5.0, M_PI / 2.0), &scan}}, {}, {.resolution_m = 0.1});
  EXPECT_EQ(cell_at(grid, {5.02, 5.55}), GridCell::kFree);
  EXPECT_EQ(cell_at(grid, {5.35, 5.02}), GridCell::kUnknown);
  EXPECT_EQ(cell_at(grid, {5.02, 6.02}), GridCell::kUnknown);  // the return's cell: no wall, not free
}

TEST(OccupancyGrid, NoReturnFreesUpToTheRangeAndAWallWinsOverABeam) {
  const LaserScan scan = fan(4.0, 1, 0.0, 4.0);  // a reading at the scanner's range: no return
  const OccupancyGrid grid =
      make_occupancy_grid({{Pose2(), &scan}}, {{{1.5, -0.45}, {1.5, 0.45}}}, {.resolution_m = 0.1});
  EXPECT_EQ(cell_at(grid, {3.95, 0.02}), GridCell::kFree);
  EXPECT_EQ(cell_at(grid, {1.52, 0.02}), GridCell::kOccupied);  // the beam passes the wall's cell
  EXPECT_EQ(grid.count(GridCell::kOccupied), 10u);
}

TEST(OccupancyGrid, DiagonalWallsAreConnected) {
  // A wall at 30 degrees: every cell it crosses, so the rasterised line has no gaps.
  const OccupancyGrid grid = make_occupancy_grid({}, {{{0.0, 0.0}, {3.0, std::tan(M_PI / 6.0) * 3.0}}},
                                                 {.resolution_m = 0.1, .margin_m = 0.2});
  for (double s = 0.0; s <= 3.0; s += 0.01) {
    EXPECT_EQ(cell_at(grid, {s, std::tan(M_PI / 6.0) * s}), GridCell::kOccupied) << s;
  }
}

TEST(OccupancyGrid, RejectsBadInput) {
  const LaserScan scan = fan(2.0);
  EXPECT_THROW(make_occupancy_grid({{Pose2(), nullptr}}, {}), std::invalid_argument);
  EXPECT_THROW(make_occupancy_grid({{Pose2(std::nan(""), 0.0, 0.0), &scan}}, {}), std::invalid_argument);
  EXPECT_THROW(make_occupancy_grid({}, {{{0.0, 0.0}, {std::numeric_limits<double>::infinity(), 0.0}}}),
               std::invalid_argument);
  EXPECT_THROW(make_occupancy_grid({}, {}, {.resolution_m = 0.0}), std::invalid_argument);
  EXPECT_THROW(make_occupancy_grid({}, {{{0.0, 0.0}, {1e5, 1e5}}}, {.resolution_m = 0.01}), std::invalid_argument);
  EXPECT_EQ(make_occupancy_grid({}, {}).cells.size(), 0u);
}

TEST(OccupancyGrid, PgmIsP5WithTheTopRowFirst) {
  // One wall cell at the bottom-left of a 3 x 2 grid.
  OccupancyGrid grid;
  grid.resolution_m = 0.5;
  grid.width = 3;
  grid.height = 2;
  grid.cells = {GridCell::kOccupied, GridCell::kFree, GridCell::kUnknown,
                GridCell::kFree, GridCell::kFree, GridCell::kFree};
  const std::string pgm = ros_map_pgm(grid);
  ASSERT_EQ(pgm.rfind("P5\n", 0), 0u);
  const std::size_t pixels = pgm.size() - 6;
  EXPECT_NE(pgm.find("\n3 2\n255\n"), std::string::npos);
  const auto px = [&](std::size_t i) { return static_cast<uint8_t>(pgm[pixels + i]); };
  EXPECT_EQ(px(0), kPgmFree);  // top row = grid row 1
  EXPECT_EQ(px(3), kPgmOccupied);
  EXPECT_EQ(px(4), kPgmFree);
  EXPECT_EQ(px(5), kPgmUnknown);
}

TEST(OccupancyGrid, WritesRosMapFiles) {
  OccupancyGrid grid;
  grid.resolution_m = 0.05;
  grid.origin = {-1.25, 2.5};
  grid.width = 4;
  grid.height = 3;
  grid.cells.assign(12, GridCell::kFree);
  const auto dir = std::filesystem::path(::testing::TempDir()) / ("lmf_grid_" + std::to_string(::getpid()));
  write_ros_map(grid, dir, "floor");
  std::ifstream yaml_file(dir / "floor.yaml");
  std::stringstream yaml;
  yaml << yaml_file.rdbuf();
  EXPECT_EQ(yaml.str(),
            "image: floor.pgm\nresolution: 0.050000\norigin: [-1.250000, 2.500000, 0.0]\nnegate: 0\n"
            "occupied_thresh: 0.65\nfree_thresh: 0.196\nmode: trinary\n");
  EXPECT_EQ(std::filesystem::file_size(dir / "floor.pgm"), ros_map_pgm(grid).size());
  std::filesystem::remove_all(dir);
  EXPECT_THROW(write_ros_map(grid, "/proc/lmf-no-such-dir"), std::runtime_error);
}

}  // namespace
}  // namespace lmf::io
