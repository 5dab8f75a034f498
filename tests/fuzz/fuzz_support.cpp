#include "fuzz_support.hpp"

#include <sys/mman.h>
#include <unistd.h>

#include <cerrno>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <cmath>
#include <sstream>

#include <Eigen/Eigenvalues>

#include "lmf/io/carmen.hpp"
#include "lmf/sim/mission.hpp"

namespace lmf::fuzz {

namespace {

std::string_view g_outcome;

// ---- bitwise comparison ---------------------------------------------------------

bool same_bits(double a, double b) { return std::memcmp(&a, &b, sizeof a) == 0; }

class Differ {
 public:
  void num(double a, double b, const std::string& what) {
    if (out_.empty() && !same_bits(a, b)) out_ = what + ": " + std::to_string(a) + " vs " + std::to_string(b);
  }
  void integer(std::int64_t a, std::int64_t b, const std::string& what) {
    if (out_.empty() && a != b) out_ = what + ": " + std::to_string(a) + " vs " + std::to_string(b);
  }
  void pose(const Pose2& a, const Pose2& b, const std::string& what) {
    num(a.x, b.x, what + ".x");
    num(a.y, b.y, what + ".y");
    num(a.phi, b.phi, what + ".phi");
  }
  void matrix(const Eigen::MatrixXd& a, const Eigen::MatrixXd& b, const std::string& what) {
    integer(a.rows(), b.rows(), what + " rows");
    integer(a.cols(), b.cols(), what + " cols");
    if (!out_.empty()) return;
    for (Eigen::Index j = 0; j < a.cols(); ++j) {
      for (Eigen::Index i = 0; i < a.rows(); ++i) {
        num(a(i, j), b(i, j), what + "(" + std::to_string(i) + "," + std::to_string(j) + ")");
      }
    }
  }
  std::string result() const { return out_; }

 private:
  std::string out_;
};

// ---- fingerprint ---------------------------------------------------------------------

class Hasher {
 public:
  void bytes(const void* data, std::size_t size) {
    const auto* p = static_cast<const unsigned char*>(data);
    for (std::size_t i = 0; i < size; ++i) {
      h_ ^= p[i];
      h_ *= 0x100000001b3ULL;  // FNV-1a
    }
  }
  void word(std::uint64_t v) {
    h_ ^= v + 0x9e3779b97f4a7c15ULL + (h_ << 6) + (h_ >> 2);
    h_ *= 0x100000001b3ULL;
  }
  void num(double v) {
    std::uint64_t bits = 0;
    std::memcpy(&bits, &v, sizeof bits);
    word(bits);
  }
  void integer(std::int64_t v) { word(static_cast<std::uint64_t>(v)); }
  void pose(const Pose2& p) {
    num(p.x);
    num(p.y);
    num(p.phi);
  }
  void matrix(const Eigen::MatrixXd& m) {
    integer(m.rows());
    integer(m.cols());
    for (Eigen::Index j = 0; j < m.cols(); ++j) {
      for (Eigen::Index i = 0; i < m.rows(); ++i) num(m(i, j));
    }
  }
  std::uint64_t value() const { return h_; }

