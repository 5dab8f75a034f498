// The sighting as it travels (runtime::Sighting, decoded and validated from
// sighting_t) as the GlobalMap takes it: the same fields (docs/design.md §5, joining).
// Here because the server is what knows both: runtime does not depend on the
// fusion core, nor the core on runtime.
#pragma once

#include "lmf/fusion/global_map.hpp"
#include "runtime/messages.hpp"

namespace lmf::server {

fusion::RobotSighting to_robot_sighting(const runtime::Sighting& s);

}  // namespace lmf::server
