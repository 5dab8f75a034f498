#include "lmf/io/occupancy_grid.hpp"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <fstream>
#include <limits>
#include <sstream>
#include <stdexcept>

namespace lmf::io {
namespace {

bool finite(const Eigen::Vector2d& p) { return std::isfinite(p.x()) && std::isfinite(p.y()); }

// Where beam i ends in W and whether it hit something; nullopt for a reading to skip.
struct Beam {
  Eigen::Vector2d end;
  bool hit = false;
};
std::optional<Beam> beam_in_world(const PosedScan& s, std::size_t i, double no_return_margin_m) {
  const LaserScan& scan = *s.scan;
  const double r = scan.ranges_m[i];
  if (!std::isfinite(r) || r <= 0.0) return std::nullopt;
  const double no_return_m =
      scan.max_range_m > 0.0 ? scan.max_range_m - no_return_margin_m : std::numeric_limits<double>::infinity();
  const bool hit = r < no_return_m;
  // A beam with no return saw free space up to the scanner's range.
  const double length = hit ? r : std::min(r, scan.max_range_m);
  const double angle = scan.beam_angle(i);
  const Eigen::Vector2d end_R(length * std::cos(angle), length * std::sin(angle));
  return Beam{s.x_WR.transform_point(end_R), hit};
}

// Calls visit(col, row) for every cell the segment a -> b crosses, in order from
// a's cell to b's cell, both included (Amanatides & Woo's traversal; a and b in
// cell units, i.e. (p - origin) / resolution).
template <typename Visit>
void for_each_cell_on_segment(const Eigen::Vector2d& a, const Eigen::Vector2d& b, Visit&& visit) {
  int col = static_cast<int>(std::floor(a.x()));
  int row = static_cast<int>(std::floor(a.y()));
  const int end_col = static_cast<int>(std::floor(b.x()));
  const int end_row = static_cast<int>(std::floor(b.y()));
  const Eigen::Vector2d d = b - a;
  const int step_col = d.x() > 0 ? 1 : -1;
  const int step_row = d.y() > 0 ? 1 : -1;
  constexpr double kInf = std::numeric_limits<double>::infinity();
  // Parameter t in [0, 1] along a -> b at the next vertical / horizontal cell border.
  double t_col = d.x() != 0.0 ? ((step_col > 0 ? col + 1 : col) - a.x()) / d.x() : kInf;
  double t_row = d.y() != 0.0 ? ((step_row > 0 ? row + 1 : row) - a.y()) / d.y() : kInf;
  const double dt_col = d.x() != 0.0 ? std::abs(1.0 / d.x()) : kInf;
  const double dt_row = d.y() != 0.0 ? std::abs(1.0 / d.y()) : kInf;
  const int steps = std::abs(end_col - col) + std::abs(end_row - row);
  visit(col, row);
  for (int i = 0; i < steps; ++i) {
    if (t_col < t_row) {
      col += step_col;
      t_col += dt_col;
    } else {
      row += step_row;
      t_row += dt_row;
    }
    visit(col, row);
  }
}

}  // namespace

std::optional<Eigen::Vector2i> OccupancyGrid::cell_of(const Eigen::Vector2d& p) const {
  const Eigen::Vector2d c = (p - origin) / resolution_m;
  if (!(c.x() >= 0.0 && c.y() >= 0.0 && c.x() < width && c.y() < height)) return std::nullopt;
  return Eigen::Vector2i(static_cast<int>(c.x()), static_cast<int>(c.y()));
}

Eigen::Vector2d OccupancyGrid::cell_center(int col, int row) const {
  return origin + resolution_m * Eigen::Vector2d(col + 0.5, row + 0.5);
}

std::size_t OccupancyGrid::count(GridCell value) const {
  return static_cast<std::size_t>(std::count(cells.begin(), cells.end(), value));
}

void OccupancyGridConfig::validate() const {
  if (!(resolution_m > 0.0) || !std::isfinite(resolution_m)) {
    throw std::invalid_argument("occupancy grid: resolution_m must be positive, not " + std::to_string(resolution_m));
  }
  if (!(margin_m >= 0.0) || !std::isfinite(margin_m)) {
    throw std::invalid_argument("occupancy grid: margin_m must be >= 0, not " + std::to_string(margin_m));
  }
}

OccupancyGrid make_occupancy_grid(const std::vector<PosedScan>& scans, const std::vector<WallSegment>& walls,
                                  const OccupancyGridConfig& config) {
  config.validate();
  // The box around every pose, beam end and wall.
  Eigen::Vector2d lo = Eigen::Vector2d::Constant(std::numeric_limits<double>::infinity());
  Eigen::Vector2d hi = -lo;
  const auto include = [&](const Eigen::Vector2d& p) {
    lo = lo.cwiseMin(p);
    hi = hi.cwiseMax(p);
  };
  for (const PosedScan& s : scans) {
    if (s.scan == nullptr) throw std::invalid_argument("occupancy grid: a scan is null");
    const Eigen::Vector2d robot(s.x_WR.x, s.x_WR.y);
    if (!finite(robot) || !std::isfinite(s.x_WR.phi)) {
      throw std::invalid_argument("occupancy grid: the scan at utime " + std::to_string(s.scan->utime) +
                                  " has a non-finite pose");
    }
    include(robot);
    for (std::size_t i = 0; i < s.scan->ranges_m.size(); ++i) {
      if (const auto beam = beam_in_world(s, i, config.no_return_margin_m)) include(beam->end);
    }
  }
  for (const WallSegment& w : walls) {
    if (!finite(w.start) || !finite(w.end)) throw std::invalid_argument("occupancy grid: a wall is not finite");
    include(w.start);
    include(w.end);
  }

  OccupancyGrid grid;
  grid.resolution_m = config.resolution_m;
  if (!(lo.x() <= hi.x())) return grid;  // nothing to draw
  const double res = config.resolution_m;
  // The origin on the resolution's lattice, so grids of one map line up.
  grid.origin = ((lo.array() - config.margin_m) / res).floor().matrix() * res;
  const Eigen::Vector2d size = ((hi.array() + config.margin_m - grid.origin.array()) / res).ceil().matrix();
  if (size.x() * size.y() > static_cast<double>(config.max_cells)) {
    throw std::invalid_argument("occupancy grid: " + std::to_string(size.x()) + " x " + std::to_string(size.y()) +
                                " cells exceed max_cells = " + std::to_string(config.max_cells) +
                                " (a coarser resolution, or poses far apart)");
  }
  grid.width = std::max(1, static_cast<int>(size.x()));
  grid.height = std::max(1, static_cast<int>(size.y()));
  grid.cells.assign(static_cast<std::size_t>(grid.width) * grid.height, GridCell::kUnknown);

  const auto to_cells = [&](const Eigen::Vector2d& p) -> Eigen::Vector2d { return (p - grid.origin) / res; };
  const auto set = [&](int col, int row, GridCell value) {
    // The box holds every end point, so the traversal stays inside; the check guards rounding.
    if (col < 0 || row < 0 || col >= grid.width || row >= grid.height) return;
    GridCell& cell = grid.cells[static_cast<std::size_t>(row) * grid.width + col];
    if (cell != GridCell::kOccupied) cell = value;
  };

  // Free: every cell a beam crosses, short of the cell of its return.
  for (const PosedScan& s : scans) {
    const Eigen::Vector2d robot = to_cells({s.x_WR.x, s.x_WR.y});
    for (std::size_t i = 0; i < s.scan->ranges_m.size(); ++i) {
      const auto beam = beam_in_world(s, i, config.no_return_margin_m);
      if (!beam) continue;
      const Eigen::Vector2d end = to_cells(beam->end);
      const Eigen::Vector2i end_cell(static_cast<int>(std::floor(end.x())), static_cast<int>(std::floor(end.y())));
      for_each_cell_on_segment(robot, end, [&](int col, int row) {
        if (beam->hit && col == end_cell.x() && row == end_cell.y()) return;
        set(col, row, GridCell::kFree);
      });
    }
  }
  // Occupied: the walls, over anything a beam passed.
  for (const WallSegment& w : walls) {
    for_each_cell_on_segment(to_cells(w.start), to_cells(w.end), [&](int col, int row) {
      if (col < 0 || row < 0 || col >= grid.width || row >= grid.height) return;
      grid.cells[static_cast<std::size_t>(row) * grid.width + col] = GridCell::kOccupied;
    });
  }
  return grid;
}

std::string ros_map_pgm(const OccupancyGrid& grid) {
  std::string out = "P5\n# lmf occupancy grid, " + std::to_string(grid.resolution_m) + " m/cell\n" +
                    std::to_string(grid.width) + " " + std::to_string(grid.height) + "\n255\n";
  const std::size_t header = out.size();
  out.resize(header + grid.cells.size());
  for (int row = 0; row < grid.height; ++row) {
    // The image's first line is the grid's top row (highest y).
    char* line = out.data() + header + static_cast<std::size_t>(grid.height - 1 - row) * grid.width;
    for (int col = 0; col < grid.width; ++col) {
      const GridCell c = grid.at(col, row);
      line[col] = static_cast<char>(c == GridCell::kOccupied ? kPgmOccupied
                                    : c == GridCell::kFree   ? kPgmFree
                                                             : kPgmUnknown);
    }
  }
  return out;
}

std::string ros_map_yaml(const OccupancyGrid& grid, const std::string& image_file) {
  char number[64];
  const auto fixed = [&](double v) {
    std::snprintf(number, sizeof number, "%.6f", v);
    return std::string(number);
  };
  std::ostringstream yaml;
  yaml << "image: " << image_file << "\n"
       << "resolution: " << fixed(grid.resolution_m) << "\n"
       << "origin: [" << fixed(grid.origin.x()) << ", " << fixed(grid.origin.y()) << ", 0.0]\n"
       << "negate: 0\n"
       << "occupied_thresh: 0.65\n"
       << "free_thresh: 0.196\n"
       << "mode: trinary\n";
  return yaml.str();
}

void write_ros_map(const OccupancyGrid& grid, const std::filesystem::path& dir, const std::string& name) {
  std::error_code error;
  std::filesystem::create_directories(dir, error);
  if (error) throw std::runtime_error("write_ros_map: cannot create " + dir.string() + ": " + error.message());
  const auto write = [](const std::filesystem::path& file, const std::string& data) {
    std::ofstream out(file, std::ios::binary);
    if (!out) throw std::runtime_error("write_ros_map: cannot open " + file.string());
    out.write(data.data(), static_cast<std::streamsize>(data.size()));
    if (!out) throw std::runtime_error("write_ros_map: cannot write " + file.string());
  };
  write(dir / (name + ".pgm"), ros_map_pgm(grid));
  write(dir / (name + ".yaml"), ros_map_yaml(grid, name + ".pgm"));
}

}  // namespace lmf::io
