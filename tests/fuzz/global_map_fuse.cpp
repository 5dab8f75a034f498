// Fuzz target: hostile local maps and sightings against a GlobalMap in
// mid-mission (Corpus::prepared_map: two robots joined, several fusions).
// Input: one byte choosing the path, then the message bytes:
//   0  local_map_t -> runtime::decode<LocalMapSnapshot> -> GlobalMap::fuse      (lmf-server's path)
//   1  sighting_t  -> runtime::decode<Sighting>          -> GlobalMap::add_sighting
//   2  local_map_t -> structure only, no runtime checks   -> GlobalMap::fuse
//      (covariance: n x n row-major if it has n² values, so it can be asymmetric;
//      the packed triangle if it has n(n+1)/2; else the largest square it fills)
//   3  sighting_t  -> structure only, no runtime checks   -> GlobalMap::add_sighting
// Paths 2 and 3 test the GlobalMap's own validation (its header promises
// InvalidInput and an unchanged map for every bad input), not only runtime's.
// Properties: InvalidInput leaves the map unchanged (MapFingerprint); nothing
// else is thrown; an accepted input leaves a finite map.
#include <cmath>
#include <cstddef>
#include <cstdint>
#include <span>
#include <string>
#include <vector>

#include "fuzz_support.hpp"
#include "lmf/fusion/global_map.hpp"
#include "runtime/convert.hpp"

