// Ray casting against wall segments and circles, accelerated by a uniform grid.
//
// All inputs and outputs are in the world frame W (metres, radians). An instance is
// immutable after construction, so it may be shared by threads.
#pragma once

#include <optional>
#include <vector>

#include <Eigen/Core>

#include "lmf/sim/world.hpp"

namespace lmf::sim {

// A disc obstacle (a robot body, a person's legs), world frame.
struct Circle {
  Eigen::Vector2d center = Eigen::Vector2d::Zero();
  double radius_m = 0.0;
};

class WallIndex {
 public:
  // cell_m: side of the grid cells (about the spacing of the walls works well).
  // Throws std::invalid_argument for a non-positive cell size.
  explicit WallIndex(std::vector<Wall> walls, double cell_m = 1.0);

  // Distance along the ray from `origin` in direction `angle_rad` to the first wall,
  // or nullopt when no wall is hit within max_range_m.
  std::optional<double> cast_ray(const Eigen::Vector2d& origin, double angle_rad, double max_range_m) const;

  // True when the open segment a-b crosses a wall (line of sight blocked).
  bool blocks(const Eigen::Vector2d& a, const Eigen::Vector2d& b) const;

  // Distance from p to the nearest wall, or nullopt when no wall lies within search_radius_m.
  std::optional<double> distance_to_nearest(const Eigen::Vector2d& p, double search_radius_m) const;

  const std::vector<Wall>& walls() const { return walls_; }

 private:
  std::vector<Wall> walls_;
  double cell_m_;
  Eigen::Vector2d origin_;
  int cols_ = 0;
  int rows_ = 0;
  std::vector<int> cell_start_;  // CSR: walls of cell c are wall_ids_[cell_start_[c] .. cell_start_[c+1])
  std::vector<int> wall_ids_;
};

// Distance along a ray (unit direction `dir`) to a wall, or nullopt (parallel or missed).
std::optional<double> ray_segment_distance(const Eigen::Vector2d& origin, const Eigen::Vector2d& dir,
                                           const Wall& wall);
// Distance along a ray (unit direction) to a circle's boundary from outside, or nullopt.
std::optional<double> ray_circle_distance(const Eigen::Vector2d& origin, const Eigen::Vector2d& dir,
                                          const Circle& circle);
// Distance from p to the segment a-b.
double point_segment_distance(const Eigen::Vector2d& p, const Eigen::Vector2d& a, const Eigen::Vector2d& b);

}  // namespace lmf::sim
