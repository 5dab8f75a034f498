// Fuzz target: LMF_SCAN_<id> all the way through lmf-agent's core: bytes ->
// runtime::decode<RobotScan> -> LocalMap::process_scan on robot 0's local map
// in mid-mission (Corpus::prepared_local_map, a fresh copy per input), after
// the agent's own check that scans do not go back in time.
// Properties: a scan the decoder accepts never crashes the LocalMap ("sensor
// data never aborts a process"); an std::invalid_argument leaves the map
// unchanged; an accepted scan leaves a finite state, a symmetric covariance
// with a finite, non-negative diagonal, and a valid snapshot (to_message accepts it).
#include <cmath>
#include <cstddef>
#include <cstdint>
#include <stdexcept>
#include <string>
#include <vector>

#include "decode_target.hpp"
#include "fuzz_support.hpp"
#include "lmf/local_map/local_map.hpp"

namespace {

// Everything observable of the LocalMap's state, bit for bit.
std::string state_bytes(const lmf::LocalMap& map) {
  std::string out;
  const auto add = [&out](const void* p, std::size_t n) { out.append(static_cast<const char*>(p), n); };
  const std::int64_t seq = map.seq();
  const double span = map.span_m();
  add(&seq, sizeof seq);
  add(&span, sizeof span);
  for (const lmf::spmap::Entity& e : map.map().entities()) {
    add(&e.id, sizeof e.id);
    add(&e.location, sizeof e.location);
    add(&e.length_m, sizeof e.length_m);
  }
  const Eigen::MatrixXd P = map.map().covariance();
  add(P.data(), static_cast<std::size_t>(P.size()) * sizeof(double));
  return out;
}

void check_state(const lmf::LocalMap& map) {
  for (const lmf::spmap::Entity& e : map.map().entities()) {
    if (!std::isfinite(e.location.x) || !std::isfinite(e.location.y) || !std::isfinite(e.location.phi) ||
        !std::isfinite(e.length_m)) {
      lmf::fuzz::fail("an accepted scan left a non-finite entity " + std::to_string(e.id));
    }
  }
  const Eigen::MatrixXd P = map.map().covariance();
  if (!P.allFinite()) lmf::fuzz::fail("an accepted scan left a non-finite covariance");
  if (P.size() > 0 && P.diagonal().minCoeff() < -1e-9 * std::max(1.0, P.diagonal().maxCoeff())) {
    lmf::fuzz::fail("an accepted scan left a negative variance");
  }
  const auto snapshot = lmf::runtime::to_message(map.snapshot());
  if (!snapshot) lmf::fuzz::fail("an accepted scan left a snapshot lmf-agent cannot ship: " + snapshot.rejection().describe());
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  const auto scan = lmf::runtime::decode<lmf::runtime::RobotScan>(data, size);
  if (!scan) {
    lmf::fuzz::note_outcome(lmf::runtime::reason_name(scan.rejection().reason));
    return 0;
  }
  // lmf-agent refuses a scan older than the last one it processed (AgentNode::on_scan).
  if (scan.value().scan.utime < lmf::fuzz::corpus().prepared_last_utime) {
    lmf::fuzz::note_outcome("agent_out_of_range");
    return 0;
  }
  static lmf::LocalMap map;
  static const std::string prepared = state_bytes(lmf::fuzz::corpus().prepared_local_map);
  map = lmf::fuzz::corpus().prepared_local_map;
  try {
    const lmf::ScanReport report = map.process_scan(scan.value().scan);
    if (report.should_ship) map.reset();
  } catch (const std::invalid_argument& e) {
    if (state_bytes(map) != prepared) lmf::fuzz::fail(std::string("process_scan threw (") + e.what() + ") and changed the map");
    lmf::fuzz::note_outcome("local_map_refused");
    return 0;
  }
  check_state(map);
  lmf::fuzz::note_outcome("accepted");
  return 0;
}

std::vector<lmf::fuzz::Bytes> LmfFuzzSeeds() {
  std::vector<lmf::fuzz::Bytes> seeds;
  for (const auto& scan : lmf::fuzz::corpus().next_scans) seeds.push_back(lmf::fuzz::encode(lmf::runtime::to_message(scan)));
  return seeds;
}
