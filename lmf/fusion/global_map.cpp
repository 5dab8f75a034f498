#include "lmf/fusion/global_map.hpp"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <limits>
#include <numeric>
#include <stdexcept>
#include <string>
#include <unordered_map>
#include <unordered_set>

#include <Eigen/Cholesky>
#include <Eigen/Eigenvalues>
#include <Eigen/Geometry>

#include "lmf/common/config_check.hpp"
#include "lmf/fusion/crossing_segments.hpp"
#include "lmf/spmap/careful_inverse.hpp"
#include "lmf/spmap/covariance_check.hpp"
#include "lmf/spmap/segment_ops.hpp"

namespace lmf::fusion {
namespace {

using Clock = std::chrono::steady_clock;

// Measures phases for FusionReport::time; never used for a decision.
class PhaseClock {
 public:
  PhaseClock() : start_(Clock::now()), last_(start_) {}
  double lap() {
    const Clock::time_point now = Clock::now();
    const double s = std::chrono::duration<double>(now - last_).count();
    last_ = now;
    return s;
  }
  double total() const { return std::chrono::duration<double>(Clock::now() - start_).count(); }

 private:
  Clock::time_point start_;
  Clock::time_point last_;
};

std::string where(int robot_id, std::int64_t seq) {
  return "local map of robot " + std::to_string(robot_id) + " seq " + std::to_string(seq);
}

bool finite(const Pose2& p) { return std::isfinite(p.x) && std::isfinite(p.y) && std::isfinite(p.phi); }

using Reason = InvalidInput::Reason;

// Why P is not a covariance (symmetric PSD within tolerance · max(1, max |P_ii|)), if it is not.
std::optional<std::pair<Reason, std::string>> covariance_problem(const Eigen::MatrixXd& P, double tolerance) {
  if (!P.allFinite()) return std::pair{Reason::kNonFinite, std::string("has NaN or inf entries")};
  const spmap::CovarianceHealth health = spmap::check_covariance(P, tolerance);
  if (!health.symmetric) {
    return std::pair{Reason::kNotSymmetricPsd,
                     "is not symmetric (max |P - P^T| = " + std::to_string(health.max_asymmetry) + ")"};
  }
  if (!health.positive_semidefinite) {
    return std::pair{Reason::kNotSymmetricPsd, "is not positive semidefinite (smallest eigenvalue " +
                                                   std::to_string(health.min_eigenvalue.value_or(std::numeric_limits<double>::quiet_NaN())) + ")"};
  }
  return std::nullopt;
}

// The LDLT pivots of a block of P, and its smallest eigenvalue when a pivot is
// negative beyond rounding (FusionReport::min_eigenvalue).
void check_pivots(const Eigen::MatrixXd& M, FusionReport& rep) {
  const Eigen::LDLT<Eigen::MatrixXd> ldlt(M);
  rep.min_ldlt_pivot = ldlt.vectorD().minCoeff();
  if (!(*rep.min_ldlt_pivot >= -FusionReport::kPsdTolerance)) {
    rep.min_eigenvalue = Eigen::SelfAdjointEigenSolver<Eigen::MatrixXd>(M, Eigen::EigenvaluesOnly).eigenvalues().minCoeff();
  }
}

// Chi2 test of an innovation through the careful inversion (eq. 8, DESIGN §6).
struct Chi2Result {
  double distance2 = 0.0;
  int dof = 0;
  bool passed = false;
};

class Chi2Table {
 public:
  explicit Chi2Table(double alpha) : alpha_(alpha) {}
  double operator()(int dof) {
    if (static_cast<std::size_t>(dof) >= cache_.size()) cache_.resize(static_cast<std::size_t>(dof) + 1, -1.0);
    double& t = cache_[static_cast<std::size_t>(dof)];
    if (t < 0.0) t = spmap::chi2_threshold(dof, alpha_);
    return t;
  }

 private:
  double alpha_;
  std::vector<double> cache_;
};

// A relation known perfectly (S ≈ 0) passes only if its innovation is ≈ 0.
constexpr double kPerfectInnovationTolerance = 1e-6;

// The rows the careful inversion dropped from S are determined by the kept
// ones: given them, their variance is below the pivot threshold. Each such
// row's innovation given the kept rows, ν_d − S_dK S_KK⁻¹ ν_K, must then be ≈ 0
// (within what a variance at the threshold allows at the chi2(1) bound):
// otherwise the measurement contradicts a relation the map already knows
// exactly (a pairing 90° off two segments the local map made perpendicular),
// and dropping the row would accept it silently.
bool dropped_rows_consistent(const Eigen::MatrixXd& S, const Eigen::VectorXd& nu, const spmap::CarefulInverse& ci,
                             double pivot_threshold, Chi2Table& chi2) {
  if (ci.dropped.empty()) return true;
  const double bound = std::max(kPerfectInnovationTolerance, std::sqrt(chi2(1) * pivot_threshold));
  const auto k = static_cast<Eigen::Index>(ci.kept.size());
  Eigen::VectorXd nu_K(k);
  for (Eigen::Index a = 0; a < k; ++a) nu_K(a) = nu(ci.kept[static_cast<std::size_t>(a)]);
  const Eigen::VectorXd Sinv_nu_K = k > 0 ? Eigen::VectorXd(ci.inverse * nu_K) : Eigen::VectorXd();
  for (const int d : ci.dropped) {
    double conditional = nu(d);
    for (Eigen::Index a = 0; a < k; ++a) conditional -= S(d, ci.kept[static_cast<std::size_t>(a)]) * Sinv_nu_K(a);
    if (!(std::abs(conditional) <= bound)) return false;
  }
  return true;
}

// The test of one measurement (innovation h) from its block S of a joint
// innovation covariance and that block's reference scale.
Chi2Result chi2_test(const Eigen::MatrixXd& S, const Eigen::VectorXd& h, double reference_scale, Chi2Table& chi2,
                     double relative_tolerance, double absolute_floor) {
  Chi2Result r;
  const double scale = std::max(reference_scale, absolute_floor / relative_tolerance);
  const spmap::CarefulInverse ci = spmap::careful_inverse(S, relative_tolerance, scale);
  const auto k = static_cast<Eigen::Index>(ci.kept.size());
  const double pivot_threshold = relative_tolerance * std::max(S.diagonal().cwiseAbs().maxCoeff(), scale);
  if (!dropped_rows_consistent(S, h, ci, pivot_threshold, chi2)) return r;
  if (k == 0) {
    r.passed = true;
    return r;
  }
  Eigen::VectorXd h_k(k);
  for (Eigen::Index i = 0; i < k; ++i) h_k(i) = h(ci.kept[static_cast<std::size_t>(i)]);
  r.dof = static_cast<int>(k);
  r.distance2 = h_k.dot(ci.inverse * h_k);
  r.passed = r.distance2 < chi2(r.dof);
  return r;
}

Chi2Result chi2_test(const GlobalState& state, const spmap::ImplicitMeasurement& m, Chi2Table& chi2,
                     double relative_tolerance, double absolute_floor) {
  const GlobalState::Innovation in = state.innovation(m);
  return chi2_test(in.S, m.h, in.reference_scale, chi2, relative_tolerance, absolute_floor);
}

// A segment as the gate sees it: midpoint and direction in its parent frame,
// and the standard deviations of its own (lateral, angular) error.
struct GateSegment {
  EntityId id = 0;
  Pose2 location;  // in the parent frame
  double c = 1.0;  // cos, sin of location.phi
  double s = 0.0;
  double half_length = 0.0;
  double sigma_lateral = 0.0;  // m
  double sigma_angle = 0.0;    // rad
};

GateSegment gate_segment(const GlobalState& state, const Entity& e) {
  return {e.id,
          e.location,
          std::cos(e.location.phi),
          std::sin(e.location.phi),
          0.5 * e.length_m,
          std::sqrt(std::max(0.0, state.covariance(e.offset, e.offset))),
          std::sqrt(std::max(0.0, state.covariance(e.offset + 1, e.offset + 1)))};
}

// Union-find over global segment ids (segments that matched one local segment).
class Groups {
 public:
  EntityId find(EntityId a) {
    auto it = parent_.find(a);
    if (it == parent_.end()) {
      parent_.emplace(a, a);
      return a;
    }
    if (it->second == a) return a;
    const EntityId root = find(it->second);
    parent_[a] = root;
    return root;
  }
  void unite(EntityId a, EntityId b) {
    const EntityId ra = find(a);
    const EntityId rb = find(b);
    if (ra != rb) parent_[std::max(ra, rb)] = std::min(ra, rb);  // the oldest id is the root
  }
  std::map<EntityId, std::vector<EntityId>> groups() {
    std::map<EntityId, std::vector<EntityId>> out;
    std::vector<EntityId> keys;
    for (const auto& [k, v] : parent_) keys.push_back(k);
    for (const EntityId k : keys) out[find(k)].push_back(k);
    return out;
  }

