// What the fuzz targets of tests/fuzz share.
//
// Why tests/fuzz and not a top-level fuzz/: the targets are tests. The
// standalone driver (lmf-fuzz) is built with the tests and its short runs are
// ctest cases, so CI runs them with everything else; the libFuzzer binaries
// (LMF_BUILD_FUZZERS, clang) are compiled from the very same target files.
//
// Every target file defines
//   extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size);
//   std::vector<lmf::fuzz::Bytes> LmfFuzzSeeds();   // valid inputs made in code
// and nothing else with external linkage. The lmf-fuzz build renames both per
// target with -D (LLVMFuzzerTestOneInput=lmf_fuzz_one_<target>, ...), so one
// driver binary holds every target; libFuzzer builds use the names as they are.
//
// A target aborts (fail()) when a property breaks: a crash is the only signal
// both drivers understand. Rejections are the expected outcome of most inputs;
// targets name each one with note_outcome() so the driver can show how deep the
// mutations reach (e.g. how many inputs were accepted and fused).
#pragma once

#include <cstddef>
#include <cstdint>
#include <filesystem>
#include <string>
#include <string_view>
#include <vector>

#include "lmf/agent_status_t.hpp"
#include "lmf/fusion/global_map.hpp"
#include "lmf/global_map_t.hpp"
#include "lmf/local_map/local_map.hpp"
#include "lmf/local_map/local_map_snapshot.hpp"
#include "lmf/scan/laser_scan.hpp"
#include "lmf/server_status_t.hpp"
#include "runtime/convert.hpp"
#include "runtime/messages.hpp"

namespace lmf::fuzz {

using Bytes = std::vector<std::uint8_t>;

// The outcome of the current input: "accepted" or a reason name. `outcome`
// must outlive the process (a literal or runtime::reason_name()).
void note_outcome(std::string_view outcome);
std::string_view take_outcome();  // the last noted one ("" if none), then clears it

// A property failed: prints `what` to stderr and aborts.
[[noreturn]] void fail(const std::string& what);

// A file in memory (memfd, named /proc/self/fd/N) holding exactly `size`
// bytes of `data`, for code that only reads or writes files. One per process,
// rewritten on every call (targets run one input at a time).
std::filesystem::path scratch_file(const void* data, std::size_t size);

// Valid values made once per process from a small simulated two-robot mission
// (lmf::sim + LocalMap, the agents' code path), plus a few hand-made ones.
struct Corpus {
  std::vector<runtime::RobotScan> scans;        // both robots, a spread over the mission
  std::vector<LocalMapSnapshot> local_maps;     // every local map both robots shipped
  std::vector<runtime::ScanAck> scan_acks;      // the agents' state after each kept scan
  std::vector<fusion::RobotSighting> sightings;     // the simulator's, with the agents' state then
  std::vector<runtime::CorrectedFrames> corrected_frames;
  std::vector<runtime::LocalMapAck> local_map_acks;
  std::vector<runtime::SightingAck> sighting_acks;
  std::vector<runtime::MissionEnd> mission_ends;
  std::vector<lmf::agent_status_t> agent_statuses;
  std::vector<lmf::server_status_t> server_statuses;
  std::vector<lmf::global_map_t> global_maps;
  std::vector<std::string> carmen_lines;        // FLASER, ROBOTLASER1, ODOM, PARAM, comments

  // A GlobalMap in mid-mission: robot 0 joined (L = W) with its first local
  // maps fused, robot 1 joined at its true start with its first map fused.
  // `pending_maps` are the next local maps of both robots (not fused yet: the
  // fuse target's seeds), `pending_sightings` sightings of robot 2 (unknown to the map).
  fusion::GlobalMap prepared_map;
  std::vector<LocalMapSnapshot> pending_maps;
  std::vector<fusion::RobotSighting> pending_sightings;

  // Robot 0's LocalMap a few scans before the end of the mission (as its
  // agent holds it) and the scans that follow (the local_map_scan target's seeds).
  LocalMap prepared_local_map;
  std::int64_t prepared_last_utime = 0;  // of the last scan it processed
  std::vector<runtime::RobotScan> next_scans;
};
const Corpus& corpus();

// A cheap, exact fingerprint of everything observable in a GlobalMap: counts,
// robots, queued/fused records, entities, a hash of the covariance's lower
// triangle, segment/submap views, corrected frames and graph edges.
struct MapFingerprint {
  std::uint64_t hash = 0;
  fusion::MapCounts counts;
  std::string describe() const;
  bool operator==(const MapFingerprint& other) const;
};
MapFingerprint fingerprint(const fusion::GlobalMap& map);

// An independent check of a covariance a validator accepted: "" when P is
// finite, exactly symmetric and PSD within the validators' tolerance (every
// |P_ij| <= sqrt(P_ii P_jj) and the smallest eigenvalue of an eigen-solver,
// not the LDLT the validators use, >= -tolerance), else what is wrong.
std::string covariance_violation(const Eigen::MatrixXd& P);

// Bitwise equality of core values (after a round trip nothing may change, not
// even -0.0 into 0.0). Each returns "" when equal, else the first difference.
std::string difference(const runtime::RobotScan& a, const runtime::RobotScan& b);
std::string difference(const LocalMapSnapshot& a, const LocalMapSnapshot& b);
std::string difference(const runtime::CorrectedFrames& a, const runtime::CorrectedFrames& b);
std::string difference(const fusion::RobotSighting& a, const fusion::RobotSighting& b);
std::string difference(const runtime::ScanAck& a, const runtime::ScanAck& b);
std::string difference(const runtime::LocalMapAck& a, const runtime::LocalMapAck& b);
std::string difference(const runtime::SightingAck& a, const runtime::SightingAck& b);
std::string difference(const runtime::MissionEnd& a, const runtime::MissionEnd& b);

// Encodes with lcm-gen's encoder (runtime::encode_message), for seeds.
template <class Msg>
Bytes encode(const Msg& msg) {
  return runtime::encode_message(msg);
}

}  // namespace lmf::fuzz
