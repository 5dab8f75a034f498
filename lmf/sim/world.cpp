#include "lmf/sim/world.hpp"

#include <algorithm>
#include <cmath>
#include <map>
#include <numbers>
#include <stdexcept>
#include <string>
#include <utility>

#include "lmf/common/config_check.hpp"
#include "lmf/sim/random.hpp"

namespace lmf::sim {
namespace {

// The layout is built on an integer grid of decimetres, so boxes meet exactly and the
// wall extraction below is exact.
constexpr double kCell = 0.1;  // m per grid unit

int to_dm(double m) { return static_cast<int>(std::lround(m / kCell)); }
double to_m(int dm) { return kCell * dm; }

struct IBox {
  int x0, y0, x1, y1;  // [x0, x1] x [y0, y1] in dm
};

Box to_box(const IBox& b) { return {{to_m(b.x0), to_m(b.y0)}, {to_m(b.x1), to_m(b.y1)}}; }

struct DoorPlan {
  int dx;          // door centre x (dm)
  int corridor_y;  // centreline y of the corridor it opens on (dm)
  int inside_y;    // y of the room-inside node (dm)
  int room;        // index into rooms
};

// A horizontal row of rooms along a corridor (the corridors with rooms all run along x).
struct RowSpec {
  int x_begin, x_end;  // extent available for rooms (dm)
  int corridor_y;      // corridor centreline (dm)
  int side;            // +1: rooms north of the corridor, -1: south
  int min_depth, max_depth;
  std::vector<std::pair<int, int>> door_zones;  // allowed door-centre x ranges (dm, inclusive)
};

class Builder {
 public:
  Builder(const WorldConfig& config, uint64_t seed) : c_(config), rng_(derive_seed(seed, 0x57'4F'52'4CULL)) {
    w_ = to_dm(c_.corridor_width_m);
    hw_ = w_ / 2;
    t_ = to_dm(c_.wall_thickness_m);
    door_ = to_dm(c_.door_width_m);
    lx_ = to_dm(c_.ring_length_m);
    ly_ = to_dm(c_.ring_width_m);
  }

  World build(uint64_t seed) {
    World world;
    world.seed = seed;
    world.config = c_;

    // Seeded positions: the cross corridor and the side corridors (on whole metres).
    xc_ = 10 * rng_.uniform_int((lx_ * 2 / 5 + 9) / 10, (lx_ * 3 / 5) / 10);
    ys_ = 10 * rng_.uniform_int((ly_ * 2 / 5 + 9) / 10, (ly_ * 3 / 5) / 10);
    stub_len_ = to_dm(c_.side_corridor_length_m);
    east_stub_ = rng_.bernoulli(0.5);
    ye_ = 10 * rng_.uniform_int((ly_ * 3 / 10 + 9) / 10, (ly_ * 7 / 10) / 10);
    east_len_ = 10 * rng_.uniform_int(6, 10);

    // Corridors.
    add_corridor({-hw_, -hw_, lx_ + hw_, hw_});              // south side of the ring
    add_corridor({-hw_, ly_ - hw_, lx_ + hw_, ly_ + hw_});   // north side
    add_corridor({-hw_, -hw_, hw_, ly_ + hw_});              // west side
    add_corridor({lx_ - hw_, -hw_, lx_ + hw_, ly_ + hw_});   // east side
    add_corridor({xc_ - hw_, hw_, xc_ + hw_, ly_ - hw_});    // cross corridor
    const int west_end = -hw_ - stub_len_;
    add_corridor({west_end, ys_ - hw_, -hw_, ys_ + hw_});
    const int east_end = lx_ + hw_ + east_len_;
    if (east_stub_) add_corridor({lx_ + hw_, ye_ - hw_, east_end, ye_ + hw_});

    // Door fronts keep 1.5 m from corners and junctions so the robots' turns stay separate.
    const int k = 15;
    const std::vector<std::pair<int, int>> ring_zones = {{k, xc_ - k}, {xc_ + k, lx_ - k}};
    const int room_min_depth = 40;
    const int room_max_depth = 60;
    // Outside the ring (south and north), inside the ring (both long sides), the side corridors.
    add_room_row({-hw_, lx_ + hw_, 0, -1, room_min_depth, room_max_depth, ring_zones});
    add_room_row({-hw_, lx_ + hw_, ly_, +1, room_min_depth, room_max_depth, ring_zones});
    const int inner_depth = std::min(room_max_depth, (ly_ - 2 * (hw_ + t_) - 20) / 2);
    const int inner_min = std::min(room_min_depth, inner_depth);
    for (const auto& [xa, xb] : std::vector<std::pair<int, int>>{{hw_ + t_, xc_ - hw_ - t_}, {xc_ + hw_ + t_, lx_ - hw_ - t_}}) {
      add_room_row({xa, xb, 0, +1, inner_min, inner_depth, ring_zones});
      add_room_row({xa, xb, ly_, -1, inner_min, inner_depth, ring_zones});
    }
    const int west_dead_end = west_end + 15;
    const std::vector<std::pair<int, int>> west_zones = {{west_dead_end + 10, -k}};
    add_room_row({west_end, -hw_ - t_, ys_, +1, room_min_depth, room_max_depth, west_zones});
    add_room_row({west_end, -hw_ - t_, ys_, -1, room_min_depth, room_max_depth, west_zones});
    const int east_dead_end = east_end - 15;
    if (east_stub_) {
      const std::vector<std::pair<int, int>> east_zones = {{lx_ + k, east_dead_end - 10}};
      // Nothing else lies east of the ring, so these rooms take the full depth range.
      add_room_row({lx_ + hw_ + t_, east_end, ye_, +1, room_min_depth, room_max_depth, east_zones});
      add_room_row({lx_ + hw_ + t_, east_end, ye_, -1, room_min_depth, room_max_depth, east_zones});
    }

    rasterize(world);
    extract_walls(world);
    build_graph(world, west_dead_end, east_dead_end);

    for (const auto& b : corridors_) world.corridors.push_back(to_box(b));
    for (const auto& b : tables_) world.tables.push_back(to_box(b));
    world.rooms = rooms_;
    world.loop = {{0.0, 0.0}, {to_m(lx_), 0.0}, {to_m(lx_), to_m(ly_)}, {0.0, to_m(ly_)}};
    world.loop_length_m = 2.0 * (to_m(lx_) + to_m(ly_));  // docs/design.md §9: a loop of 100 m or more

    const double pi = std::numbers::pi;
    world.start_spots = {
        {{4.0, 0.0}, 0.0},                                 // robot 0: south corridor, eastwards
        {{9.0, 0.0}, 0.0},                                 // robot 1: 5 m ahead of robot 0
        {{to_m(lx_) - 4.0, to_m(ly_)}, pi},                // robot 2: north corridor, westwards
        {{to_m(xc_), to_m(ly_) / 2.0}, pi / 2.0},          // cross corridor, northwards
        {{to_m(lx_), 3.0}, pi / 2.0},                      // east side, northwards
        {{to_m(west_end) + 3.0, to_m(ys_)}, 0.0},          // west corridor, eastwards
        {{to_m(lx_) - 4.0, 0.0}, pi},                      // south corridor, westwards
        {{4.0, to_m(ly_)}, 0.0},                           // north corridor, eastwards
    };
    return world;
  }

 private:
  void add_corridor(const IBox& b) {
    corridors_.push_back(b);
    free_.push_back(b);
  }

  void add_room_row(const RowSpec& row) {
    const int face = row.corridor_y + row.side * hw_;  // the corridor's wall face
    const int near = face + row.side * t_;             // the room's wall face towards the corridor
    const int min_w = 35;
    const int max_w = 60;
    int x = row.x_begin;
    while (x + min_w <= row.x_end) {
      int w = rng_.uniform_int(min_w, max_w);
      if (x + w > row.x_end || row.x_end - (x + w + t_) < min_w) w = row.x_end - x;
      const int depth = rng_.uniform_int(row.min_depth, row.max_depth);
      const bool exists = rng_.bernoulli(c_.room_probability);
      // The door centre keeps 0.8 m from the side walls (the robot drives straight in).
      int lo = x + 8;
      int hi = x + w - 8;
      std::vector<std::pair<int, int>> options;
      for (const auto& [za, zb] : row.door_zones) {
        const int a = std::max(lo, za);
        const int b = std::min(hi, zb);
        if (a <= b) options.emplace_back(a, b);
      }
      int total = 0;
      for (const auto& [a, b] : options) total += b - a + 1;
      const int pick = total > 0 ? rng_.uniform_int(0, total - 1) : 0;
      const bool table = rng_.bernoulli(c_.table_probability);
      const double table_u = rng_.uniform01();
      if (exists && total > 0) {
        int dx = 0;
        int rest = pick;
        for (const auto& [a, b] : options) {
          if (rest <= b - a) {
            dx = a + rest;
            break;
          }
          rest -= b - a + 1;
        }
        const int far = near + row.side * depth;
        IBox room{x, std::min(near, far), x + w, std::max(near, far)};
        free_.push_back(room);
        free_.push_back({dx - door_ / 2, std::min(face, near), dx - door_ / 2 + door_, std::max(face, near)});
        Room r;
        r.box = to_box(room);
        r.door_center = {to_m(dx - door_ / 2) + 0.5 * c_.door_width_m, to_m(face) + 0.5 * row.side * c_.wall_thickness_m};
        // A free-standing table 1.6 m x 0.8 m, 0.4 m from the back wall, clear of the door's line.
        const int tw = 16;
        const int td = 8;
        if (table && w >= tw + 6) {
          const int tx = x + 3 + static_cast<int>(std::floor(table_u * (w - 6 - tw)));
          const int back = far - row.side * 4;
          const int front = back - row.side * td;
          tables_.push_back({tx, std::min(back, front), tx + tw, std::max(back, front)});
          r.has_table = true;
        }
        doors_.push_back({dx, row.corridor_y, near + row.side * 14, static_cast<int>(rooms_.size())});
        rooms_.push_back(r);
      }
      x += w + t_;
    }
  }

  void rasterize(World& world) {
    int x0 = 0, y0 = 0, x1 = 0, y1 = 0;
    for (const auto& b : free_) {
      x0 = std::min(x0, b.x0);
      y0 = std::min(y0, b.y0);
      x1 = std::max(x1, b.x1);
      y1 = std::max(y1, b.y1);
    }
    ox_ = x0 - 2;
    oy_ = y0 - 2;
    cols_ = x1 - x0 + 4;
    rows_ = y1 - y0 + 4;
    grid_.assign(static_cast<std::size_t>(cols_) * rows_, 0);
    auto fill = [&](const IBox& b, uint8_t v) {
      for (int j = b.y0 - oy_; j < b.y1 - oy_; ++j)
        for (int i = b.x0 - ox_; i < b.x1 - ox_; ++i) grid_[static_cast<std::size_t>(j) * cols_ + i] = v;
    };
    for (const auto& b : free_) fill(b, 1);
    for (const auto& b : tables_) fill(b, 0);
    world.set_free_raster({to_m(ox_), to_m(oy_)}, kCell, cols_, rows_, grid_);
    world.bounds = {{to_m(x0), to_m(y0)}, {to_m(x1), to_m(y1)}};
  }

  bool free_at(int i, int j) const {
    if (i < 0 || j < 0 || i >= cols_ || j >= rows_) return false;
    return grid_[static_cast<std::size_t>(j) * cols_ + i] != 0;
  }

  // Every cell edge between a free and an occupied cell is a piece of a wall face; runs of
  // pieces on one line with the same orientation merge into one segment.
  void extract_walls(World& world) const {
    auto emit = [&](int ax, int ay, int bx, int by) {
      world.walls.push_back({{to_m(ax + ox_), to_m(ay + oy_)}, {to_m(bx + ox_), to_m(by + oy_)}});
    };
    // Horizontal edges on grid line j (between rows j-1 and j).
    for (int j = 0; j <= rows_; ++j) {
      int run_start = -1;
      int run_kind = 0;  // +1: free below (face runs towards -x), -1: free above (towards +x)
      for (int i = 0; i <= cols_; ++i) {
        int kind = 0;
        if (i < cols_) {
          const bool below = free_at(i, j - 1);
          const bool above = free_at(i, j);
          if (below && !above) kind = +1;
          if (above && !below) kind = -1;
        }
        if (kind != run_kind) {
          if (run_kind == +1) emit(i, j, run_start, j);
          if (run_kind == -1) emit(run_start, j, i, j);
          run_start = i;
          run_kind = kind;
        }
      }
    }
    // Vertical edges on grid line i (between columns i-1 and i).
    for (int i = 0; i <= cols_; ++i) {
      int run_start = -1;
      int run_kind = 0;  // +1: free on the left (face runs towards +y), -1: free on the right (-y)
      for (int j = 0; j <= rows_; ++j) {
        int kind = 0;
        if (j < rows_) {
          const bool left = free_at(i - 1, j);
          const bool right = free_at(i, j);
          if (left && !right) kind = +1;
          if (right && !left) kind = -1;
        }
        if (kind != run_kind) {
          if (run_kind == +1) emit(i, run_start, i, j);
          if (run_kind == -1) emit(i, j, i, run_start);
          run_start = j;
          run_kind = kind;
        }
      }
    }
  }

  void build_graph(World& world, int west_dead_end, int east_dead_end) const {
    std::map<std::pair<int, int>, int> index;
    RoadGraph& g = world.graph;
    auto node = [&](int x, int y, NodeKind kind, int room = -1) {
      const auto key = std::make_pair(x, y);
      const auto it = index.find(key);
      if (it != index.end()) return it->second;
      const int id = static_cast<int>(g.nodes.size());
      g.nodes.push_back({{to_m(x), to_m(y)}, kind, room});
      index.emplace(key, id);
      return id;
    };
    auto connect = [&](int a, int b) {
      g.neighbours.resize(g.nodes.size());
      g.neighbours[a].push_back(b);
      g.neighbours[b].push_back(a);
    };
    // Straight corridor centrelines: the nodes that lie on them, in order.
    struct Line {
      bool horizontal;
      int fixed;            // y of a horizontal line, x of a vertical one
      std::vector<int> at;  // x (horizontal) or y (vertical) of its nodes
    };
    std::vector<Line> lines = {
        {true, 0, {0, xc_, lx_}},
        {true, ly_, {0, xc_, lx_}},
        {false, 0, {0, ys_, ly_}},
        {false, lx_, east_stub_ ? std::vector<int>{0, ye_, ly_} : std::vector<int>{0, ly_}},
        {false, xc_, {0, ly_}},
        {true, ys_, {west_dead_end, 0}},
    };
    if (east_stub_) lines.push_back({true, ye_, {lx_, east_dead_end}});
    std::vector<int> door_front_of(doors_.size(), -1);
    for (const auto& line : lines) {
      for (int v : line.at) {
        const int x = line.horizontal ? v : line.fixed;
        const int y = line.horizontal ? line.fixed : v;
        const bool dead = (line.horizontal && line.fixed == ys_ && v == west_dead_end) ||
                          (east_stub_ && line.horizontal && line.fixed == ye_ && v == east_dead_end);
        node(x, y, dead ? NodeKind::kDeadEnd : NodeKind::kCorridor);
      }
      // Corridor runs (for people) between the line's ends.
      const int a = *std::min_element(line.at.begin(), line.at.end());
      const int b = *std::max_element(line.at.begin(), line.at.end());
      if (line.horizontal) {
        world.corridor_runs.push_back({{to_m(a), to_m(line.fixed)}, {to_m(b), to_m(line.fixed)}});
      } else {
        world.corridor_runs.push_back({{to_m(line.fixed), to_m(a)}, {to_m(line.fixed), to_m(b)}});
      }
    }
    for (std::size_t d = 0; d < doors_.size(); ++d) {
      door_front_of[d] = node(doors_[d].dx, doors_[d].corridor_y, NodeKind::kDoorFront);
    }
    g.neighbours.resize(g.nodes.size());
    for (const auto& line : lines) {
      std::vector<std::pair<int, int>> on;  // (coordinate along the line, node)
      const int a = *std::min_element(line.at.begin(), line.at.end());
      const int b = *std::max_element(line.at.begin(), line.at.end());
      for (const auto& [key, id] : index) {
        const int along = line.horizontal ? key.first : key.second;
        const int across = line.horizontal ? key.second : key.first;
        if (across == line.fixed && along >= a && along <= b) on.emplace_back(along, id);
      }
      std::sort(on.begin(), on.end());
      for (std::size_t i = 1; i < on.size(); ++i) connect(on[i - 1].second, on[i].second);
    }
    for (std::size_t d = 0; d < doors_.size(); ++d) {
      const int inside = node(doors_[d].dx, doors_[d].inside_y, NodeKind::kRoomInside, doors_[d].room);
      connect(door_front_of[d], inside);
    }
    for (auto& n : g.neighbours) {
      std::sort(n.begin(), n.end());
      n.erase(std::unique(n.begin(), n.end()), n.end());
    }
  }

  WorldConfig c_;
  Rng rng_;
  int w_ = 0, hw_ = 0, t_ = 0, door_ = 0, lx_ = 0, ly_ = 0;
  int xc_ = 0, ys_ = 0, stub_len_ = 0, ye_ = 0, east_len_ = 0;
  bool east_stub_ = false;
  std::vector<IBox> corridors_, free_, tables_;
  std::vector<Room> rooms_;
  std::vector<DoorPlan> doors_;
  int ox_ = 0, oy_ = 0, cols_ = 0, rows_ = 0;
  std::vector<uint8_t> grid_;
};

}  // namespace

void WorldConfig::validate() const {
  const ConfigCheck require("WorldConfig");
  require(ring_length_m >= 24.0 && ring_length_m <= 400.0, "ring_length_m must be in [24, 400]");
  require(ring_width_m >= 16.0 && ring_width_m <= 400.0, "ring_width_m must be in [16, 400]");
  require(corridor_width_m >= 1.4 && corridor_width_m <= 4.0, "corridor_width_m must be in [1.4, 4]");
  require(wall_thickness_m >= 0.1 && wall_thickness_m <= 0.5, "wall_thickness_m must be in [0.1, 0.5]");
  require(door_width_m >= 0.8 && door_width_m <= corridor_width_m, "door_width_m must be in [0.8, corridor_width_m]");
  require(side_corridor_length_m >= 4.0 && side_corridor_length_m <= 30.0, "side_corridor_length_m must be in [4, 30]");
  require(room_probability >= 0.0 && room_probability <= 1.0, "room_probability must be in [0, 1]");
  require(table_probability >= 0.0 && table_probability <= 1.0, "table_probability must be in [0, 1]");
}

bool World::is_free(const Eigen::Vector2d& p) const {
  const double fx = (p.x() - raster_origin_.x()) / cell_m_;
  const double fy = (p.y() - raster_origin_.y()) / cell_m_;
  if (!(fx >= 0.0 && fy >= 0.0)) return false;
  const auto i = static_cast<int>(fx);
  const auto j = static_cast<int>(fy);
  if (i >= raster_cols_ || j >= raster_rows_) return false;
  return raster_[static_cast<std::size_t>(j) * raster_cols_ + i] != 0;
}

void World::set_free_raster(const Eigen::Vector2d& origin, double cell_m, int cols, int rows,
                            std::vector<uint8_t> cells) {
  if (!(cell_m > 0.0) || cols < 0 || rows < 0 || cells.size() != static_cast<std::size_t>(cols) * rows) {
    throw std::invalid_argument("World::set_free_raster: cell size or cell count does not match");
  }
  raster_origin_ = origin;
  cell_m_ = cell_m;
  raster_cols_ = cols;
  raster_rows_ = rows;
  raster_ = std::move(cells);
}

World generate_world(const WorldConfig& config, uint64_t seed) {
  config.validate();
  return Builder(config, seed).build(seed);
}

}  // namespace lmf::sim
