#include "lmf/fusion/global_map_archive.hpp"

#include <algorithm>
#include <cmath>
#include <cstring>
#include <istream>
#include <limits>
#include <ostream>
#include <set>
#include <unordered_set>
#include <utility>


namespace lmf::fusion {


namespace {

constexpr std::string_view kMapMagic("LMFGMAP\0", 8);
// A sanity cap on the covariance buffer a (checksummed) archive may ask for:
// 65536² doubles is 32 GiB, beyond any map this server handles.
constexpr std::int64_t kMaxCapacity = std::int64_t{1} << 16;

void write_optional(ArchiveWriter& w, const std::optional<double>& v) {
  w.boolean(v.has_value());
  w.f64(v.value_or(0.0));
}

std::optional<double> read_optional(ArchiveReader& r) {
  const bool has = r.boolean();
  const double v = r.f64();
  return has ? std::optional<double>(v) : std::nullopt;
}

}  // namespace

// ---------------------------------------------------------------------------
// The map

class GlobalMapArchive {
 public:
  static void write(ArchiveWriter& w, const GlobalMap& map);
  static GlobalMap read(ArchiveReader& r);
  static void write_config(ArchiveWriter& w, const GlobalMapConfig& c);
  static GlobalMapConfig read_config(ArchiveReader& r);
  static void write_state(ArchiveWriter& w, const GlobalState& s);
  static void read_state(ArchiveReader& r, GlobalState& s);
};

// Payload, in order:
//   config      11 f64 (alpha, gate_angle_rad, gate_distance_m, gate_gap_m,
//               gate_sigmas, min_overlap_m, careful_relative_tolerance,
//               careful_absolute_floor, snapshot_tolerance, max_coordinate_m,
//               local_map_covariance_scale),
//               u8 first_robot_defines_world, u8 health, i32 frame_history_per_robot,
//               f64 footprint_radius_m, f64 crossing_margin_m, f64 crossing_max_angle_rad,
//               registration: u8 enabled, 6 f64 (window_m, window_rad, resolution_m,
//               min_score, ambiguity_ratio, min_constraint), i32 own_recent_maps,
//               u8 confirm_pairings,
//               place_recognition: u8 enabled, 2 f64 (resolution_m, min_score),
//               i32 max_candidates
//   state       i64 next_id, i64 n, i64 capacity, u64 count + entities
//               (i64 id, u8 kind, pose, f64 length, u8 has_parent, i64 parent,
//               i64 offset), then P's lower triangle by columns (column j:
//               rows j..n-1), n(n+1)/2 f64
//   robots      u64 count + (i32 id, u8 joined, i64 next_seq, i64 min_seq,
//               frames: u64 count + (i64 seq, i64 frame, u8 has_robot, i64 robot),
//               queue: u64 count + local maps (write_local_map),
//               fused: u64 count + i64 seq,
//               history: u64 count + (i64 seq, pose, 9 f64 column-major))
//   submaps     u64 count + (i64 frame, i32 robot_id, i64 seq)
//   edges       u64 count + (i64 a, i64 b)
//   sightings   u64 count + pending RobotSighting (see write_sighting)
//   flags       u8 any_joined (version 4 had a second u8 here, always 0)
//   footprints  u64 count + (f64 x, f64 y) in the order added (0 when off)
void GlobalMapArchive::write_config(ArchiveWriter& w, const GlobalMapConfig& c) {
  // f64, u8 (bool, HealthCheck), i32, in visit_fields' order.
  struct Write {
    ArchiveWriter& w;
    void operator()(const char*, double v) const { w.f64(v); }
    void operator()(const char*, bool v) const { w.boolean(v); }
    void operator()(const char*, int v) const { w.i32(v); }
    void operator()(const char*, HealthCheck v) const { w.u8(static_cast<std::uint8_t>(v)); }
    void operator()(const char*, const FrameRegistrationConfig& g) const { visit_fields(g, *this); }
    void operator()(const char*, const PlaceRecognitionConfig& g) const { visit_fields(g, *this); }
  };
  visit_fields(c, Write{w});
}

GlobalMapConfig GlobalMapArchive::read_config(ArchiveReader& r) {
  struct Read {
    ArchiveReader& r;
    void operator()(const char*, double& v) const { v = r.f64(); }
    void operator()(const char*, bool& v) const { v = r.boolean(); }
    void operator()(const char*, int& v) const { v = r.i32(); }
    void operator()(const char* name, HealthCheck& v) const {
      const std::uint8_t code = r.u8();
      if (code > static_cast<std::uint8_t>(HealthCheck::kFullEigen)) {
        r.fail(std::string("corrupt: ") + name + " " + std::to_string(code));
      }
      v = static_cast<HealthCheck>(code);
    }
    void operator()(const char*, FrameRegistrationConfig& g) const { visit_fields(g, *this); }
    void operator()(const char*, PlaceRecognitionConfig& g) const { visit_fields(g, *this); }
  };
  GlobalMapConfig c;
  visit_fields(c, Read{r});
  try {
    c.validate();
  } catch (const std::invalid_argument& e) {
    r.fail(std::string("corrupt config: ") + e.what());
  }
  return c;
}

void GlobalMapArchive::write_state(ArchiveWriter& w, const GlobalState& s) {
  w.i64(s.next_id_);
  w.i64(s.n_);
  w.i64(s.capacity());
  w.count(s.entities_.size());
  for (const Entity& e : s.entities_) {
    w.i64(e.id);
    w.u8(static_cast<std::uint8_t>(e.kind));
    w.pose(e.location);
    w.f64(e.length_m);
    w.boolean(e.parent.has_value());
    w.i64(e.parent.value_or(0));
    w.i64(e.offset);
  }
  // Lower triangle, column by column: each piece is contiguous in the buffer.
  for (Eigen::Index j = 0; j < s.n_; ++j) {
    w.raw(s.storage_.data() + j * s.storage_.outerStride() + j, static_cast<std::size_t>(s.n_ - j) * sizeof(double));
  }
}

void GlobalMapArchive::read_state(ArchiveReader& r, GlobalState& s) {
  const std::int64_t next_id = r.i64();
  const std::int64_t n = r.i64();
  const std::int64_t capacity = r.i64();
  if (n < 0 || capacity < n || capacity > kMaxCapacity) {
    r.fail("corrupt state: dimension " + std::to_string(n) + ", capacity " + std::to_string(capacity));
  }
  const std::size_t count = r.count(43);
  std::vector<Entity> entities(count);
  std::unordered_map<EntityId, std::size_t> index;
  std::int64_t offset = 0;
  for (std::size_t i = 0; i < count; ++i) {
    Entity& e = entities[i];
    e.id = r.i64();
    const std::uint8_t kind = r.u8();
    if (kind > static_cast<std::uint8_t>(EntityKind::kSegment)) r.fail("corrupt state: entity kind " + std::to_string(kind));
    e.kind = static_cast<EntityKind>(kind);
    e.location = r.pose();
    e.length_m = r.f64();
    const bool has_parent = r.boolean();
    const std::int64_t parent = r.i64();
    if (has_parent) e.parent = parent;
    e.offset = r.i64();
    if (e.id < 0 || e.id >= next_id || !index.emplace(e.id, i).second) {
      r.fail("corrupt state: entity id " + std::to_string(e.id) + " (next id " + std::to_string(next_id) + ")");
    }
    if (e.offset != offset) r.fail("corrupt state: entity " + std::to_string(e.id) + " offset " + std::to_string(e.offset));
    offset += spmap::dof(e.kind);
  }
  if (offset != n) r.fail("corrupt state: entities span " + std::to_string(offset) + " rows, dimension " + std::to_string(n));
  for (const Entity& e : entities) {
    if (e.parent && index.count(*e.parent) == 0) {
      r.fail("corrupt state: entity " + std::to_string(e.id) + " has unknown parent " + std::to_string(*e.parent));
    }
  }
  const auto triangle = static_cast<std::uint64_t>(n) * static_cast<std::uint64_t>(n + 1) / 2;
  if (triangle > r.remaining() / sizeof(double)) r.fail("truncated: covariance of dimension " + std::to_string(n));
  Eigen::MatrixXd storage = Eigen::MatrixXd::Zero(capacity, capacity);
  for (Eigen::Index j = 0; j < n; ++j) {
    r.raw(storage.data() + j * storage.outerStride() + j, static_cast<std::size_t>(n - j) * sizeof(double));
  }
  s.entities_ = std::move(entities);
  s.index_ = std::move(index);
  s.storage_ = std::move(storage);
  s.n_ = n;
  s.next_id_ = next_id;
}

void GlobalMapArchive::write(ArchiveWriter& w, const GlobalMap& map) {
  write_config(w, map.config_);
  write_state(w, map.state_);
  const RobotArrivals& arrivals = map.arrivals_;
  w.count(arrivals.robots_.size());
  for (const auto& [id, rec] : arrivals.robots_) {
    w.i32(id);
    w.boolean(rec.joined);
    w.i64(rec.next_seq);
    w.i64(rec.min_seq);
    w.count(rec.frames.size());
    for (const auto& [seq, slot] : rec.frames) {
      w.i64(seq);
      w.i64(slot.frame);
      w.boolean(slot.robot.has_value());
      w.i64(slot.robot.value_or(0));
    }
    w.count(rec.queue.size());
    for (const auto& [seq, snapshot] : rec.queue) {
      w.i64(seq);
      write_local_map(w, snapshot);
    }
    w.count(rec.fused.size());
    for (const std::int64_t seq : rec.fused) w.i64(seq);
    w.count(rec.history.size());
    for (const auto& [seq, frame] : rec.history) {
      w.i64(seq);
      w.pose(frame.first);
      w.matrix3(frame.second);
    }
  }
  w.count(map.graph_.submaps_.size());
  for (const SubmapRecord& s : map.graph_.submaps_) {
    w.i64(s.frame);
    w.i32(s.robot_id);
    w.i64(s.seq);
  }
  w.count(map.graph_.paired_edges_.size());
  for (const auto& [a, b] : map.graph_.paired_edges_) {
    w.i64(a);
    w.i64(b);
  }
  w.count(arrivals.pending_sightings_.size());
  for (const RobotSighting& s : arrivals.pending_sightings_) write_sighting(w, s);
  w.boolean(arrivals.any_joined_);
  const std::vector<Eigen::Vector2d> none;
  const std::vector<Eigen::Vector2d>& footprints = map.footprints_ ? map.footprints_->positions() : none;
  w.count(footprints.size());
  for (const Eigen::Vector2d& p : footprints) {
    w.f64(p.x());
    w.f64(p.y());
  }
}

GlobalMap GlobalMapArchive::read(ArchiveReader& r) {
  GlobalMap map(read_config(r));
  read_state(r, map.state_);
  const GlobalState& state = map.state_;
  const auto require_entity = [&](EntityId id, const std::string& what) {
    if (!state.contains(id)) r.fail("corrupt map: " + what + " refers to unknown entity " + std::to_string(id));
  };
  RobotArrivals& arrivals = map.arrivals_;
  const std::size_t robots = r.count(41);
  for (std::size_t i = 0; i < robots; ++i) {
    const int id = r.i32();
    if (arrivals.robots_.count(id) != 0) r.fail("corrupt map: robot " + std::to_string(id) + " twice");
    RobotArrivals::Robot& rec = arrivals.robots_[id];
    const std::string who = "robot " + std::to_string(id);
    rec.joined = r.boolean();
    rec.next_seq = r.i64();
    rec.min_seq = r.i64();
    const std::size_t frames = r.count(25);
    for (std::size_t k = 0; k < frames; ++k) {
      const std::int64_t seq = r.i64();
      RobotArrivals::FrameSlot slot;
      slot.frame = r.i64();
      const bool has_robot = r.boolean();
      const std::int64_t robot = r.i64();
      if (has_robot) slot.robot = robot;
      require_entity(slot.frame, who + " frame");
      if (slot.robot) require_entity(*slot.robot, who + " pre-placed robot");
      if (!rec.frames.emplace(seq, slot).second) r.fail("corrupt map: " + who + " frame seq repeated");
    }
    if (rec.joined && rec.frames.count(rec.next_seq) == 0) r.fail("corrupt map: " + who + " has no current frame");
    const std::size_t queued = r.count(8);
    for (std::size_t k = 0; k < queued; ++k) {
      const std::int64_t seq = r.i64();
      LocalMapSnapshot s = read_local_map(r);
      if (s.seq != seq || s.robot_id != id) r.fail("corrupt map: " + who + " queue entry mismatch");
      if (!rec.queue.emplace(seq, std::move(s)).second) r.fail("corrupt map: " + who + " queued seq repeated");
    }
    const std::size_t fused = r.count(8);
    for (std::size_t k = 0; k < fused; ++k) rec.fused.insert(r.i64());
    if (rec.fused.size() != fused) r.fail("corrupt map: " + who + " fused seq repeated");
    const std::size_t history = r.count(104);
    for (std::size_t k = 0; k < history; ++k) {
      const std::int64_t seq = r.i64();
      const Pose2 x_WL = r.pose();
      const Eigen::Matrix3d cov = r.matrix3();
      rec.history[seq] = {x_WL, cov};
    }
  }
  const std::size_t submaps = r.count(20);
  for (std::size_t i = 0; i < submaps; ++i) {
    const EntityId frame = r.i64();
    const int robot_id = r.i32();
    const std::int64_t seq = r.i64();
    require_entity(frame, "submap");
    map.graph_.add_submap(frame, robot_id, seq);
  }
  const std::size_t edges = r.count(16);
  for (std::size_t i = 0; i < edges; ++i) {
    const EntityId a = r.i64();
    const EntityId b = r.i64();
    map.graph_.paired_edges_.insert({a, b});
  }
  const std::size_t pending = r.count(8);
  for (std::size_t i = 0; i < pending; ++i) arrivals.add_pending(read_sighting(r));
  arrivals.any_joined_ = r.boolean();
  const std::size_t footprints = r.count(16);
  if (footprints > 0 && !map.footprints_) r.fail("corrupt map: robot footprints with footprint_radius_m 0");
  for (std::size_t i = 0; i < footprints; ++i) {
    const double x = r.f64();
    const double y = r.f64();
    if (!std::isfinite(x) || !std::isfinite(y)) r.fail("corrupt map: a robot footprint is not finite");
    map.footprints_->add({x, y});
  }
  return map;
}

void write_global_map(ArchiveWriter& w, const GlobalMap& map) { GlobalMapArchive::write(w, map); }

GlobalMap read_global_map(ArchiveReader& r) { return GlobalMapArchive::read(r); }

void write_archive(const GlobalMap& map, std::ostream& out) {
  std::string payload;
  ArchiveWriter w(payload);
  write_global_map(w, map);
  write_framed(out, kMapMagic, kGlobalMapArchiveVersion, payload);
  if (!out) throw std::runtime_error("write_archive: the stream failed");
}

GlobalMap read_archive(std::istream& in) {
  std::uint32_t version = 0;
  const std::string payload = read_framed(in, kMapMagic, kGlobalMapArchiveVersion, version);
  ArchiveReader r(payload.data(), payload.size(), "global map archive");
  GlobalMap map = read_global_map(r);
  if (r.remaining() != 0) r.fail("corrupt: " + std::to_string(r.remaining()) + " bytes after the map");
  return map;
}

// ---------------------------------------------------------------------------
// Local maps and fusion reports

void write_local_map(ArchiveWriter& w, const LocalMapSnapshot& s) {
  w.i32(s.robot_id);
  w.i64(s.seq);
  w.i64(s.first_utime);
  w.i64(s.last_utime);
  w.pose(s.x_LR);
  w.count(s.segments.size());
  for (const SegmentEstimate& seg : s.segments) {
    w.pose(seg.location);
    w.f64(seg.length_m);
  }
  w.matrix(s.covariance);
  w.count(s.scan_poses.size());
  for (const ScanPose& p : s.scan_poses) {
    w.i64(p.utime);
    w.pose(p.x_LR);
  }
}

LocalMapSnapshot read_local_map(ArchiveReader& r) {
  LocalMapSnapshot s;
  s.robot_id = r.i32();
  s.seq = r.i64();
  s.first_utime = r.i64();
  s.last_utime = r.i64();
  s.x_LR = r.pose();
  s.segments.resize(r.count(32));
  for (SegmentEstimate& seg : s.segments) {
    seg.location = r.pose();
    seg.length_m = r.f64();
  }
  s.covariance = r.matrix();
  s.scan_poses.resize(r.count(32));
  for (ScanPose& p : s.scan_poses) {
    p.utime = r.i64();
    p.x_LR = r.pose();
  }
  return s;
}

void write_sighting(ArchiveWriter& w, const RobotSighting& s) {
  w.i64(s.utime);
  w.i32(s.observer_id);
  w.i32(s.observed_id);
  w.i64(s.observer_seq);
  w.pose(s.x_LA);
  w.matrix3(s.cov_LA);
  w.pose(s.x_AB);
  w.matrix3(s.cov_AB);
  w.i64(s.observed_seq);
  w.pose(s.x_LB);
  w.matrix3(s.cov_LB);
}

RobotSighting read_sighting(ArchiveReader& r) {
  RobotSighting s;
  s.utime = r.i64();
  s.observer_id = r.i32();
  s.observed_id = r.i32();
  s.observer_seq = r.i64();
  s.x_LA = r.pose();
  s.cov_LA = r.matrix3();
  s.x_AB = r.pose();
  s.cov_AB = r.matrix3();
  s.observed_seq = r.i64();
  s.x_LB = r.pose();
  s.cov_LB = r.matrix3();
  return s;
}

void write_fusion_report(ArchiveWriter& w, const FusionReport& f) {
  w.i32(f.robot_id);
  w.i64(f.seq);
  w.i32(f.local_segments);
  w.boolean(f.anchored_backward);
  w.u8(static_cast<std::uint8_t>(f.registration));
  w.pose(f.registration_offset);
  w.f64(f.registration_distance2);
  w.f64(f.registration_score);
  w.boolean(f.registration_unresolved);
  w.i64(f.pairs_considered);
  w.i64(f.gate_rejected);
  w.i32(f.unconfirmed_pairs);
  for (const int v : {f.chi2_rejected, f.overlap_rejected, f.jc_candidates, f.jc_rejected, f.pairings_accepted,
                      f.update_rows, f.rows_dropped, f.rows_kept}) {
    w.i32(v);
  }
  w.f64(f.update_distance2);
  w.i64(f.update_dimension);
  for (const int v : {f.segments_extended, f.local_segments_removed, f.global_segments_fused,
                      f.global_fusions_rejected, f.new_segments, f.footprint_segments_removed,
                      f.crossing_segments_removed}) {
    w.i32(v);
  }
  w.boolean(f.new_submap.has_value());
  w.i64(f.new_submap.value_or(0));
  w.pose(f.x_WL_predicted);
  w.pose(f.x_WL_fused);
  w.pose(f.x_WL_next);
  w.u8(static_cast<std::uint8_t>(f.health_scope));
  write_optional(w, f.min_ldlt_pivot);
  write_optional(w, f.min_eigenvalue);
  const MapCounts& c = f.size_after;
  for (const int v : {c.segments, c.submaps, c.robots_joined, c.graph_edges, c.queued_local_maps}) w.i32(v);
  w.i64(c.state_dimension);
  const PhaseTimes& t = f.time;
  for (const double v : {t.validate_s, t.augment_s, t.registration_s, t.gate_s, t.individual_s, t.joint_s, t.update_s, t.geometric_s,
                         t.frames_s, t.remove_s, t.health_s, t.total_s}) {
    w.f64(v);
  }
}

FusionReport read_fusion_report(ArchiveReader& r) {
  FusionReport f;
  f.robot_id = r.i32();
  f.seq = r.i64();
  f.local_segments = r.i32();
  f.anchored_backward = r.boolean();
  const std::uint8_t registration = r.u8();
  if (registration > static_cast<std::uint8_t>(RegistrationOutcome::kRelocated)) {
    r.fail("corrupt: registration outcome " + std::to_string(registration));
  }
  f.registration = static_cast<RegistrationOutcome>(registration);
  f.registration_offset = r.pose();
  f.registration_distance2 = r.f64();
  f.registration_score = r.f64();
  f.registration_unresolved = r.boolean();
  f.pairs_considered = r.i64();
  f.gate_rejected = r.i64();
  f.unconfirmed_pairs = r.i32();
  for (int* v : {&f.chi2_rejected, &f.overlap_rejected, &f.jc_candidates, &f.jc_rejected, &f.pairings_accepted,
                 &f.update_rows, &f.rows_dropped, &f.rows_kept}) {
    *v = r.i32();
  }
  f.update_distance2 = r.f64();
  f.update_dimension = r.i64();
  for (int* v : {&f.segments_extended, &f.local_segments_removed, &f.global_segments_fused,
                 &f.global_fusions_rejected, &f.new_segments,
                 &f.footprint_segments_removed, &f.crossing_segments_removed}) {
    *v = r.i32();
  }
  const bool has_submap = r.boolean();
  const std::int64_t submap = r.i64();
  if (has_submap) f.new_submap = submap;
  f.x_WL_predicted = r.pose();
  f.x_WL_fused = r.pose();
  f.x_WL_next = r.pose();
  const std::uint8_t scope = r.u8();
  if (scope > static_cast<std::uint8_t>(HealthCheck::kFullEigen)) r.fail("corrupt: health scope " + std::to_string(scope));
  f.health_scope = static_cast<HealthCheck>(scope);
  f.min_ldlt_pivot = read_optional(r);
  f.min_eigenvalue = read_optional(r);
  MapCounts& c = f.size_after;
  for (int* v : {&c.segments, &c.submaps, &c.robots_joined, &c.graph_edges, &c.queued_local_maps}) *v = r.i32();
  c.state_dimension = r.i64();
  PhaseTimes& t = f.time;
  for (double* v : {&t.validate_s, &t.augment_s, &t.registration_s, &t.gate_s, &t.individual_s, &t.joint_s, &t.update_s, &t.geometric_s,
                    &t.frames_s, &t.remove_s, &t.health_s, &t.total_s}) {
    *v = r.f64();
  }
  return f;
}

bool same_config(const GlobalMapConfig& a, const GlobalMapConfig& b) {
  std::string sa;
  std::string sb;
  ArchiveWriter wa(sa);
  ArchiveWriter wb(sb);
  GlobalMapArchive::write_config(wa, a);
  GlobalMapArchive::write_config(wb, b);
  return sa == sb;
}

}  // namespace lmf::fusion
