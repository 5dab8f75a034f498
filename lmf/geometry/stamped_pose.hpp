// A pose with the time it holds at: trajectories, references, scan poses.
#pragma once

#include <cstdint>

#include "lmf/geometry/pose2.hpp"

namespace lmf {

struct StampedPose {
  int64_t utime = 0;  // microseconds
  Pose2 pose;         // x_WR: the robot in the trajectory's frame
};

}  // namespace lmf