namespace {

using lmf::fuzz::Bytes;

enum Path : std::uint8_t { kLocalMap = 0, kSighting = 1, kRawLocalMap = 2, kRawSighting = 3, kNumPaths = 4 };

const char* reason_name(lmf::fusion::InvalidInput::Reason reason) {
  switch (reason) {
    case lmf::fusion::InvalidInput::Reason::kMalformed: return "map_malformed";
    case lmf::fusion::InvalidInput::Reason::kNonFinite: return "map_non_finite";
    case lmf::fusion::InvalidInput::Reason::kOutOfRange: return "map_out_of_range";
    case lmf::fusion::InvalidInput::Reason::kNotSymmetricPsd: return "map_not_symmetric_psd";
    case lmf::fusion::InvalidInput::Reason::kDuplicate: return "map_duplicate";
  }
  return "map_unknown_reason";
}

// The map an input works on: a fresh copy of the prepared map for every input
// that reaches it, so each input is reproducible alone.
struct Working {
  lmf::fusion::GlobalMap map = lmf::fuzz::corpus().prepared_map;
  lmf::fuzz::MapFingerprint prepared = lmf::fuzz::fingerprint(lmf::fuzz::corpus().prepared_map);
  bool dirty = false;
};

Working& working() {
  static Working w;
  return w;
}

void check_finite(const lmf::fusion::GlobalMap& map, const std::string& what) {
  for (const lmf::fusion::SegmentView& s : map.segments()) {
    if (!std::isfinite(s.x_WS.x) || !std::isfinite(s.x_WS.y) || !std::isfinite(s.x_WS.phi) ||
        !std::isfinite(s.length_m) || !s.covariance.allFinite()) {
      lmf::fuzz::fail(what + " was accepted and left a non-finite segment " + std::to_string(s.id));
    }
  }
  for (const lmf::fusion::CorrectedFrame& f : map.corrected_frames()) {
    if (!std::isfinite(f.x_WL.x) || !std::isfinite(f.x_WL.y) || !std::isfinite(f.x_WL.phi) || !f.covariance.allFinite()) {
      lmf::fuzz::fail(what + " was accepted and left a non-finite frame of robot " + std::to_string(f.robot_id));
    }
  }
}

template <class Op>
void apply(const std::string& what, Op op) {
  Working& w = working();
  if (w.dirty) w.map = lmf::fuzz::corpus().prepared_map;
  w.dirty = true;
  try {
    op(w.map);
  } catch (const lmf::fusion::InvalidInput& e) {
    const lmf::fuzz::MapFingerprint after = lmf::fuzz::fingerprint(w.map);
    if (!(after == w.prepared)) {
      lmf::fuzz::fail(what + " threw InvalidInput (" + e.what() + ") but changed the map: " + w.prepared.describe() +
                      " -> " + after.describe());
    }
    lmf::fuzz::note_outcome(reason_name(e.reason()));
    return;
  }
  check_finite(w.map, what);
  lmf::fuzz::note_outcome("accepted");
}

lmf::LocalMapSnapshot unchecked_snapshot(const lmf::local_map_t& msg) {
  lmf::LocalMapSnapshot s;
  s.robot_id = msg.robot_id;
  s.seq = msg.seq;
  s.first_utime = msg.first_scan_utime;
  s.last_utime = msg.utime;
  s.x_LR = lmf::Pose2(msg.robot.x, msg.robot.y, msg.robot.phi);
  for (const lmf::segment_t& seg : msg.segments) {
    s.segments.push_back({lmf::Pose2(seg.location.x, seg.location.y, seg.location.phi), seg.length});
  }
  const auto n = static_cast<Eigen::Index>(3 + 2 * msg.segments.size());
  const auto values = static_cast<Eigen::Index>(msg.covariance.size());
  if (values == n * n) {
    s.covariance = Eigen::Map<const Eigen::Matrix<double, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor>>(
        msg.covariance.data(), n, n);
  } else if (values == n * (n + 1) / 2) {
    s.covariance = lmf::runtime::unpack_upper_triangle(msg.covariance, static_cast<int>(n));
  } else {
    const auto k = static_cast<Eigen::Index>(std::sqrt(static_cast<double>(values)));
    s.covariance = Eigen::Map<const Eigen::MatrixXd>(msg.covariance.data(), k, k);
  }
  for (std::size_t i = 0; i < msg.scan_poses.size() && i < msg.scan_utimes.size(); ++i) {
    const lmf::pose2_t& p = msg.scan_poses[i];
    s.scan_poses.push_back({msg.scan_utimes[i], lmf::Pose2(p.x, p.y, p.phi)});
  }
  return s;
}

lmf::fusion::RobotSighting unchecked_sighting(const lmf::sighting_t& msg) {
  const auto pose = [](const lmf::pose2_t& p) { return lmf::Pose2(p.x, p.y, p.phi); };
  const auto cov = [](const double* packed) {
    return Eigen::Matrix3d(lmf::runtime::unpack_upper_triangle(std::span<const double>(packed, 6), 3));
  };
  lmf::fusion::RobotSighting s;
  s.utime = msg.utime;
  s.observer_id = msg.observer_id;
  s.observed_id = msg.observed_id;
  s.observer_seq = msg.observer_seq;
  s.x_LA = pose(msg.observer_in_local);
  s.cov_LA = cov(msg.observer_covariance);
  s.x_AB = pose(msg.relative);
  s.cov_AB = cov(msg.covariance);
  s.observed_seq = msg.observed_seq;
  s.x_LB = pose(msg.observed_in_local);
  s.cov_LB = cov(msg.observed_covariance);
  return s;
}

template <class T>
bool decoded_or_note(const lmf::runtime::Checked<T>& decoded) {
  if (!decoded) lmf::fuzz::note_outcome(lmf::runtime::reason_name(decoded.rejection().reason));
  return decoded.ok();
}

Bytes with_path(Path path, Bytes message) {
  message.insert(message.begin(), static_cast<std::uint8_t>(path));
  return message;
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  if (size < 1) {
    lmf::fuzz::note_outcome("empty");
    return 0;
  }
  const auto path = static_cast<Path>(data[0] % kNumPaths);
  const std::uint8_t* bytes = data + 1;
  const std::size_t length = size - 1;
  switch (path) {
    case kLocalMap: {
      const auto decoded = lmf::runtime::decode<lmf::LocalMapSnapshot>(bytes, length);
      if (!decoded_or_note(decoded)) return 0;
      apply("fuse(decoded local map)", [&](lmf::fusion::GlobalMap& map) { map.fuse(decoded.value()); });
      break;
    }
    case kSighting: {
      const auto decoded = lmf::runtime::decode<lmf::fusion::RobotSighting>(bytes, length);
      if (!decoded_or_note(decoded)) return 0;
      const lmf::fusion::RobotSighting s = decoded.value();
      apply("add_sighting(decoded sighting)", [&](lmf::fusion::GlobalMap& map) { map.add_sighting(s); });
      break;
    }
    case kRawLocalMap: {
      const auto decoded = lmf::runtime::decode_message<lmf::local_map_t>(bytes, length);
      if (!decoded_or_note(decoded)) return 0;
      const lmf::LocalMapSnapshot s = unchecked_snapshot(decoded.value());
      apply("fuse(unchecked local map)", [&](lmf::fusion::GlobalMap& map) { map.fuse(s); });
      break;
    }
    case kRawSighting: {
      const auto decoded = lmf::runtime::decode_message<lmf::sighting_t>(bytes, length);
      if (!decoded_or_note(decoded)) return 0;
      const lmf::fusion::RobotSighting s = unchecked_sighting(decoded.value());
      apply("add_sighting(unchecked sighting)", [&](lmf::fusion::GlobalMap& map) { map.add_sighting(s); });
      break;
    }
    case kNumPaths: break;
  }
  return 0;
}

std::vector<Bytes> LmfFuzzSeeds() {
  const lmf::fuzz::Corpus& c = lmf::fuzz::corpus();
  std::vector<Bytes> seeds;
  for (const lmf::LocalMapSnapshot& map : c.pending_maps) {
    lmf::local_map_t msg = lmf::runtime::to_message(map).value();
    seeds.push_back(with_path(kLocalMap, lmf::fuzz::encode(msg)));
    seeds.push_back(with_path(kRawLocalMap, lmf::fuzz::encode(msg)));
    // The full n x n matrix, row by row, for asymmetric mutations.
    const Eigen::Matrix<double, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor> P = map.covariance;
    msg.covariance.assign(P.data(), P.data() + P.size());
    msg.num_covariance = static_cast<std::int32_t>(msg.covariance.size());
    seeds.push_back(with_path(kRawLocalMap, lmf::fuzz::encode(msg)));
  }
  // A map of a robot that has not joined (queued).
  lmf::LocalMapSnapshot stranger = c.local_maps.front();
  stranger.robot_id = 5;
  seeds.push_back(with_path(kLocalMap, lmf::fuzz::encode(lmf::runtime::to_message(stranger).value())));
  for (const lmf::fusion::RobotSighting& s : c.pending_sightings) {
    const lmf::sighting_t msg = lmf::runtime::to_message(s).value();
    seeds.push_back(with_path(kSighting, lmf::fuzz::encode(msg)));
    seeds.push_back(with_path(kRawSighting, lmf::fuzz::encode(msg)));
  }
  return seeds;
}
