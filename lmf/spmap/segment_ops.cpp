#include "lmf/spmap/segment_ops.hpp"

#include <algorithm>
#include <cmath>
#include <stdexcept>
#include <string>

#include "lmf/spmap/ekf.hpp"
#include "lmf/spmap/estimator.hpp"
#include "lmf/spmap/relative_location.hpp"

namespace lmf::spmap {
namespace {

void require_segment(const StochasticMap& map, EntityId id, const char* where) {
  if (map.entity(id).kind != EntityKind::kSegment) {
    throw std::invalid_argument(std::string(where) + ": entity " + std::to_string(id) + " is not a segment");
  }
}

}  // namespace

Interval project_extent(const Pose2& x_SB, double length_B) {
  // B's endpoints sit at ±length_B/2 on its own x axis.
  const double a = x_SB.transform_point({-0.5 * length_B, 0.0}).x();
  const double b = x_SB.transform_point({0.5 * length_B, 0.0}).x();
  return {std::min(a, b), std::max(a, b)};
}

double extent_overlap(const Pose2& x_SB, double length_S, double length_B) {
  const Interval b = project_extent(x_SB, length_B);
  return std::min(0.5 * length_S, b.max) - std::max(-0.5 * length_S, b.min);
}

void extend_segment(StochasticMap& map, EntityId s, const Interval& interval_in_s) {
  require_segment(map, s, "extend_segment");
  if (!std::isfinite(interval_in_s.min) || !std::isfinite(interval_in_s.max) ||
      interval_in_s.min > interval_in_s.max) {
    throw std::invalid_argument("extend_segment: interval [" + std::to_string(interval_in_s.min) + ", " +
                                std::to_string(interval_in_s.max) + "] of segment " + std::to_string(s) +
                                " is not a finite interval");
  }
  const double half = 0.5 * map.entity(s).length_m;
  const double new_min = std::min(-half, interval_in_s.min);
  const double new_max = std::max(half, interval_in_s.max);
  if (new_min == -half && new_max == half) return;  // already covered

  const double dx = 0.5 * (new_min + new_max);
  Entity& e = map.mutable_entity(s);
  e.location = compose(e.location, Pose2(dx, 0.0, 0.0));
  e.length_m = new_max - new_min;
  // docs/design.md §3: the frame moved by dx along x, so p' = [[1, dx], [0, 1]] p.
  map.replace_perturbation(s, {{s, segment_frame_shift(dx)}});
}

bool fuse_segments(StochasticMap& map, EntityId keep, EntityId drop, double alpha) {
  require_segment(map, keep, "fuse_segments");
  require_segment(map, drop, "fuse_segments");
  if (keep == drop) throw std::invalid_argument("fuse_segments: keep and drop are the same entity");
  const std::vector<EntityId> orphans = map.children(drop);
  if (!orphans.empty()) {
    throw std::invalid_argument("fuse_segments: segment " + std::to_string(drop) + " has children");
  }

  // Perfect constraint: drop lies on keep's line with keep's direction,
  // B(⊖x_keep ⊕ x_drop) = 0 on the lateral and angular rows, R = 0.
  const ImplicitMeasurement m = measurement_from_chain(chain_between(map, keep, drop), {1, 2});
  Chi2Table chi2(alpha);
  const CarefulTolerance tolerance;
  if (!individual_compatibility(map, m, tolerance, chi2).passed) return false;
  ekf_update(map, {&m, 1}, tolerance);

  // Geometric update: keep grows to cover drop's extent (now on its line).
  const Pose2 x_keep_drop = between(map.root_location(keep), map.root_location(drop));
  extend_segment(map, keep, project_extent(x_keep_drop, map.entity(drop).length_m));
  map.remove(drop);
  return true;
}

}  // namespace lmf::spmap
