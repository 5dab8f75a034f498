// What the fuzz targets found (each case made a target crash or fail a
// property before its fix), kept as plain tests, and checks of the fuzz machinery itself: the map fingerprint sees
// every change, the mutator is deterministic, every target's seeds are valid.
#include <cmath>
#include <cstdint>
#include <filesystem>
#include <fstream>
#include <limits>
#include <string>
#include <vector>

#include <gtest/gtest.h>

#include "fuzz_support.hpp"
#include "lmf/io/carmen.hpp"
#include "lmf/io/text_file.hpp"
#include "monitor/monitor_state.hpp"
#include "mutator.hpp"
#include "runtime/convert.hpp"

namespace {

namespace rt = lmf::runtime;
using lmf::fuzz::Bytes;

Bytes with_int32_at(Bytes bytes, std::size_t at, std::int32_t value) {
  const auto v = static_cast<std::uint32_t>(value);
  for (std::size_t i = 0; i < 4; ++i) bytes.at(at + i) = static_cast<std::uint8_t>(v >> (24 - 8 * i));
  return bytes;
}

// ---- runtime/convert ------------------------------------------------------------------

TEST(FuzzRegression, StatusReasonStringsAreCheckedBeforeLcmGensDecoder) {
  lmf::agent_status_t status = lmf::fuzz::corpus().agent_statuses.front();
  ASSERT_EQ(status.reject_reasons.front(), "decode_failed");
  const Bytes good = rt::encode_message(status);
  ASSERT_TRUE(rt::decode_message<lmf::agent_status_t>(good.data(), good.size()).ok());
  // The first string's length field sits right after num_reject_reasons.
  const std::size_t at = static_cast<std::size_t>(lmf::agent_status_t{}.getEncodedSize());
  ASSERT_EQ(good.at(at + 3), 14) << "agent_status_t layout changed";  // "decode_failed" + NUL
  for (const std::int32_t length : {0, -1, std::numeric_limits<std::int32_t>::min(), 66, 1 << 30}) {
    const Bytes bad = with_int32_at(good, at, length);
    const auto decoded = rt::decode_message<lmf::agent_status_t>(bad.data(), bad.size());
    ASSERT_FALSE(decoded.ok()) << "length " << length;
    EXPECT_EQ(decoded.rejection().reason, rt::RejectReason::kDecodeFailed) << "length " << length;
  }
  Bytes embedded_nul = good;
  embedded_nul.at(at + 4 + 3) = 0;  // "dec\0de_failed": the encoder would drop the tail
  EXPECT_FALSE(rt::decode_message<lmf::agent_status_t>(embedded_nul.data(), embedded_nul.size()).ok());
  Bytes not_ascii = good;
  not_ascii.at(at + 4 + 3) = 0xc3;  // not printable ASCII: a monitor writes it into JSON
  EXPECT_FALSE(rt::decode_message<lmf::agent_status_t>(not_ascii.data(), not_ascii.size()).ok());
}

TEST(FuzzRegression, AbsurdCoordinatesAreOutOfRange) {
  rt::RobotScan scan = lmf::fuzz::corpus().scans.front();
  scan.scan.odometry.x = -2.8e304;  // finite: overflowed the agent's covariance
  const Bytes bytes = rt::encode_message(rt::to_message(scan));
  const auto decoded = rt::decode<rt::RobotScan>(bytes.data(), bytes.size());
  ASSERT_FALSE(decoded.ok());
  EXPECT_EQ(decoded.rejection().reason, rt::RejectReason::kOutOfRange);
}

// P(5,10) = -2.3e307 in an otherwise small covariance: inside LLT the
// overflow became NaN, which passes the pivot test, and the GlobalMap
// accepted the map and fused NaN into itself.
TEST(FuzzRegression, HugeOffDiagonalCovarianceIsRefusedAndTheMapIsUnchanged) {
  const lmf::fuzz::Corpus& c = lmf::fuzz::corpus();
  lmf::LocalMapSnapshot map = c.pending_maps.front();
  ASSERT_GT(map.covariance.rows(), 10);
  map.covariance(5, 10) = map.covariance(10, 5) = -2.3e307;
  EXPECT_TRUE(rt::check_covariance(map.covariance, "P").has_value());
  lmf::fusion::GlobalMap global = c.prepared_map;
  const lmf::fuzz::MapFingerprint before = lmf::fuzz::fingerprint(global);
  EXPECT_THROW(global.fuse(map), lmf::fusion::InvalidInput);
  EXPECT_TRUE(lmf::fuzz::fingerprint(global) == before);
}

// Var(y_R) = 9.2e268: finite and PSD, accepted by both validators, and the
// fusion overflowed into a NaN corrected frame.
TEST(FuzzRegression, AbsurdVarianceIsRefusedAndTheMapIsUnchanged) {
  const lmf::fuzz::Corpus& c = lmf::fuzz::corpus();
  lmf::LocalMapSnapshot map = c.pending_maps.front();
  map.covariance(1, 1) = 9.2e268;
  const auto r = rt::check_covariance(map.covariance, "P");
  ASSERT_TRUE(r.has_value());
  EXPECT_EQ(r->reason, rt::RejectReason::kOutOfRange);
  lmf::fusion::GlobalMap global = c.prepared_map;
  const lmf::fuzz::MapFingerprint before = lmf::fuzz::fingerprint(global);
  EXPECT_THROW(global.fuse(map), lmf::fusion::InvalidInput);
  EXPECT_TRUE(lmf::fuzz::fingerprint(global) == before);
}

// ---- lmf/io ------------------------------------------------------------------------------

TEST(FuzzRegression, NulBytesDoNotGlueLinesTogether) {
  const auto file = std::filesystem::path(::testing::TempDir()) / "lmf_fuzz_nul.log";
  {
    std::ofstream out(file, std::ios::binary);
    out << "PARAM a_" << '\0' << "b 1\n# next\nODOM x 0 0 0 0 0 1.0 host 1.0\n";
  }
  std::vector<std::string> lines;
  lmf::io::for_each_line(file, [&](const std::string& text, std::size_t) { lines.push_back(text); });
  ASSERT_EQ(lines.size(), 3u);
  EXPECT_EQ(lines[0], std::string("PARAM a_\0b 1", 12));
  EXPECT_EQ(lines[1], "# next");
  try {
    lmf::io::read_carmen_log(file);
    ADD_FAILURE() << "the ODOM line is malformed";
  } catch (const lmf::io::CarmenParseError& e) {
    EXPECT_EQ(e.line(), 3u) << e.what();
  }
}

TEST(FuzzRegression, HugeFlaserValuesAreWrittenWhole) {
  lmf::LaserScan scan = lmf::fuzz::corpus().scans.front().scan;
  scan.ranges_m[7] = 1e300;
  scan.odometry = lmf::Pose2(-1e300, 1e300, 1.0);
  const std::string line = lmf::io::carmen_flaser_line(scan, "host");
  lmf::io::CarmenLog log;
  lmf::io::parse_carmen_line(line, "written", 1, {}, log);
  ASSERT_EQ(log.scans.size(), 1u);
  EXPECT_NEAR(log.scans[0].ranges_m[7] / 1e300, 1.0, 1e-12);
  EXPECT_NEAR(log.scans[0].odometry.x / -1e300, 1.0, 1e-12);
  EXPECT_NEAR(log.scans[0].odometry.y / 1e300, 1.0, 1e-12);
}

// ---- monitor ---------------------------------------------------------------------------

TEST(FuzzRegression, MonitorSurvivesHostileStatusValues) {
  lmf::monitor::MonitorState state;
  // Values runtime::from_message accepts at their extremes, and some it would
  // refuse (MonitorState does not rely on its caller having checked).
  rt::AgentStatus a = rt::from_message(lmf::fuzz::corpus().agent_statuses.front()).value();
  a.utime = std::numeric_limits<std::int64_t>::max();
  for (auto& [reason, count] : a.rejects) count = std::numeric_limits<std::int64_t>::max();
  ASSERT_GE(a.rejects.size(), 2u);
  state.on_agent_status(a, 1);
  a.utime = std::numeric_limits<std::int64_t>::min();  // utime differences overflowed int64
  a.x_WR.x = std::numeric_limits<double>::quiet_NaN();  // made map.svg throw
  a.scan_time_p99_ms = std::numeric_limits<double>::quiet_NaN();  // null in the JSON line
  state.on_agent_status(a, 2);
  EXPECT_EQ(state.robots().at(a.robot_id).rejects, std::numeric_limits<std::int64_t>::max());
  EXPECT_EQ(state.timing_series().at(a.robot_id).size(), 2u);
  const auto file = std::filesystem::path(::testing::TempDir()) / "lmf_fuzz_monitor.svg";
  EXPECT_NO_THROW(state.write_map_svg(file));
  EXPECT_NO_THROW(state.write_timing_svg(file));
  EXPECT_NO_THROW(state.to_json(3).dump());
}

// ---- the fuzz machinery ----------------------------------------------------------------

TEST(FuzzMachinery, FingerprintSeesEveryKindOfChange) {
  const lmf::fuzz::Corpus& c = lmf::fuzz::corpus();
  const lmf::fuzz::MapFingerprint prepared = lmf::fuzz::fingerprint(c.prepared_map);
  lmf::fusion::GlobalMap copy = c.prepared_map;
  EXPECT_TRUE(lmf::fuzz::fingerprint(copy) == prepared) << "a copy is the same map";
  // A fusion, a queued map of a robot that has not joined, a join by sighting.
  lmf::fusion::GlobalMap fused = c.prepared_map;
  fused.fuse(c.pending_maps.front());
  EXPECT_FALSE(lmf::fuzz::fingerprint(fused) == prepared);
  lmf::fusion::GlobalMap queued = c.prepared_map;
  lmf::LocalMapSnapshot stranger = c.pending_maps.front();
  stranger.robot_id = 6;
  queued.fuse(stranger);
  EXPECT_FALSE(lmf::fuzz::fingerprint(queued) == prepared);
  lmf::fusion::GlobalMap joined = c.prepared_map;
  joined.add_sighting(c.pending_sightings.front());
  EXPECT_FALSE(lmf::fuzz::fingerprint(joined) == prepared);
}

TEST(FuzzMachinery, MutatorIsDeterministicPerInputAndMutates) {
  const std::vector<Bytes> seeds = {Bytes(64, 0x11), Bytes(100, 0x22)};
  lmf::fuzz::Mutator a(seeds, 4096);
  lmf::fuzz::Mutator b(seeds, 4096);
  // b builds the same inputs in the opposite order: input i depends on i only.
  std::vector<Bytes> backwards(200);
  for (std::uint64_t i = 200; i-- > 0;) backwards[i] = b.input(5, i);
  int changed = 0;
  for (std::uint64_t i = 0; i < 200; ++i) {
    const Bytes x = a.input(5, i);
    EXPECT_EQ(x, backwards[i]) << "input " << i;
    EXPECT_LE(x.size(), 4096u);
    changed += (x != seeds[0] && x != seeds[1]) ? 1 : 0;
  }
  EXPECT_GT(changed, 190);
  EXPECT_NE(a.input(5, 3), a.input(6, 3)) << "the run seed matters";
}

TEST(FuzzMachinery, CovarianceViolationFindsWhatTheValidatorsMustRefuse) {
  Eigen::Matrix3d P = Eigen::Vector3d(1e-3, 1e-3, 1e-4).asDiagonal();
  EXPECT_EQ(lmf::fuzz::covariance_violation(P), "");
  P(0, 1) = P(1, 0) = 2e-3;
  EXPECT_NE(lmf::fuzz::covariance_violation(P), "");
  P(0, 1) = 0.0;
  P(1, 0) = 1e-12;
  EXPECT_NE(lmf::fuzz::covariance_violation(P), "") << "asymmetric";
}

}  // namespace
