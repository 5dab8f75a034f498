// The steps of the fusion beyond the paper (robot footprints, crossing
// segments) and the covariance check that ends it (fusion_steps.hpp).
#include <cmath>
#include <set>
#include <unordered_map>
#include <unordered_set>

#include <Eigen/Cholesky>
#include <Eigen/Eigenvalues>
#include <Eigen/Geometry>

#include "lmf/fusion/crossing_segments.hpp"
#include "lmf/fusion/fusion_steps.hpp"

namespace lmf::fusion {

void remove_footprint_segments(FusionContext& f, RobotFootprints& footprints) {
  for (const ScanPose& p : f.snapshot.scan_poses) {
    const Pose2 x_WR = compose(f.x_WL_fused, p.x_LR);
    footprints.add({x_WR.x, x_WR.y});
  }
  // Every segment, not only this map's: this map's poses may cover a segment
  // another robot shipped before (the body it saw), and this map's segments
  // may lie on an earlier pose of another robot.
  const std::unordered_set<EntityId> leaving(f.removals.begin(), f.removals.end());
  const double diameter = 2.0 * footprints.radius();
  for (const Entity& e : f.state.entities()) {
    if (e.kind != EntityKind::kSegment || e.length_m > diameter || leaving.count(e.id) != 0) continue;
    const Pose2 x_WS = f.state.root_location(e.id);
    const double half = 0.5 * e.length_m;
    if (footprints.covers(x_WS.transform_point({-half, 0.0}), x_WS.transform_point({half, 0.0}))) {
      f.removals.push_back(e.id);
      ++f.report.footprint_segments_removed;
    }
  }
}

namespace {

// A segment staying in the map, in W, as the crossing test sees it.
struct CrossingCandidate {
  EntityId id;
  EndPoints ends;
  Eigen::AlignedBox2d box;
  double length_m;
  Eigen::Index angle_row;  // row of the angular error of its own perturbation (its frame's excluded)
};

// Every segment staying, in W (each parent frame composed once: a fusion
// visits every segment here, so this must stay a small part of the O(n²) update).
std::vector<CrossingCandidate> staying_segments(const GlobalState& state, const std::unordered_set<EntityId>& leaving) {
  std::unordered_map<EntityId, Pose2> frame_in_W;
  std::vector<CrossingCandidate> staying;
  staying.reserve(state.entities().size());
  for (const Entity& e : state.entities()) {
    if (e.kind != EntityKind::kSegment || leaving.count(e.id) != 0) continue;
    Pose2 x_WS = e.location;
    if (e.parent) {
      auto [frame, inserted] = frame_in_W.try_emplace(*e.parent);
      if (inserted) frame->second = state.root_location(*e.parent);
      x_WS = compose(frame->second, e.location);
    }
    const Eigen::Vector2d half = 0.5 * e.length_m * Eigen::Vector2d(std::cos(x_WS.phi), std::sin(x_WS.phi));
    const Eigen::Vector2d mid(x_WS.x, x_WS.y);
    const EndPoints ends{mid - half, mid + half};
    Eigen::AlignedBox2d box(ends.start.cwiseMin(ends.end), ends.start.cwiseMax(ends.end));
    staying.push_back({e.id, ends, box, e.length_m, e.offset + 1});
  }
  return staying;
}

}  // namespace

void remove_crossing_segments(FusionContext& f) {
  const CrossingRule rule{f.config.crossing_margin_m, f.config.crossing_max_angle_rad};
  std::unordered_set<EntityId> leaving(f.removals.begin(), f.removals.end());
  const std::vector<CrossingCandidate> staying = staying_segments(f.state, leaving);
  std::vector<std::size_t> new_ones;  // indices into staying
  const std::unordered_set<EntityId> added_set(f.unpaired.begin(), f.unpaired.end());
  for (std::size_t i = 0; i < staying.size(); ++i) {
    if (added_set.count(staying[i].id) != 0) new_ones.push_back(i);
  }
  for (const std::size_t i : new_ones) {
    const CrossingCandidate& a = staying[i];
    if (leaving.count(a.id) != 0) continue;
    for (const CrossingCandidate& b : staying) {
      // Boxes that do not touch hold no crossing: most pairs stop here.
      if (!a.box.intersects(b.box) || b.id == a.id || leaving.count(b.id) != 0 ||
          !segments_cross(a.ends, b.ends, rule)) {
        continue;
      }
      // The direction known less well goes (the shorter one on a tie).
      const double var_a = f.state.covariance(a.angle_row, a.angle_row);
      const double var_b = f.state.covariance(b.angle_row, b.angle_row);
      const bool drop_a = var_a != var_b ? var_a > var_b : a.length_m < b.length_m;
      const EntityId drop = drop_a ? a.id : b.id;
      f.removals.push_back(drop);
      leaving.insert(drop);
      ++f.report.crossing_segments_removed;
      if (drop_a) break;
    }
  }
}

namespace {

// The LDLT pivots of a block of P, and its smallest eigenvalue when a pivot is
// negative beyond rounding (FusionReport::min_eigenvalue).
void check_pivots(const Eigen::MatrixXd& M, FusionReport& rep) {
  const Eigen::LDLT<Eigen::MatrixXd> ldlt(M);
  rep.min_ldlt_pivot = ldlt.vectorD().minCoeff();
  if (!(*rep.min_ldlt_pivot >= -FusionReport::kPsdTolerance)) {
    rep.min_eigenvalue = Eigen::SelfAdjointEigenSolver<Eigen::MatrixXd>(M, Eigen::EigenvaluesOnly).eigenvalues().minCoeff();
  }
}

}  // namespace

void check_health(FusionContext& f, EntityId current_frame) {
  // Covariance supervision (docs/design.md §4, §9): cheap by default.
  const GlobalState& state = f.state;
  FusionReport& rep = f.report;
  rep.health_scope = f.config.health;
  if (f.config.health == HealthCheck::kTouched) {
    std::vector<EntityId> ids;
    std::set<EntityId> seen;
    auto take = [&](EntityId id) {
      if (state.contains(id) && seen.insert(id).second) ids.push_back(id);
    };
    for (const spmap::ImplicitMeasurement& m : f.accepted_measurements) {
      for (const spmap::JacobianBlock& b : m.blocks) take(b.entity);
    }
    take(current_frame);
    for (const EntityId u : f.unpaired) take(u);
    if (rep.new_submap) take(*rep.new_submap);
    if (!ids.empty()) check_pivots(state.marginal(ids), rep);
  } else if (f.config.health == HealthCheck::kFullLdlt && state.dimension() > 0) {
    check_pivots(state.full_covariance(), rep);
  } else if (f.config.health == HealthCheck::kFullEigen && state.dimension() > 0) {
    const Eigen::SelfAdjointEigenSolver<Eigen::MatrixXd> es(state.full_covariance(), Eigen::EigenvaluesOnly);
    rep.min_eigenvalue = es.eigenvalues().minCoeff();
  }
}

}  // namespace lmf::fusion
