// The front end tests' world: a closed 10 m x 6 m room with a pillar, so every
// direction is constrained and no pose looks like another.
#pragma once

#include "scan/synthetic_scan.hpp"

namespace lmf::testing {

inline SyntheticWorld room_with_pillar() {
  SyntheticWorld w;
  const Eigen::Vector2d c[4] = {{-3, -3}, {7, -3}, {7, 3}, {-3, 3}};
  for (int i = 0; i < 4; ++i) w.walls.push_back({c[i], c[(i + 1) % 4]});
  w.walls.push_back({{2.0, 1.0}, {2.5, 1.0}});
  w.walls.push_back({{2.5, 1.0}, {2.5, 1.6}});
  return w;
}

}  // namespace lmf::testing
