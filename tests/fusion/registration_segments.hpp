// Synthetic walls as the registration's and place recognition's segments.
#pragma once

#include <vector>

#include "fusion/synthetic_maps.hpp"
#include "lmf/fusion/frame_registration.hpp"

namespace lmf::fusion::synthetic {

// The walls in W.
inline std::vector<RegistrationSegment> in_world(const std::vector<Wall>& walls) {
  std::vector<RegistrationSegment> out;
  for (const Wall& w : walls) out.push_back({w.x_WS, w.length_m});
  return out;
}

// The walls seen from the frame x_WL (in L).
inline std::vector<RegistrationSegment> in_frame(const std::vector<Wall>& walls, const Pose2& x_WL) {
  std::vector<RegistrationSegment> out;
  for (const Wall& w : walls) out.push_back({between(x_WL, w.x_WS), w.length_m});
  return out;
}

}  // namespace lmf::fusion::synthetic
