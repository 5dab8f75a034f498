// The simulator's indoor world: a university-like floor of corridors and rooms.
//
// Layout (all in metres, world frame W, x east, y north):
// * an outer ring corridor whose centreline is the rectangle (0,0)-(ring_length_m, ring_width_m)
//   (40 m x 20 m by default, a 120 m loop like the paper's university floor);
// * a cross corridor joining the two long sides (its x position depends on the seed), so there
//   are also two smaller loops;
// * a dead-end side corridor off the west side (and, for some seeds, one off the east side);
// * rows of rooms off the long corridors (outside and inside the ring) and off the side corridors,
//   each with one door; room widths, depths, doors, which rooms exist and which hold a table
//   depend on the seed.
// Free space is a union of axis-aligned boxes on a 0.1 m grid; walls are the boundary of the
// free space, so a wall between a room and a corridor (wall_thickness_m thick) has two faces,
// each a separate segment. Every wall face is oriented with the free space on its LEFT
// (walking from a to b), which is the side a laser sees it from.
//
// The world also carries the road graph the robots drive on (corridor centrelines, a node in
// front of every door and one inside every room) and the robots' start spots.
#pragma once

#include <cstdint>
#include <string>
#include <vector>

#include <Eigen/Core>

namespace lmf::sim {

struct WorldConfig {
  double ring_length_m = 40.0;      // x extent of the ring corridor's centreline, >= 24
  double ring_width_m = 20.0;       // y extent of the ring corridor's centreline, >= 16
  double corridor_width_m = 2.0;    // in [1.4, 4]
  double wall_thickness_m = 0.2;    // in [0.1, 0.5]
  double door_width_m = 1.0;        // in [0.8, corridor_width_m]
  double side_corridor_length_m = 12.0;  // the west dead-end corridor, in [4, 30]
  double room_probability = 0.85;   // chance that a room slot holds a room (else solid)
  double table_probability = 0.5;   // chance that a room holds a free-standing table
  // Lengths are rounded to the 0.1 m grid. Throws std::invalid_argument when out of range.
  void validate() const;
};

// An axis-aligned box [min, max] (m).
struct Box {
  Eigen::Vector2d min = Eigen::Vector2d::Zero();
  Eigen::Vector2d max = Eigen::Vector2d::Zero();
  bool contains(const Eigen::Vector2d& p) const {
    return p.x() >= min.x() && p.x() <= max.x() && p.y() >= min.y() && p.y() <= max.y();
  }
};

// One wall face: free space on the left of a -> b.
struct Wall {
  Eigen::Vector2d a = Eigen::Vector2d::Zero();
  Eigen::Vector2d b = Eigen::Vector2d::Zero();
  double length() const { return (b - a).norm(); }
};

struct Room {
  Box box;                         // the room's free space
  Eigen::Vector2d door_center;     // middle of the door opening (inside the wall)
  bool has_table = false;
};

enum class NodeKind { kCorridor, kDoorFront, kRoomInside, kDeadEnd };

struct RoadNode {
  Eigen::Vector2d p = Eigen::Vector2d::Zero();
  NodeKind kind = NodeKind::kCorridor;
  int room = -1;  // kRoomInside: index into World::rooms
};

// Robots drive along the edges (straight, axis-aligned) between adjacent nodes.
struct RoadGraph {
  std::vector<RoadNode> nodes;
  std::vector<std::vector<int>> neighbours;  // sorted node indices
};

// Where robot i starts (a point on a corridor centreline and a heading along it).
struct StartSpot {
  Eigen::Vector2d p = Eigen::Vector2d::Zero();
  double heading_rad = 0.0;
};

class World {
 public:
  uint64_t seed = 0;
  WorldConfig config;
  std::vector<Wall> walls;               // every face, free space on the left
  std::vector<Box> corridors;            // free boxes of the corridors
  std::vector<Room> rooms;
  std::vector<Box> tables;               // obstacles inside rooms
  std::vector<Wall> corridor_runs;       // straight centreline pieces between junctions/corners/ends
  RoadGraph graph;
  std::vector<Eigen::Vector2d> loop;     // the ring's centreline corners, counter-clockwise
  double loop_length_m = 0.0;            // centreline length of the ring corridor
  std::vector<StartSpot> start_spots;    // up to 8 robots
  Box bounds;                            // contains all free space

  // True where the point is in free space (inside a corridor, door or room, not in a table).
  bool is_free(const Eigen::Vector2d& p) const;

  // The free-space raster behind is_free(): cols x rows cells of cell_m, row-major from the
  // cell at `origin` (its lower-left corner), 1 = free. Set by generate_world.
  void set_free_raster(const Eigen::Vector2d& origin, double cell_m, int cols, int rows, std::vector<uint8_t> cells);

 private:
  double cell_m_ = 0.1;
  Eigen::Vector2d raster_origin_ = Eigen::Vector2d::Zero();
  int raster_cols_ = 0;
  int raster_rows_ = 0;
  std::vector<uint8_t> raster_;
};

// Generates the world for a seed. Same (config, seed) -> identical world.
// Throws std::invalid_argument for a bad config.
World generate_world(const WorldConfig& config, uint64_t seed);

}  // namespace lmf::sim