 private:
  std::unordered_map<EntityId, EntityId> parent_;
};

struct Candidate {
  EntityId global_segment = 0;
  EntityId local_segment = 0;
  std::size_t local_index = 0;
  spmap::ImplicitMeasurement measurement;
  Eigen::Index row = 0;  // its first row in the gated pairs' joint innovation
  double distance2 = 0.0;
};

}  // namespace

// ---------------------------------------------------------------------------
// Configuration and validation

void GlobalMapConfig::validate() const {
  const ConfigCheck require("GlobalMapConfig");
  require(alpha > 0.0 && alpha < 1.0, "alpha must be in (0, 1)");
  require(std::isfinite(local_map_covariance_scale) && local_map_covariance_scale > 0.0,
          "local_map_covariance_scale must be finite and > 0");
  require(std::isfinite(gate_angle_rad) && gate_angle_rad >= 0.0, "gate_angle_rad must be finite and >= 0");
  require(std::isfinite(gate_distance_m) && gate_distance_m >= 0.0, "gate_distance_m must be finite and >= 0");
  require(std::isfinite(gate_gap_m) && gate_gap_m >= 0.0, "gate_gap_m must be finite and >= 0");
  require(std::isfinite(gate_sigmas) && gate_sigmas >= 0.0, "gate_sigmas must be finite and >= 0");
  require(std::isfinite(min_overlap_m), "min_overlap_m must be finite");
  require(careful_relative_tolerance > 0.0 && careful_relative_tolerance < 1.0,
          "careful_relative_tolerance must be in (0, 1)");
  require(std::isfinite(careful_absolute_floor) && careful_absolute_floor >= 0.0,
          "careful_absolute_floor must be finite and >= 0");
  require(std::isfinite(snapshot_tolerance) && snapshot_tolerance >= 0.0,
          "snapshot_tolerance must be finite and >= 0");
  require(std::isfinite(max_coordinate_m) && max_coordinate_m > 0.0, "max_coordinate_m must be finite and > 0");
  require(frame_history_per_robot >= 0, "frame_history_per_robot must be >= 0");
  require(std::isfinite(footprint_radius_m) && footprint_radius_m >= 0.0,
          "footprint_radius_m must be finite and >= 0");
  require(std::isfinite(crossing_margin_m) && crossing_margin_m >= 0.0, "crossing_margin_m must be finite and >= 0");
  require(crossing_max_angle_rad > 0.0 && crossing_max_angle_rad <= std::numbers::pi / 2,
          "crossing_max_angle_rad must be in (0, pi/2]");
}

bool FusionReport::covariance_ok() const {
  if (min_eigenvalue) return *min_eigenvalue >= -kPsdTolerance;
  return !min_ldlt_pivot || *min_ldlt_pivot >= -kPsdTolerance;
}

GlobalMap::GlobalMap(GlobalMapConfig config) : config_(config) {
  config_.validate();
  if (config_.footprint_radius_m > 0.0) footprints_.emplace(config_.footprint_radius_m);
}

std::optional<std::pair<Reason, std::string>> GlobalMap::pose_problem(const Pose2& pose) const {
  if (!finite(pose)) return std::pair{Reason::kNonFinite, std::string(" is not finite")};
  if (std::abs(pose.x) > config_.max_coordinate_m || std::abs(pose.y) > config_.max_coordinate_m) {
    return std::pair{Reason::kOutOfRange, std::string(" is beyond max_coordinate_m")};
  }
  return std::nullopt;
}

void GlobalMap::check_pose(const Pose2& pose, const std::string& what) const {
  if (const auto problem = pose_problem(pose)) throw InvalidInput(problem->first, what + problem->second);
}

void GlobalMap::check_covariance(const Eigen::MatrixXd& P, const std::string& what) const {
  if (const auto problem = covariance_problem(P, config_.snapshot_tolerance)) {
    throw InvalidInput(problem->first, what + " " + problem->second);
  }
  // A standard deviation beyond max_coordinate_m is garbage like such a
  // coordinate; a finite but absurd variance (1e268) overflowed the fusion
  // into a NaN map (found by fuzzing).
  const double max_variance = config_.max_coordinate_m * config_.max_coordinate_m;
  if (P.size() > 0 && P.diagonal().maxCoeff() > max_variance) {
    throw InvalidInput(Reason::kOutOfRange, what + " has a variance above max_coordinate_m²");
  }
}

void GlobalMap::validate(const LocalMapSnapshot& s) const {
  // This runs on every local map: the messages are built only for a rejection.
  const auto at = [&s] { return where(s.robot_id, s.seq); };
  if (s.seq < 0) throw InvalidInput(Reason::kOutOfRange, at() + ": negative sequence number");
  if (const auto problem = pose_problem(s.x_LR)) {
    throw InvalidInput(problem->first, at() + ": robot pose x_LR" + problem->second);
  }
  for (std::size_t j = 0; j < s.segments.size(); ++j) {
    const SegmentEstimate& seg = s.segments[j];
    const auto name = [&] { return at() + ": segment " + std::to_string(j); };
    if (const auto problem = pose_problem(seg.location)) {
      throw InvalidInput(problem->first, name() + " location" + problem->second);
    }
    if (!std::isfinite(seg.length_m)) throw InvalidInput(Reason::kNonFinite, name() + " length is not finite");
    if (seg.length_m <= 0.0 || seg.length_m > config_.max_coordinate_m) {
      throw InvalidInput(Reason::kOutOfRange,
                         name() + " has length " + std::to_string(seg.length_m) + " (must be > 0)");
    }
  }
  for (std::size_t i = 0; i < s.scan_poses.size(); ++i) {
    if (const auto problem = pose_problem(s.scan_poses[i].x_LR)) {
      throw InvalidInput(problem->first, at() + ": scan pose " + std::to_string(i) + problem->second);
    }
  }
  const auto expected = static_cast<Eigen::Index>(3 + 2 * s.segments.size());
  if (s.covariance.rows() != expected || s.covariance.cols() != expected) {
    throw InvalidInput(Reason::kMalformed, at() + ": covariance is " + std::to_string(s.covariance.rows()) + "x" +
                                               std::to_string(s.covariance.cols()) + ", expected " +
                                               std::to_string(expected) + " (3 + 2 x " +
                                               std::to_string(s.segments.size()) + " segments)");
  }
  check_covariance(s.covariance, at() + ": covariance");
}

// ---------------------------------------------------------------------------
// Queries

bool GlobalMap::is_joined(int robot_id) const {
  const auto it = robots_.find(robot_id);
  return it != robots_.end() && it->second.joined;
}

bool GlobalMap::has_fused(int robot_id, std::int64_t seq) const {
  const auto it = robots_.find(robot_id);
  return it != robots_.end() && it->second.fused.count(seq) != 0;
}

bool GlobalMap::is_queued(int robot_id, std::int64_t seq) const {
  const auto it = robots_.find(robot_id);
  return it != robots_.end() && it->second.queue.count(seq) != 0;
}

int GlobalMap::queued_count() const {
  std::size_t n = 0;
  for (const auto& [id, rec] : robots_) n += rec.queue.size();
  return static_cast<int>(n);
}

std::vector<int> GlobalMap::robots() const {
  std::vector<int> out;
  for (const auto& [id, rec] : robots_) {
    if (rec.joined) out.push_back(id);
  }
  return out;
}

std::optional<CorrectedFrame> GlobalMap::corrected_frame(int robot_id) const {
  const auto it = robots_.find(robot_id);
  if (it == robots_.end() || !it->second.joined) return std::nullopt;
  const RobotRecord& rec = it->second;
  const EntityId L = rec.frames.at(rec.next_seq).frame;
  CorrectedFrame f;
  f.robot_id = robot_id;
  f.seq = rec.next_seq;
  f.x_WL = state_.root_location(L);
  f.covariance = frame_world_covariance(state_, L);
  return f;
}

std::vector<CorrectedFrame> GlobalMap::corrected_frames() const {
  std::vector<CorrectedFrame> out;
  for (const int id : robots()) out.push_back(*corrected_frame(id));
  return out;
}

bool GlobalMap::is_submap(EntityId frame) const {
  return std::any_of(submaps_.begin(), submaps_.end(), [frame](const SubmapRecord& r) { return r.frame == frame; });
}

std::vector<SegmentView> GlobalMap::segments() const {
  std::vector<SegmentView> out;
  for (const Entity& e : state_.entities()) {
    if (e.kind != EntityKind::kSegment) continue;
    SegmentView v;
    v.id = e.id;
    v.submap = e.parent.value_or(-1);
    v.x_WS = state_.root_location(e.id);
    v.length_m = e.length_m;
    v.start_W = v.x_WS.transform_point({-0.5 * e.length_m, 0.0});
    v.end_W = v.x_WS.transform_point({0.5 * e.length_m, 0.0});
    v.covariance = segment_world_covariance(state_, e.id);
    out.push_back(v);
  }
  return out;
}

std::vector<SubmapView> GlobalMap::submaps() const {
  std::unordered_map<EntityId, int> children;
  for (const Entity& e : state_.entities()) {
    if (e.parent) ++children[*e.parent];
  }
  std::vector<SubmapView> out;
  for (const SubmapRecord& r : submaps_) {
    SubmapView v;
    v.frame = r.frame;
    v.robot_id = r.robot_id;
    v.seq = r.seq;
    v.x_WF = state_.root_location(r.frame);
    v.covariance = frame_world_covariance(state_, r.frame);
    const auto it = children.find(r.frame);
    v.segments = it == children.end() ? 0 : it->second;
    out.push_back(v);
  }
  return out;
}

std::vector<GraphEdge> GlobalMap::graph_edges() const {
  // DESIGN §5.7: consecutive submaps of one robot (by local map number), and
  // submaps whose segments were paired in one fusion.
  std::map<std::pair<EntityId, EntityId>, GraphEdge::Kind> edges;
  std::map<int, std::vector<std::pair<std::int64_t, EntityId>>> by_robot;
  for (const SubmapRecord& r : submaps_) by_robot[r.robot_id].emplace_back(r.seq, r.frame);
  for (auto& [robot_id, list] : by_robot) {
    std::sort(list.begin(), list.end());
    for (std::size_t i = 1; i < list.size(); ++i) {
      const EntityId a = std::min(list[i - 1].second, list[i].second);
      const EntityId b = std::max(list[i - 1].second, list[i].second);
      edges[{a, b}] = GraphEdge::Kind::kConsecutive;
    }
  }
  for (const auto& key : paired_edges_) edges.emplace(key, GraphEdge::Kind::kPaired);
  std::vector<GraphEdge> out;
  for (const auto& [key, kind] : edges) out.push_back({key.first, key.second, kind});
  return out;
}

MapCounts GlobalMap::counts() const {
  MapCounts c;
  for (const Entity& e : state_.entities()) {
    if (e.kind == EntityKind::kSegment) ++c.segments;
  }
  c.submaps = static_cast<int>(submaps_.size());
  c.robots_joined = static_cast<int>(robots().size());
  c.graph_edges = static_cast<int>(graph_edges().size());
  c.queued_local_maps = queued_count();
  c.state_dimension = state_.dimension();
  return c;
}

// ---------------------------------------------------------------------------
// Joining

std::vector<FusionReport> GlobalMap::join_robot(int robot_id, const Pose2& x_WL, const Eigen::Matrix3d& covariance,
                                                std::int64_t seq) {
  const std::string at = "join_robot(robot " + std::to_string(robot_id) + ")";
  if (is_joined(robot_id)) throw InvalidInput(Reason::kDuplicate, at + ": the robot has already joined");
  if (seq < 0) throw InvalidInput(Reason::kOutOfRange, at + ": negative sequence number");
  check_pose(x_WL, at + ": x_WL");
  check_covariance(covariance, at + ": covariance");

  std::vector<FusionReport> out;
  const EntityId L = state_.add(EntityKind::kFrame, x_WL);
  state_.set_block(L, L, covariance);
  join(robot_id, L, seq, out);
  resolve_sightings(out);
  return out;
}

void GlobalMap::join(int robot_id, EntityId frame, std::int64_t seq, std::vector<FusionReport>& out) {
  RobotRecord& rec = robot(robot_id);
  rec.joined = true;
  any_joined_ = true;
  rec.next_seq = seq;
  rec.min_seq = seq;
  rec.frames[seq] = {frame, std::nullopt};
  // Local maps recorded before this frame, contiguous down from seq - 1: their
  // frames follow backwards from this one; they are then fused in order.
  for (std::int64_t k = seq - 1; k >= 0 && rec.queue.count(k) != 0; --k) prepare_backward(robot_id, k);
  drain(robot_id, out);
}

void GlobalMap::prepare_backward(int robot_id, std::int64_t seq) {
  RobotRecord& rec = robot(robot_id);
  const LocalMapSnapshot& s = rec.queue.at(seq);
  const EntityId next = rec.frames.at(seq + 1).frame;
  // L_k = L_{k+1} ⊕ ⊖x_R(k): the robot's final pose of map k is the next frame.
  const PreviousFrame pf = previous_frame(state_.root_location(next), s.x_LR);
  const EntityId L = state_.add(EntityKind::kFrame, pf.x_WL_previous);
  const EntityId R = state_.add(EntityKind::kRobot, s.x_LR, L);
  state_.set_block(R, R, config_.local_map_covariance_scale * s.covariance.topLeftCorner(3, 3));
  state_.replace_perturbation(L, {{next, pf.J_next}, {R, pf.J_R}});
  rec.frames[seq] = {L, R};
  rec.min_seq = std::min(rec.min_seq, seq);
}

void GlobalMap::drain(int robot_id, std::vector<FusionReport>& out) {
  while (true) {
    RobotRecord& rec = robot(robot_id);
    std::optional<std::int64_t> next;
    // Backward-anchored maps first (they are the older ones), lowest seq first.
    for (const auto& [seq, slot] : rec.frames) {
      if (slot.robot) {
        next = seq;
        break;
      }
    }
    if (!next && rec.queue.count(rec.next_seq) != 0) next = rec.next_seq;
    if (!next && rec.min_seq > 0 && rec.queue.count(rec.min_seq - 1) != 0 && rec.frames.count(rec.min_seq) != 0) {
      prepare_backward(robot_id, rec.min_seq - 1);
      continue;
    }
    if (!next) break;
    const LocalMapSnapshot snapshot = std::move(rec.queue.at(*next));
    rec.queue.erase(*next);
    out.push_back(fuse_one(robot_id, snapshot));
    resolve_sightings(out);
  }
}

// ---------------------------------------------------------------------------
// Sightings

SightingResult GlobalMap::add_sighting(const RobotSighting& s) {
  const std::string at = "sighting of robot " + std::to_string(s.observed_id) + " by robot " +
                         std::to_string(s.observer_id);
  if (s.observer_id == s.observed_id) throw InvalidInput(Reason::kMalformed, at + ": a robot cannot sight itself");
  if (s.observer_seq < 0 || s.observed_seq < 0) {
    throw InvalidInput(Reason::kOutOfRange, at + ": negative sequence number");
  }
  check_pose(s.x_LA, at + ": x_LA");
  check_pose(s.x_AB, at + ": x_AB");
  check_pose(s.x_LB, at + ": x_LB");
  check_covariance(s.cov_LA, at + ": cov_LA");
  check_covariance(s.cov_AB, at + ": cov_AB");
  check_covariance(s.cov_LB, at + ": cov_LB");

  SightingResult result;
  if (is_joined(s.observed_id)) {
    result.status = SightingStatus::kIgnored;
    return result;
  }
  const std::optional<SightingStatus> status = try_resolve(s, result.fused);
  if (!status) {
    pending_sightings_.push_back(s);
    result.status = SightingStatus::kPending;
    return result;
  }
  result.status = *status;
  resolve_sightings(result.fused);
  return result;
}

std::optional<SightingStatus> GlobalMap::try_resolve(const RobotSighting& s, std::vector<FusionReport>& out) {
  if (is_joined(s.observed_id)) return SightingStatus::kIgnored;
  if (!is_joined(s.observer_id)) return std::nullopt;
  const RobotRecord& obs = robots_.at(s.observer_id);

  // The observer's frame of local map observer_seq: still in the state (its
  // current frame, an anchor, or the submap copied from it), or remembered.
  std::optional<EntityId> frame;
  if (const auto it = obs.frames.find(s.observer_seq); it != obs.frames.end()) frame = it->second.frame;
  for (const SubmapRecord& r : submaps_) {
    if (!frame && r.robot_id == s.observer_id && r.seq == s.observer_seq) frame = r.frame;
  }
  EntityId L_B = 0;
  SightingStatus status = SightingStatus::kJoined;
  if (frame) {
    const SightedFrame sf = sighted_frame(state_.root_location(*frame), s);
    L_B = state_.add(EntityKind::kFrame, sf.x_WLB);
    state_.replace_perturbation(L_B, {{*frame, sf.J_LA}});
    state_.add_to_block(L_B, sf.noise);
  } else if (const auto h = obs.history.find(s.observer_seq); h != obs.history.end()) {
    const SightedFrame sf = sighted_frame(h->second.first, s);
    L_B = state_.add(EntityKind::kFrame, sf.x_WLB);
    state_.set_block(L_B, L_B, sf.J_LA * h->second.second * sf.J_LA.transpose() + sf.noise);
    status = SightingStatus::kJoinedApproximately;
  } else {
    return std::nullopt;  // the observer has not reached (or not yet fused) that local map
  }
  join(s.observed_id, L_B, s.observed_seq, out);
  return status;
}

void GlobalMap::resolve_sightings(std::vector<FusionReport>& out) {
  // Re-entered through join() -> drain(): the outer loop picks up the changes.
  if (resolving_) return;
  resolving_ = true;
  bool progress = true;
  while (progress) {
    progress = false;
    for (std::size_t i = 0; i < pending_sightings_.size(); ++i) {
      const RobotSighting s = pending_sightings_[i];
      if (try_resolve(s, out)) {
        pending_sightings_.erase(pending_sightings_.begin() + static_cast<std::ptrdiff_t>(i));
        progress = true;
        break;
      }
    }
  }
  resolving_ = false;
}

// ---------------------------------------------------------------------------
// Fusion

std::vector<FusionReport> GlobalMap::fuse(const LocalMapSnapshot& snapshot) {
  validate(snapshot);
  if (has_fused(snapshot.robot_id, snapshot.seq)) {
    throw InvalidInput(Reason::kDuplicate, where(snapshot.robot_id, snapshot.seq) + ": already fused");
  }
  if (is_queued(snapshot.robot_id, snapshot.seq)) {
    throw InvalidInput(Reason::kDuplicate, where(snapshot.robot_id, snapshot.seq) + ": already queued");
  }
  std::vector<FusionReport> out;
  RobotRecord& rec = robot(snapshot.robot_id);
  rec.queue.emplace(snapshot.seq, snapshot);
  if (!any_joined_ && config_.first_robot_defines_world) {
    // DESIGN §5: the first robot defines the global frame.
    const EntityId L = state_.add(EntityKind::kFrame, Pose2());
    join(snapshot.robot_id, L, snapshot.seq, out);
  } else if (rec.joined) {
    drain(snapshot.robot_id, out);
  }
  resolve_sightings(out);
  return out;
}

void GlobalMap::extend_to_cover(EntityId segment, const spmap::Interval& interval,
                                std::map<EntityId, Eigen::Matrix2d>& shifts) {
  // Geometric update (paper §II.C): the segment grows to cover the projection;
  // moving its frame by dx along its axis changes the meaning of its lateral
  // error, p' = [[1, dx], [0, 1]] p (DESIGN §3).
  Entity& e = state_.mutable_entity(segment);
  const double half = 0.5 * e.length_m;
  const double lo = std::min(-half, interval.min);
  const double hi = std::max(half, interval.max);
  if (lo >= -half && hi <= half) return;
  const double dx = 0.5 * (lo + hi);
  e.location = compose(e.location, Pose2(dx, 0.0, 0.0));
  e.length_m = hi - lo;
  const auto [it, inserted] = shifts.try_emplace(segment, Eigen::Matrix2d::Identity());
  it->second = spmap::segment_frame_shift(dx) * it->second;
}

namespace {

void apply_shifts(GlobalState& state, const std::map<EntityId, Eigen::Matrix2d>& shifts) {
  std::vector<GlobalState::LinearTerm> maps;
  maps.reserve(shifts.size());
  for (const auto& [id, J] : shifts) maps.push_back({id, J});
  state.transform_perturbations(maps);
}

}  // namespace

FusionReport GlobalMap::fuse_one(int robot_id, const LocalMapSnapshot& s) {
  PhaseClock clock;
  RobotRecord& rec = robot(robot_id);
  FusionReport rep;
  rep.robot_id = robot_id;
  rep.seq = s.seq;
  rep.local_segments = static_cast<int>(s.segments.size());
  const FrameSlot slot = rec.frames.at(s.seq);
  const EntityId L = slot.frame;
  const bool anchored = slot.robot.has_value();
  rep.anchored_backward = anchored;
  Chi2Table chi2(config_.alpha);
  const double rel = config_.careful_relative_tolerance;
  const double floor = config_.careful_absolute_floor;
  rep.time.validate_s = clock.lap();

  // (1) Augmentation, eq. (4): the local map is independent of the global one,
  // P⁻ = [[P, 0], [0, P_Mr]]; robot and local segments are children of L_r.
  // P_Mr is the shipped covariance times local_map_covariance_scale.
  const Eigen::MatrixXd P_Mr = config_.local_map_covariance_scale * s.covariance;
  const std::size_t k = s.segments.size();
  const auto k_rows = static_cast<Eigen::Index>(2 * k);
  std::vector<EntityId> local(k);
  EntityId R = 0;
  std::vector<GlobalState::NewEntity> additions;
  if (!anchored) additions.push_back({EntityKind::kRobot, s.x_LR, L, 0.0});
  for (const SegmentEstimate& seg : s.segments) additions.push_back({EntityKind::kSegment, seg.location, L, seg.length_m});
  const std::vector<EntityId> added = state_.add_many(additions);
  std::copy(added.end() - static_cast<std::ptrdiff_t>(k), added.end(), local.begin());
  if (!anchored) {
    R = added.front();
    state_.set_marginal(added, P_Mr);
  } else {
    // The robot is already in the state (it defined L_r); the segments join
    // conditioned on it: p_S = A p_R + w, A = P_SR P_RR⁺, Cov(w) = P_SS − A P_RS.
    R = *slot.robot;
    const Eigen::MatrixXd P_RR = P_Mr.topLeftCorner(3, 3);
    const Eigen::MatrixXd P_SR = P_Mr.bottomLeftCorner(k_rows, 3);
    const spmap::CarefulInverse ci = spmap::careful_inverse(P_RR, rel);
    Eigen::MatrixXd P_RR_pinv = Eigen::MatrixXd::Zero(3, 3);
    for (std::size_t a = 0; a < ci.kept.size(); ++a) {
      for (std::size_t b = 0; b < ci.kept.size(); ++b) {
        P_RR_pinv(ci.kept[a], ci.kept[b]) = ci.inverse(static_cast<Eigen::Index>(a), static_cast<Eigen::Index>(b));
      }
    }
    const Eigen::MatrixXd A = P_SR * P_RR_pinv;
    for (std::size_t j = 0; j < k; ++j) {
      state_.replace_perturbation(local[j], {{R, A.middleRows(static_cast<Eigen::Index>(2 * j), 2)}});
    }
    Eigen::MatrixXd residual = P_Mr.bottomRightCorner(k_rows, k_rows) - A * P_SR.transpose();
    residual = (0.5 * (residual + residual.transpose())).eval();
    state_.add_to_marginal(local, residual);
  }
  rep.time.augment_s = clock.lap();

  // (2) Implicit measurements, eq. (12). A cheap geometric gate first, so the
  // chi2 test only sees plausible pairs. It works per submap F_n in F_n's frame
  // with the RELATIVE covariance of L_r and F_n (their absolute uncertainty
  // grows without bound in a large map while the relative one stays small);
  // standard deviations of independent-looking parts are added (|cov| <= σa σb),
  // so the gate is never narrower than the chi2 test would need.
  std::vector<EntityId> submap_order;
  std::unordered_map<EntityId, std::vector<GateSegment>> by_submap;
  for (const Entity& e : state_.entities()) {
    if (e.kind != EntityKind::kSegment || !e.parent || *e.parent == L) continue;
    auto [it, inserted] = by_submap.try_emplace(*e.parent);
    if (inserted) submap_order.push_back(*e.parent);
    it->second.push_back(gate_segment(state_, e));
  }
  std::vector<GateSegment> locals;
  for (std::size_t j = 0; j < k; ++j) locals.push_back(gate_segment(state_, state_.entity(local[j])));
  const Pose2 x_WL = state_.root_location(L);
  const double gs = config_.gate_sigmas;
  std::vector<std::pair<EntityId, std::size_t>> gated;  // (global segment, local index)
  std::int64_t globals_count = 0;
  for (const EntityId F : submap_order) {
    const std::vector<GateSegment>& globals = by_submap.at(F);
    globals_count += static_cast<std::int64_t>(globals.size());
    // x_FL = ⊖x_WF ⊕ x_WL and the covariance of its (x, y, phi).
    const Pose2 x_WF = state_.root_location(F);
    const spmap::ImplicitMeasurement relative = spmap::measurement_from_chain(
        {{x_WF, EntityKind::kFrame, true, F}, {x_WL, EntityKind::kFrame, false, L}}, {0, 1, 2});
    Eigen::MatrixXd J(3, 6);
    J.leftCols(3) = relative.blocks[0].entity == F ? relative.blocks[0].J : relative.blocks[1].J;
    J.rightCols(3) = relative.blocks[0].entity == F ? relative.blocks[1].J : relative.blocks[0].J;
    const Eigen::Matrix3d Sigma = J * state_.marginal({F, L}) * J.transpose();
    const Pose2 x_FL = between(x_WF, x_WL);
    const double sigma_frame_angle = std::sqrt(std::max(0.0, Sigma(2, 2)));
    for (std::size_t j = 0; j < locals.size(); ++j) {
      const GateSegment& l = locals[j];
      // The local midpoint in F and the covariance of its position from Sigma.
      const Pose2 x_F_Sj = compose(x_FL, l.location);
      Eigen::Matrix<double, 2, 3> G;
      const double cf = std::cos(x_FL.phi);
      const double sf = std::sin(x_FL.phi);
      G << 1.0, 0.0, -sf * l.location.x - cf * l.location.y,  //
          0.0, 1.0, cf * l.location.x - sf * l.location.y;
      const Eigen::Matrix2d cov_p = G * Sigma * G.transpose();
      for (const GateSegment& g : globals) {
        const double angle_sigma = sigma_frame_angle + g.sigma_angle + l.sigma_angle;
        if (std::abs(wrap_angle(x_F_Sj.phi - g.location.phi)) > config_.gate_angle_rad + gs * angle_sigma) continue;
        const Eigen::Vector2d d(x_F_Sj.x - g.location.x, x_F_Sj.y - g.location.y);
        const Eigen::Vector2d t(g.c, g.s);
        const Eigen::Vector2d nrm(-g.s, g.c);
        const double along = t.dot(d);
        const double lateral = nrm.dot(d);
        const double lateral_sigma = std::sqrt(std::max(0.0, nrm.dot(cov_p * nrm))) + g.sigma_lateral +
                                     std::abs(along) * g.sigma_angle + l.sigma_lateral;
        if (std::abs(lateral) > config_.gate_distance_m + gs * lateral_sigma) continue;
        // Extent gap along the global segment's axis (projection of the local one).
        const double reach = l.half_length * std::abs(std::cos(x_F_Sj.phi - g.location.phi));
        const double gap = std::max(along - reach - g.half_length, -g.half_length - (along + reach));
        const double along_sigma = std::sqrt(std::max(0.0, t.dot(cov_p * t)));
        if (gap > config_.gate_gap_m + gs * along_sigma) continue;
        gated.emplace_back(g.id, j);
      }
    }
  }
  rep.pairs_considered = globals_count * static_cast<std::int64_t>(k);
  rep.gate_rejected = rep.pairs_considered - static_cast<std::int64_t>(gated.size());
  rep.time.gate_s = clock.lap();

  // Individual compatibility (eq. 8) and overlap test; several pairings per
  // local segment are allowed (no nearest neighbour). One joint innovation
  // covariance of all gated pairs serves both tests: each individual S is a
  // diagonal block of it, the joint test's S the block of the candidates.
  std::vector<spmap::ImplicitMeasurement> gated_measurements;
  gated_measurements.reserve(gated.size());
  for (const auto& [global_id, j] : gated) {
    gated_measurements.push_back(pairing_measurement(state_, global_id, locals[j].id));
  }
  const GlobalState::Innovation gated_in =
      gated.empty() ? GlobalState::Innovation{} : state_.innovation(gated_measurements);
  std::vector<Candidate> candidates;
  Eigen::Index row = 0;
  for (std::size_t g = 0; g < gated.size(); ++g) {
    Candidate c;
    c.global_segment = gated[g].first;
    c.local_index = gated[g].second;
    c.local_segment = locals[c.local_index].id;
    c.measurement = std::move(gated_measurements[g]);
    c.row = row;
    const Eigen::Index dim = c.measurement.h.size();
    row += dim;
    const Chi2Result t = chi2_test(gated_in.S.block(c.row, c.row, dim, dim), c.measurement.h,
                                   gated_in.row_scale.segment(c.row, dim).maxCoeff(), chi2, rel, floor);
    if (!t.passed) {
      ++rep.chi2_rejected;
      continue;
    }
    const Pose2 x_SiSj = between(state_.root_location(c.global_segment), state_.root_location(c.local_segment));
    if (spmap::extent_overlap(x_SiSj, state_.entity(c.global_segment).length_m,
                              state_.entity(c.local_segment).length_m) < config_.min_overlap_m) {
      ++rep.overlap_rejected;
      continue;
    }
    c.distance2 = t.distance2;
    candidates.push_back(std::move(c));
  }
  rep.jc_candidates = static_cast<int>(candidates.size());
  rep.time.individual_s = clock.lap();

  // (3) Incremental joint compatibility, best individual distance first. The
  // accepted set's S⁻¹ grows by Schur complements; rows a candidate adds that
  // the accepted ones already determine are dropped (careful inversion, §III.B).
  std::vector<std::size_t> order(candidates.size());
  std::iota(order.begin(), order.end(), std::size_t{0});
  std::stable_sort(order.begin(), order.end(), [&](std::size_t a, std::size_t b) {
    return candidates[a].distance2 < candidates[b].distance2;
  });
  std::vector<std::size_t> accepted;  // indices into candidates
  std::vector<spmap::ImplicitMeasurement> accepted_measurements;
  if (!candidates.empty()) {
    // The candidates' rows of the gated innovation, in test order.
    std::vector<Eigen::Index> rows;
    for (const std::size_t c : order) {
      for (Eigen::Index i = 0; i < candidates[c].measurement.h.size(); ++i) rows.push_back(candidates[c].row + i);
    }
    const auto m_all = static_cast<Eigen::Index>(rows.size());
    Eigen::MatrixXd S_all(m_all, m_all);
    Eigen::VectorXd h_all(m_all);
    double candidates_scale = 0.0;
    for (Eigen::Index a = 0; a < m_all; ++a) {
      const Eigen::Index ra = rows[static_cast<std::size_t>(a)];
      for (Eigen::Index b = 0; b < m_all; ++b) S_all(a, b) = gated_in.S(ra, rows[static_cast<std::size_t>(b)]);
      candidates_scale = std::max(candidates_scale, gated_in.row_scale(ra));
    }
    Eigen::Index filled = 0;
    for (const std::size_t c : order) {
      h_all.segment(filled, candidates[c].measurement.h.size()) = candidates[c].measurement.h;
      filled += candidates[c].measurement.h.size();
    }
    const double threshold = rel * std::max({S_all.diagonal().maxCoeff(), candidates_scale, floor / rel});
    std::vector<Eigen::Index> K;  // kept rows of S_all
    Eigen::MatrixXd S_K_inv(0, 0);
    Eigen::VectorXd h_K(0);
    double d2 = 0.0;
    int dof = 0;
    for (std::size_t c = 0; c < order.size(); ++c) {
      const auto r0 = static_cast<Eigen::Index>(2 * c);
      const auto nK = static_cast<Eigen::Index>(K.size());
      Eigen::MatrixXd B(2, nK);
      for (Eigen::Index a = 0; a < nK; ++a) B.col(a) = S_all.block(r0, K[static_cast<std::size_t>(a)], 2, 1);
      // Products of 2 or 3 rows: coefficient-based (lazyProduct); Eigen's blocked
      // GEMM spends more on packing than on the arithmetic at these shapes.
      const Eigen::MatrixXd B_Sinv = B.lazyProduct(S_K_inv);
      Eigen::MatrixXd residual = S_all.block(r0, r0, 2, 2) - B_Sinv.lazyProduct(B.transpose());
      residual = (0.5 * (residual + residual.transpose())).eval();
      const Eigen::VectorXd nu = h_all.segment(r0, 2) - B_Sinv * h_K;
      const spmap::CarefulInverse ci = spmap::careful_inverse(residual, rel, threshold / rel);
      const double pivot_threshold = std::max(threshold, rel * residual.diagonal().cwiseAbs().maxCoeff());
      if (!dropped_rows_consistent(residual, nu, ci, pivot_threshold, chi2)) {
        ++rep.jc_rejected;
        continue;
      }
      const auto kc = static_cast<Eigen::Index>(ci.kept.size());
      Eigen::VectorXd nu_k(kc);
      for (Eigen::Index a = 0; a < kc; ++a) nu_k(a) = nu(ci.kept[static_cast<std::size_t>(a)]);
      const double d2_new = d2 + (kc > 0 ? nu_k.dot(ci.inverse * nu_k) : 0.0);
      const int dof_new = dof + static_cast<int>(kc);
      if (dof_new > 0 && !(d2_new < chi2(dof_new))) {
        ++rep.jc_rejected;
        continue;
      }
      accepted.push_back(order[c]);
      accepted_measurements.push_back(std::move(candidates[order[c]].measurement));  // the test reads h_all, S_all
      d2 = d2_new;
      dof = dof_new;
      if (kc == 0) continue;
      // Block inverse of the grown accepted S.
      Eigen::MatrixXd Bk_Sinv(kc, nK);
      for (Eigen::Index a = 0; a < kc; ++a) Bk_Sinv.row(a) = B_Sinv.row(ci.kept[static_cast<std::size_t>(a)]);
      const Eigen::MatrixXd& Rk_inv = ci.inverse;
      Eigen::MatrixXd grown(nK + kc, nK + kc);
      grown.topRightCorner(nK, kc).noalias() = -Bk_Sinv.transpose().lazyProduct(Rk_inv);
      grown.topLeftCorner(nK, nK).noalias() = S_K_inv - grown.topRightCorner(nK, kc).lazyProduct(Bk_Sinv);
      grown.bottomLeftCorner(kc, nK) = grown.topRightCorner(nK, kc).transpose();
      grown.bottomRightCorner(kc, kc) = Rk_inv;
      S_K_inv = std::move(grown);
      Eigen::VectorXd h_grown(nK + kc);
      h_grown.head(nK) = h_K;
      for (Eigen::Index a = 0; a < kc; ++a) h_grown(nK + a) = h_all(r0 + ci.kept[static_cast<std::size_t>(a)]);
      h_K = std::move(h_grown);
      for (const int kept_row : ci.kept) K.push_back(r0 + kept_row);
    }
  }
  rep.pairings_accepted = static_cast<int>(accepted.size());
  rep.time.joint_s = clock.lap();

  // EKF update with every compatible pairing (eq. 9), careful inversion (§6).
  {
    rep.update_dimension = state_.dimension();
    const StateUpdateReport u = state_.ekf_update(accepted_measurements, rel, floor);
    rep.update_rows = u.rows;
    rep.rows_dropped = u.rows_dropped;
    rep.rows_kept = u.rows_kept;
    rep.update_distance2 = u.distance2;
  }
  rep.time.update_s = clock.lap();

  // (4) Geometric update: project each paired local segment onto its (updated)
  // global segment and extend it; the used local segments go; global segments
  // that matched one local segment are fused into one.
  std::vector<EntityId> removals;
  std::vector<bool> used(k, false);
  std::set<EntityId> touched_submaps;
  std::map<std::size_t, std::vector<EntityId>> matches_of_local;
  std::map<EntityId, Eigen::Matrix2d> shifts;
  for (const std::size_t a : accepted) {
    const Candidate& c = candidates[a];
    const Pose2 x_SiSj = between(state_.root_location(c.global_segment), state_.root_location(c.local_segment));
    const Entity& global = state_.entity(c.global_segment);
    const double before = global.length_m;
    extend_to_cover(c.global_segment, spmap::project_extent(x_SiSj, state_.entity(c.local_segment).length_m),
                    shifts);
    if (state_.entity(c.global_segment).length_m > before) ++rep.segments_extended;
    used[c.local_index] = true;
    touched_submaps.insert(*state_.entity(c.global_segment).parent);
    matches_of_local[c.local_index].push_back(c.global_segment);
  }
  apply_shifts(state_, shifts);
  for (std::size_t j = 0; j < k; ++j) {
    if (used[j]) removals.push_back(local[j]);
  }
  rep.local_segments_removed = static_cast<int>(removals.size());
  Groups groups;
  for (const auto& [j, globals_of_j] : matches_of_local) {
    for (std::size_t a = 1; a < globals_of_j.size(); ++a) groups.unite(globals_of_j[0], globals_of_j[a]);
  }
  for (const auto& [keep, members] : groups.groups()) {
    for (const EntityId drop : members) {
      if (drop == keep) continue;
      // The two are the same wall: the perfect constraint B(⊖x_keep ⊕ x_drop) = 0.
      const spmap::ImplicitMeasurement m =
          spmap::measurement_from_chain(state_.chain_between(keep, drop), {1, 2});
      const Chi2Result t = chi2_test(state_, m, chi2, rel, floor);
      if (!t.passed) {
        ++rep.global_fusions_rejected;
        continue;
      }
      state_.ekf_update({m}, rel, floor);
      const Pose2 x_keep_drop = between(state_.root_location(keep), state_.root_location(drop));
      std::map<EntityId, Eigen::Matrix2d> shift;
      extend_to_cover(keep, spmap::project_extent(x_keep_drop, state_.entity(drop).length_m), shift);
      apply_shifts(state_, shift);
      removals.push_back(drop);
      ++rep.global_segments_fused;
    }
  }
  rep.time.geometric_s = clock.lap();

  // (5) Unpaired local segments stay relative to L_r, which becomes a new
  // submap frame F_new (a copy of L_r with its correlations). (6) L_r ← L_r ⊕ x_R.
  std::vector<EntityId> unpaired;
  for (std::size_t j = 0; j < k; ++j) {
    if (!used[j]) unpaired.push_back(local[j]);
  }
  rep.new_segments = static_cast<int>(unpaired.size());
  const Pose2 x_WL_fused = state_.root_location(L);
  const Eigen::Matrix3d cov_L_fused = state_.block(L, L);
  if (!anchored) {
    const bool keep_anchor = s.seq == rec.min_seq && s.seq > 0;  // an older local map may still come
    std::optional<EntityId> copy;
    if (!unpaired.empty()) {
      copy = state_.add_copy(L);
      for (const EntityId u : unpaired) state_.mutable_entity(u).parent = *copy;
      submaps_.push_back({*copy, robot_id, s.seq});
      rep.new_submap = copy;
    } else if (keep_anchor) {
      copy = state_.add_copy(L);
    }
    const FrameAdvance adv = advance_frame(state_.entity(L).location, state_.entity(R).location);
    state_.replace_perturbation(L, {{L, adv.J_L}, {R, adv.J_R}});
    state_.mutable_entity(L).location = adv.x_WL_next;
    rep.x_WL_next = adv.x_WL_next;
    removals.push_back(R);
    rec.frames.erase(s.seq);
    if (keep_anchor) rec.frames[s.seq] = {*copy, std::nullopt};
    rec.frames[s.seq + 1] = {L, std::nullopt};
    rec.next_seq = s.seq + 1;
  } else {
    // The next frame already exists (it defined this one); L_k itself becomes
    // the submap of the unpaired segments, already its children.
    if (!unpaired.empty()) {
      submaps_.push_back({L, robot_id, s.seq});
      rep.new_submap = L;
    }
    removals.push_back(R);
    rec.frames.at(s.seq).robot.reset();
    rep.x_WL_next = state_.root_location(rec.frames.at(s.seq + 1).frame);
  }
  if (rep.new_submap) touched_submaps.insert(*rep.new_submap);
  // (7) Environment graph: the submaps this local map touched are neighbours.
  for (auto a = touched_submaps.begin(); a != touched_submaps.end(); ++a) {
    for (auto b = std::next(a); b != touched_submaps.end(); ++b) paired_edges_.insert({*a, *b});
  }
  rec.fused.insert(s.seq);
  rec.history[s.seq] = {x_WL_fused, cov_L_fused};
  while (static_cast<int>(rec.history.size()) > config_.frame_history_per_robot) {
    rec.history.erase(rec.history.begin());
  }
  retire_frames(robot_id, removals);
  // (8) Beyond the paper: segments inside a robot's footprint are bodies, not walls.
  if (footprints_) remove_footprint_segments(s, x_WL_fused, removals, rep);
  // (9) Beyond the paper: two wall faces cannot cross; the less certain one goes.
  if (config_.crossing_margin_m > 0.0) remove_crossing_segments(unpaired, removals, rep);
  rep.time.frames_s = clock.lap();

  state_.remove(removals);
  rep.time.remove_s = clock.lap();

  // Covariance supervision (DESIGN §4, §9): cheap by default.
  rep.health_scope = config_.health;
  if (config_.health == HealthCheck::kTouched) {
    std::vector<EntityId> ids;
    std::set<EntityId> seen;
    auto take = [&](EntityId id) {
      if (state_.contains(id) && seen.insert(id).second) ids.push_back(id);
    };
    for (const spmap::ImplicitMeasurement& m : accepted_measurements) {
      for (const spmap::JacobianBlock& b : m.blocks) take(b.entity);
    }
    take(rec.frames.at(rec.next_seq).frame);
    for (const EntityId u : unpaired) take(u);
    if (rep.new_submap) take(*rep.new_submap);
    if (!ids.empty()) check_pivots(state_.marginal(ids), rep);
  } else if (config_.health == HealthCheck::kFullLdlt && state_.dimension() > 0) {
    check_pivots(state_.full_covariance(), rep);
  } else if (config_.health == HealthCheck::kFullEigen && state_.dimension() > 0) {
    const Eigen::SelfAdjointEigenSolver<Eigen::MatrixXd> es(state_.full_covariance(), Eigen::EigenvaluesOnly);
    rep.min_eigenvalue = es.eigenvalues().minCoeff();
  }
  rep.time.health_s = clock.lap();

  rep.size_after = counts();
  rep.time.total_s = clock.total();
  return rep;
}

void GlobalMap::remove_footprint_segments(const LocalMapSnapshot& s, const Pose2& x_WL,
                                          std::vector<EntityId>& removals, FusionReport& rep) {
  for (const ScanPose& p : s.scan_poses) {
    const Pose2 x_WR = compose(x_WL, p.x_LR);
    footprints_->add({x_WR.x, x_WR.y});
  }
  // Every segment, not only this map's: this map's poses may cover a segment
  // another robot shipped before (the body it saw), and this map's segments
  // may lie on an earlier pose of another robot.
  const std::unordered_set<EntityId> leaving(removals.begin(), removals.end());
  const double diameter = 2.0 * footprints_->radius();
  for (const Entity& e : state_.entities()) {
    if (e.kind != EntityKind::kSegment || e.length_m > diameter || leaving.count(e.id) != 0) continue;
    const Pose2 x_WS = state_.root_location(e.id);
    const double half = 0.5 * e.length_m;
    if (footprints_->covers(x_WS.transform_point({-half, 0.0}), x_WS.transform_point({half, 0.0}))) {
      removals.push_back(e.id);
      ++rep.footprint_segments_removed;
    }
  }
}

void GlobalMap::remove_crossing_segments(const std::vector<EntityId>& added, std::vector<EntityId>& removals,
                                         FusionReport& rep) const {
  const CrossingRule rule{config_.crossing_margin_m, config_.crossing_max_angle_rad};
  std::unordered_set<EntityId> leaving(removals.begin(), removals.end());
  struct Candidate {
    EntityId id;
    EndPoints ends;
    Eigen::AlignedBox2d box;
    double length_m;
    Eigen::Index angle_row;  // row of the angular error of its own perturbation (its frame's excluded)
  };
  // Every segment staying, in W (each parent frame composed once: a fusion
  // visits every segment here, so this must stay a small part of the O(n²) update).
  std::unordered_map<EntityId, Pose2> frame_in_W;
  std::vector<Candidate> staying;
  staying.reserve(state_.entities().size());
  for (const Entity& e : state_.entities()) {
    if (e.kind != EntityKind::kSegment || leaving.count(e.id) != 0) continue;
    Pose2 x_WS = e.location;
    if (e.parent) {
      auto [frame, inserted] = frame_in_W.try_emplace(*e.parent);
      if (inserted) frame->second = state_.root_location(*e.parent);
      x_WS = compose(frame->second, e.location);
    }
    const Eigen::Vector2d half = 0.5 * e.length_m * Eigen::Vector2d(std::cos(x_WS.phi), std::sin(x_WS.phi));
    const Eigen::Vector2d mid(x_WS.x, x_WS.y);
    const EndPoints ends{mid - half, mid + half};
    Eigen::AlignedBox2d box(ends.start.cwiseMin(ends.end), ends.start.cwiseMax(ends.end));
    staying.push_back({e.id, ends, box, e.length_m, e.offset + 1});
  }
  std::vector<std::size_t> new_ones;  // indices into staying
  const std::unordered_set<EntityId> added_set(added.begin(), added.end());
  for (std::size_t i = 0; i < staying.size(); ++i) {
    if (added_set.count(staying[i].id) != 0) new_ones.push_back(i);
  }
  for (const std::size_t i : new_ones) {
    const Candidate& a = staying[i];
    if (leaving.count(a.id) != 0) continue;
    for (const Candidate& b : staying) {
      // Boxes that do not touch hold no crossing: most pairs stop here.
      if (!a.box.intersects(b.box) || b.id == a.id || leaving.count(b.id) != 0 ||
          !segments_cross(a.ends, b.ends, rule)) {
        continue;
      }
      // The direction known less well goes (the shorter one on a tie).
      const double var_a = state_.covariance(a.angle_row, a.angle_row);
      const double var_b = state_.covariance(b.angle_row, b.angle_row);
      const bool drop_a = var_a != var_b ? var_a > var_b : a.length_m < b.length_m;
      const EntityId drop = drop_a ? a.id : b.id;
      removals.push_back(drop);
      leaving.insert(drop);
      ++rep.crossing_segments_removed;
      if (drop_a) break;
    }
  }
}

void GlobalMap::retire_frames(int robot_id, std::vector<EntityId>& removals) {
  RobotRecord& rec = robot(robot_id);
  for (auto it = rec.frames.begin(); it != rec.frames.end();) {
    const std::int64_t seq = it->first;
    const FrameSlot& slot = it->second;
    const bool needed = seq == rec.next_seq || slot.robot.has_value() || (seq == rec.min_seq && rec.min_seq > 0);
    if (needed) {
      ++it;
      continue;
    }
    const EntityId frame = slot.frame;
    it = rec.frames.erase(it);
    const bool shared = std::any_of(rec.frames.begin(), rec.frames.end(),
                                    [frame](const auto& kv) { return kv.second.frame == frame; });
    if (!shared && !is_submap(frame)) removals.push_back(frame);
  }
}

}  // namespace lmf::fusion