 private:
  std::uint64_t h_ = 0xcbf29ce484222325ULL;
};

// ---- the corpus ----------------------------------------------------------------------------

Eigen::Matrix3d sighting_covariance() { return Eigen::Vector3d(0.05 * 0.05, 0.05 * 0.05, 0.02 * 0.02).asDiagonal(); }

lmf::agent_status_t agent_status(int robot_id, bool with_rejects) {
  lmf::agent_status_t msg{};
  msg.utime = 1'700'000'000'000'000 + robot_id;
  msg.robot_id = robot_id;
  msg.joined = 1;
  msg.scans = 412;
  msg.local_map_segments = 17;
  msg.maps_shipped = 9;
  msg.maps_acknowledged = 8;
  msg.scan_time_p50_ms = 3.5f;
  msg.scan_time_p99_ms = 11.25f;
  msg.scan_time_max_ms = 19.0f;
  msg.window_scans = 4;
  msg.covariance_ok = 1;
  msg.global_pose = runtime::to_message(Pose2(3.0, -1.5, 0.7));
  msg.mission_done = 0;
  if (with_rejects) {
    msg.reject_reasons = {"decode_failed", "stale_sequence", "non_finite"};
    msg.reject_counts = {3, 1, 12};
  }
  msg.num_reject_reasons = static_cast<std::int32_t>(msg.reject_reasons.size());
  return msg;
}

lmf::server_status_t server_status(bool with_rejects) {
  lmf::server_status_t msg{};
  msg.utime = 1'700'000'000'500'000;
  msg.num_robots_joined = 2;
  msg.num_segments = 140;
  msg.num_submaps = 12;
  msg.num_graph_edges = 15;
  msg.fusions = 13;
  msg.last_fusion_ms = 21.5f;
  msg.mean_fusion_ms = 14.0f;
  msg.queue_length = 1;
  msg.covariance_ok = 1;
  msg.min_eigenvalue = 1e-9f;
  if (with_rejects) {
    msg.reject_reasons = {"covariance_not_psd", "unknown_robot"};
    msg.reject_counts = {2, 5};
  }
  msg.num_reject_reasons = static_cast<std::int32_t>(msg.reject_reasons.size());
  return msg;
}

runtime::CorrectedFrames corrected_frames_of(const fusion::GlobalMap& map, std::int64_t fusions) {
  runtime::CorrectedFrames out;
  out.utime = 30'000'000;
  out.fusion_count = fusions;
  for (fusion::CorrectedFrame f : map.corrected_frames()) {
    f.covariance = 0.5 * (f.covariance + f.covariance.transpose());  // as lmf-server publishes it
    out.frames.push_back(f);
  }
  return out;
}

lmf::global_map_t global_map_of(const fusion::GlobalMap& map, std::int64_t fusions) {
  lmf::global_map_t msg{};
  msg.utime = 30'000'000;
  msg.fusion_count = fusions;
  const fusion::MapCounts counts = map.counts();
  msg.num_submaps = counts.submaps;
  msg.num_graph_edges = counts.graph_edges;
  for (const fusion::SegmentView& s : map.segments()) {
    msg.endpoints.push_back({static_cast<float>(s.start_W.x()), static_cast<float>(s.start_W.y()),
                             static_cast<float>(s.end_W.x()), static_cast<float>(s.end_W.y())});
  }
  msg.num_segments = static_cast<std::int32_t>(msg.endpoints.size());
  return msg;
}

Corpus make_corpus() {
  Corpus c;
  // A short two-robot mission: robot 1 starts 5 m ahead of robot 0 (in its
  // view), so the simulator reports sightings early; small local maps (3 m)
  // keep the seeds small and the fusions quick.
  sim::MissionConfig mission_config;
  mission_config.seed = 11;
  mission_config.num_robots = 2;
  mission_config.duration_s = 24.0;
  mission_config.laser.num_beams = 181;
  const sim::Mission mission = sim::simulate_mission(mission_config);

  LocalMapConfig local_config;
  local_config.ship_distance_m = 3.0;
  std::vector<LocalMap> agents;
  std::vector<std::vector<runtime::ScanAck>> acks(mission.robots.size());
  std::vector<std::vector<LocalMapSnapshot>> shipped(mission.robots.size());
  for (const sim::RobotRun& run : mission.robots) agents.emplace_back(local_config, run.id);
  const std::size_t num_scans = mission.robots.front().scans.size();
  const std::size_t prepared_at = num_scans - 6;
  for (std::size_t k = 0; k < num_scans; ++k) {
    if (k == prepared_at) {
      c.prepared_local_map = agents[0];
      c.prepared_last_utime = mission.robots[0].scans[k - 1].utime;
    }
    if (k >= prepared_at) {
      c.next_scans.push_back(runtime::RobotScan{0, static_cast<std::int64_t>(k), mission.robots[0].scans[k]});
    }
    for (std::size_t r = 0; r < mission.robots.size(); ++r) {
      const sim::RobotRun& run = mission.robots[r];
      if (k >= run.scans.size()) continue;
      LocalMap& agent = agents[r];
      if (agent.process_scan(run.scans[k]).should_ship) {
        shipped[r].push_back(agent.snapshot());
        agent.reset();
      }
      acks[r].push_back(runtime::ScanAck{run.scans[k].utime, run.id, static_cast<std::int64_t>(k), agent.seq(),
                                         agent.x_LR(), agent.robot_covariance()});
      if (k % 25 == 3) c.scans.push_back(runtime::RobotScan{run.id, static_cast<std::int64_t>(k), run.scans[k]});
      if (k % 40 == 7) c.scan_acks.push_back(acks[r].back());
    }
  }
  for (const auto& maps : shipped) c.local_maps.insert(c.local_maps.end(), maps.begin(), maps.end());
  for (const sim::Sighting& s : mission.sightings) {
    const runtime::ScanAck& a = acks[static_cast<std::size_t>(s.observer)][s.observer_scan];
    const runtime::ScanAck& b = acks[static_cast<std::size_t>(s.observed)][s.observed_scan];
    fusion::RobotSighting out;
    out.utime = s.utime;
    out.observer_id = s.observer;
    out.observed_id = s.observed;
    out.x_AB = s.x_AB;
    out.cov_AB = sighting_covariance();
    out.observer_seq = a.local_map_seq;
    out.x_LA = a.x_LR;
    out.cov_LA = 0.5 * (a.covariance + a.covariance.transpose());
    out.observed_seq = b.local_map_seq;
    out.x_LB = b.x_LR;
    out.cov_LB = 0.5 * (b.covariance + b.covariance.transpose());
    c.sightings.push_back(out);
  }

  // The prepared global map, as lmf-server holds it mid-mission.
  const auto& maps0 = shipped.at(0);
  const auto& maps1 = shipped.at(1);
  if (maps0.size() < 2 || maps1.size() < 2) fail("fuzz corpus: the simulated mission shipped too few local maps");
  c.prepared_map.join_robot(0, Pose2());  // L = W (docs/design.md §5)
  std::int64_t fusions = 0;
  for (std::size_t i = 0; i + 1 < maps0.size(); ++i) fusions += static_cast<std::int64_t>(c.prepared_map.fuse(maps0[i]).size());
  const Pose2 x_WL1 = between(mission.robots[0].true_poses.front(), mission.robots[1].true_poses.front());
  c.prepared_map.join_robot(1, x_WL1, Eigen::Vector3d(1e-4, 1e-4, 1e-5).asDiagonal());
  for (std::size_t i = 0; i + 1 < maps1.size(); ++i) fusions += static_cast<std::int64_t>(c.prepared_map.fuse(maps1[i]).size());
  c.pending_maps = {maps0.back(), maps1.back()};
  // Robot 2 (never simulated) seen by robot 0 and by robot 1 in the local
  // maps the prepared map expects next from them (so robot 2 joins).
  for (int observer = 0; observer < 2; ++observer) {
    fusion::RobotSighting s;
    s.utime = 20'000'000 + observer;
    s.observer_id = observer;
    s.observed_id = 2;
    s.x_AB = Pose2(2.5, -0.4, 2.8);
    s.cov_AB = sighting_covariance();
    s.observer_seq = c.prepared_map.corrected_frame(observer).value().map_seq;
    s.x_LA = Pose2(1.2, 0.1, 0.05);
    s.cov_LA = Eigen::Vector3d(4e-4, 3e-4, 1e-4).asDiagonal();
    s.observed_seq = 0;
    s.x_LB = Pose2();
    c.pending_sightings.push_back(s);
  }

  c.corrected_frames.push_back(corrected_frames_of(c.prepared_map, fusions));
  c.corrected_frames.push_back(runtime::CorrectedFrames{0, 0, {}});
  c.global_maps.push_back(global_map_of(c.prepared_map, fusions));
  c.global_maps.push_back(lmf::global_map_t{});
  c.local_map_acks = {{1'700'000'000'000'000, 0, 3, runtime::LocalMapAck::Status::kFused},
                      {1'700'000'000'000'001, 1, 0, runtime::LocalMapAck::Status::kDuplicate},
                      {1'700'000'000'000'002, 2, 7, runtime::LocalMapAck::Status::kQueued}};
  c.sighting_acks = {{24'000'000, 0, 1, runtime::SightingAck::Status::kApplied},
                     {0, 1, 0, runtime::SightingAck::Status::kDuplicate},
                     {1'700'000'000'000'000, 2, 3, runtime::SightingAck::Status::kRejected}};
  c.mission_ends = {{24'000'000, {0, 1}}, {1, {0, 1, 2, 3, 4, 5, 6, 7}}, {0, {}}};
  c.agent_statuses = {agent_status(0, true), agent_status(1, false)};
  c.server_statuses = {server_status(true), server_status(false)};

  // CARMEN lines: FLASER from the simulator, the other kinds hand-made.
  for (std::size_t i = 0; i < c.scans.size() && i < 4; ++i) {
    c.carmen_lines.push_back(io::carmen_flaser_line(c.scans[i].scan, "fuzz"));
  }
  c.carmen_lines.push_back(
      "ROBOTLASER1 0 -1.5707963 3.1415927 0.7853982 81.9 0.01 0 5 1.5 2.25 80.0 0.5 3.125 2 10 20 "
      "1.0 2.0 0.1 1.05 2.0 0.1 0.3 0.05 0.5 0.5 0.2 1234.500000 host 1234.501");
  c.carmen_lines.push_back("ODOM 1.25 -0.5 3.1 0.3 0.01 0 1234.567890 host 1234.6");
  c.carmen_lines.push_back("PARAM robot_front_laser_max 81.9 nohost 1234.0 1234.0");
  c.carmen_lines.push_back("# a comment FLASER 3 1 2 3");
  c.carmen_lines.push_back("SYNC 1 2 3");
  return c;
}

}  // namespace

void note_outcome(std::string_view outcome) { g_outcome = outcome; }

std::string_view take_outcome() {
  const std::string_view out = g_outcome;
  g_outcome = {};
  return out;
}

void fail(const std::string& what) {
  std::fprintf(stderr, "lmf-fuzz: PROPERTY FAILED: %s\n", what.c_str());
  std::fflush(stderr);
  std::abort();
}

std::filesystem::path scratch_file(const void* data, std::size_t size) {
  static const int fd = [] {
    const int f = ::memfd_create("lmf-fuzz-scratch", 0);
    if (f < 0) fail(std::string("memfd_create: ") + std::strerror(errno));
    return f;
  }();
  if (::ftruncate(fd, 0) != 0) fail(std::string("ftruncate: ") + std::strerror(errno));
  const auto* p = static_cast<const char*>(data);
  std::size_t done = 0;
  while (done < size) {
    const ssize_t n = ::pwrite(fd, p + done, size - done, static_cast<off_t>(done));
    if (n <= 0) fail(std::string("pwrite: ") + std::strerror(errno));
    done += static_cast<std::size_t>(n);
  }
  return "/proc/self/fd/" + std::to_string(fd);
}

const Corpus& corpus() {
  static const Corpus c = make_corpus();
  return c;
}

MapFingerprint fingerprint(const fusion::GlobalMap& map) {
  MapFingerprint f;
  f.counts = map.counts();
  Hasher h;
  h.integer(map.queued_count());
  for (const int robot : map.robots()) {
    h.integer(robot);
    // Records of the first sequence numbers (the mission's are small).
    for (std::int64_t seq = 0; seq < 32; ++seq) h.integer((map.has_fused(robot, seq) ? 1 : 0) + (map.is_queued(robot, seq) ? 2 : 0));
  }
  for (const fusion::CorrectedFrame& c : map.corrected_frames()) {
    h.integer(c.robot_id);
    h.integer(c.map_seq);
    h.pose(c.x_WL);
    h.matrix(c.covariance);
  }
  const fusion::GlobalState& state = map.state();
  h.integer(state.dimension());
  for (const spmap::Entity& e : state.entities()) {
    h.integer(e.id);
    h.integer(static_cast<std::int64_t>(e.kind));
    h.pose(e.location);
    h.num(e.length_m);
    h.integer(e.parent ? static_cast<std::int64_t>(*e.parent) : -1);
    h.integer(e.offset);
  }
  // The covariance: only its lower triangle is stored (GlobalState header).
  const auto P = state.lower_view();
  for (Eigen::Index j = 0; j < P.cols(); ++j) h.bytes(P.col(j).data() + j, static_cast<std::size_t>(P.rows() - j) * sizeof(double));
  for (const fusion::SegmentView& s : map.segments()) {
    h.integer(s.id);
    h.integer(s.submap);
    h.pose(s.x_WS);
    h.num(s.length_m);
    h.matrix(s.covariance);
  }
  for (const fusion::SubmapView& s : map.submaps()) {
    h.integer(s.frame);
    h.integer(s.robot_id);
    h.integer(s.seq);
    h.pose(s.x_WF);
    h.integer(s.segments);
  }
  for (const fusion::GraphEdge& e : map.graph_edges()) {
    h.integer(e.a);
    h.integer(e.b);
    h.integer(static_cast<std::int64_t>(e.kind));
  }
  f.hash = h.value();
  return f;
}

bool MapFingerprint::operator==(const MapFingerprint& other) const {
  return hash == other.hash && counts.segments == other.counts.segments && counts.submaps == other.counts.submaps &&
         counts.robots_joined == other.counts.robots_joined && counts.graph_edges == other.counts.graph_edges &&
         counts.queued_local_maps == other.counts.queued_local_maps &&
         counts.state_dimension == other.counts.state_dimension;
}

std::string MapFingerprint::describe() const {
  std::ostringstream out;
  out << "segments " << counts.segments << ", submaps " << counts.submaps << ", robots " << counts.robots_joined
      << ", edges " << counts.graph_edges << ", queued " << counts.queued_local_maps << ", n "
      << counts.state_dimension << ", hash " << std::hex << hash;
  return out.str();
}

std::string covariance_violation(const Eigen::MatrixXd& P) {
  if (P.size() == 0) return "";
  if (!P.allFinite()) return "not finite";
  if (P != P.transpose()) return "not symmetric";
  const double max_diagonal = P.diagonal().maxCoeff();
  const double tolerance = 2e-9 * std::max(max_diagonal, 0.0);
  for (Eigen::Index j = 0; j < P.cols(); ++j) {
    if (P(j, j) < -tolerance) return "negative variance P(" + std::to_string(j) + "," + std::to_string(j) + ")";
    for (Eigen::Index i = j + 1; i < P.rows(); ++i) {
      // P + tolerance I PSD implies this 2 x 2 minor condition.
      // (Two square roots: the product of two tiny variances underflows.)
      const double bound =
          std::sqrt(std::max(P(i, i), 0.0) + tolerance) * std::sqrt(std::max(P(j, j), 0.0) + tolerance) * (1.0 + 1e-6);
      if (std::abs(P(i, j)) > bound) {
        std::ostringstream out;
        out << "|P(" << i << "," << j << ")| = " << std::abs(P(i, j)) << " > sqrt((P_ii + t)(P_jj + t)) = " << bound;
        return out.str();
      }
    }
  }
  const Eigen::SelfAdjointEigenSolver<Eigen::MatrixXd> eigen(P, Eigen::EigenvaluesOnly);
  const double slack = 64.0 * static_cast<double>(P.rows()) * 2.2e-16 * P.cwiseAbs().maxCoeff();
  if (eigen.info() != Eigen::Success || eigen.eigenvalues().minCoeff() < -(tolerance + slack)) {
    return "smallest eigenvalue " + std::to_string(eigen.eigenvalues().minCoeff()) + " (max P_ii " +
           std::to_string(max_diagonal) + ")";
  }
  return "";
}

// ---- differences ------------------------------------------------------------------------

std::string difference(const runtime::RobotScan& a, const runtime::RobotScan& b) {
  Differ d;
  d.integer(a.robot_id, b.robot_id, "robot_id");
  d.integer(a.seq, b.seq, "seq");
  d.integer(a.scan.utime, b.scan.utime, "utime");
  d.pose(a.scan.odometry, b.scan.odometry, "odometry");
  d.num(a.scan.angle_min_rad, b.scan.angle_min_rad, "angle_min");
  d.num(a.scan.angle_increment_rad, b.scan.angle_increment_rad, "angle_increment");
  d.num(a.scan.max_range_m, b.scan.max_range_m, "max_range");
  d.integer(static_cast<std::int64_t>(a.scan.ranges_m.size()), static_cast<std::int64_t>(b.scan.ranges_m.size()), "beams");
  for (std::size_t i = 0; i < a.scan.ranges_m.size() && i < b.scan.ranges_m.size(); ++i) {
    d.num(a.scan.ranges_m[i], b.scan.ranges_m[i], "ranges[" + std::to_string(i) + "]");
  }
  return d.result();
}

std::string difference(const LocalMapSnapshot& a, const LocalMapSnapshot& b) {
  Differ d;
  d.integer(a.robot_id, b.robot_id, "robot_id");
  d.integer(a.seq, b.seq, "seq");
  d.integer(a.first_utime, b.first_utime, "first_utime");
  d.integer(a.last_utime, b.last_utime, "last_utime");
  d.pose(a.x_LR, b.x_LR, "x_LR");
  d.integer(static_cast<std::int64_t>(a.segments.size()), static_cast<std::int64_t>(b.segments.size()), "segments");
  for (std::size_t i = 0; i < a.segments.size() && i < b.segments.size(); ++i) {
    d.pose(a.segments[i].location, b.segments[i].location, "segments[" + std::to_string(i) + "]");
    d.num(a.segments[i].length_m, b.segments[i].length_m, "segments[" + std::to_string(i) + "].length");
  }
  d.matrix(a.covariance, b.covariance, "covariance");
  d.integer(static_cast<std::int64_t>(a.scan_poses.size()), static_cast<std::int64_t>(b.scan_poses.size()), "scan_poses");
  for (std::size_t i = 0; i < a.scan_poses.size() && i < b.scan_poses.size(); ++i) {
    d.integer(a.scan_poses[i].utime, b.scan_poses[i].utime, "scan_poses[" + std::to_string(i) + "].utime");
    d.pose(a.scan_poses[i].x_LR, b.scan_poses[i].x_LR, "scan_poses[" + std::to_string(i) + "]");
  }
  return d.result();
}

std::string difference(const runtime::CorrectedFrames& a, const runtime::CorrectedFrames& b) {
  Differ d;
  d.integer(a.utime, b.utime, "utime");
  d.integer(a.fusion_count, b.fusion_count, "fusion_count");
  d.integer(static_cast<std::int64_t>(a.frames.size()), static_cast<std::int64_t>(b.frames.size()), "frames");
  for (std::size_t i = 0; i < a.frames.size() && i < b.frames.size(); ++i) {
    const std::string what = "frames[" + std::to_string(i) + "]";
    d.integer(a.frames[i].robot_id, b.frames[i].robot_id, what + ".robot_id");
    d.integer(a.frames[i].map_seq, b.frames[i].map_seq, what + ".map_seq");
    d.pose(a.frames[i].x_WL, b.frames[i].x_WL, what + ".x_WL");
    d.matrix(a.frames[i].covariance, b.frames[i].covariance, what + ".covariance");
  }
  return d.result();
}

std::string difference(const fusion::RobotSighting& a, const fusion::RobotSighting& b) {
  Differ d;
  d.integer(a.utime, b.utime, "utime");
  d.integer(a.observer_id, b.observer_id, "observer_id");
  d.integer(a.observed_id, b.observed_id, "observed_id");
  d.pose(a.x_AB, b.x_AB, "x_AB");
  d.matrix(a.cov_AB, b.cov_AB, "cov_AB");
  d.integer(a.observer_seq, b.observer_seq, "observer_seq");
  d.pose(a.x_LA, b.x_LA, "x_LA");
  d.matrix(a.cov_LA, b.cov_LA, "cov_LA");
  d.integer(a.observed_seq, b.observed_seq, "observed_seq");
  d.pose(a.x_LB, b.x_LB, "x_LB");
  d.matrix(a.cov_LB, b.cov_LB, "cov_LB");
  return d.result();
}

std::string difference(const runtime::ScanAck& a, const runtime::ScanAck& b) {
  Differ d;
  d.integer(a.utime, b.utime, "utime");
  d.integer(a.robot_id, b.robot_id, "robot_id");
  d.integer(a.seq, b.seq, "seq");
  d.integer(a.local_map_seq, b.local_map_seq, "local_map_seq");
  d.pose(a.x_LR, b.x_LR, "x_LR");
  d.matrix(a.covariance, b.covariance, "covariance");
  return d.result();
}

std::string difference(const runtime::LocalMapAck& a, const runtime::LocalMapAck& b) {
  Differ d;
  d.integer(a.utime, b.utime, "utime");
  d.integer(a.robot_id, b.robot_id, "robot_id");
  d.integer(a.seq, b.seq, "seq");
  d.integer(static_cast<std::int64_t>(a.status), static_cast<std::int64_t>(b.status), "status");
  return d.result();
}

std::string difference(const runtime::SightingAck& a, const runtime::SightingAck& b) {
  Differ d;
  d.integer(a.utime, b.utime, "utime");
  d.integer(a.observer_id, b.observer_id, "observer_id");
  d.integer(a.observed_id, b.observed_id, "observed_id");
  d.integer(static_cast<std::int64_t>(a.status), static_cast<std::int64_t>(b.status), "status");
  return d.result();
}

std::string difference(const runtime::MissionEnd& a, const runtime::MissionEnd& b) {
  Differ d;
  d.integer(a.utime, b.utime, "utime");
  d.integer(static_cast<std::int64_t>(a.robot_ids.size()), static_cast<std::int64_t>(b.robot_ids.size()), "robot_ids");
  for (std::size_t i = 0; i < a.robot_ids.size() && i < b.robot_ids.size(); ++i) {
    d.integer(a.robot_ids[i], b.robot_ids[i], "robot_ids[" + std::to_string(i) + "]");
  }
  return d.result();
}

}  // namespace lmf::fuzz
