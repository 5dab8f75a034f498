// Round trips of every LCM <-> core conversion, and every rejection reason
// triggered by a crafted message.
#include <cmath>
#include <cstring>
#include <limits>
#include <numbers>
#include <vector>

#include <Eigen/Eigenvalues>
#include <gtest/gtest.h>

#include "runtime/convert.hpp"
#include "test_support.hpp"

namespace {

using lmf::Pose2;
using lmf::runtime::Checked;
using lmf::fusion::CorrectedFrame;
using lmf::runtime::CorrectedFrames;
using lmf::runtime::DecodeLimits;
using lmf::runtime::LocalMapAck;
using lmf::runtime::SightingAck;
using lmf::runtime::MissionEnd;
using lmf::runtime::RejectReason;
using lmf::runtime::RobotScan;
using lmf::runtime::ScanAck;
using lmf::fusion::RobotSighting;
namespace rt = lmf::runtime;

constexpr double kNan = std::numeric_limits<double>::quiet_NaN();

template <class T>
RejectReason reason_of(const Checked<T>& checked) {
  EXPECT_FALSE(checked.ok()) << "expected a rejection";
  return checked.ok() ? RejectReason::kHandlerError : checked.rejection().reason;
}

// A random symmetric PSD matrix of rank <= rank.
Eigen::MatrixXd random_covariance(int n, int rank, unsigned seed) {
  std::srand(seed);
  const Eigen::MatrixXd A = Eigen::MatrixXd::Random(n, rank) * 0.1;
  return A * A.transpose();
}

RobotScan make_scan() {
  RobotScan scan;
  scan.robot_id = 3;
  scan.seq = 41;
  scan.scan.utime = 1'700'000'123'456;
  scan.scan.odometry = Pose2(1.25, -2.5, 3.0);
  scan.scan.angle_min_rad = -std::numbers::pi / 2;
  scan.scan.angle_increment_rad = lmf::beam_increment_for_180deg(181);
  scan.scan.max_range_m = 8.0;
  for (int i = 0; i < 181; ++i) scan.scan.ranges_m.push_back(0.5 + 0.01 * i);
  return scan;
}

lmf::LocalMapSnapshot make_map(int segments) {
  lmf::LocalMapSnapshot map;
  map.robot_id = 2;
  map.seq = 9;
  map.first_utime = 1000;
  map.last_utime = 21000;
  map.x_LR = Pose2(3.0, 0.5, -0.3);
  for (int i = 0; i < segments; ++i) {
    map.segments.push_back({Pose2(0.5 * i, 1.0, 0.1 * i - 1.0), 1.5 + 0.25 * i});
  }
  const int n = 3 + 2 * segments;
  map.covariance = random_covariance(n, std::max(1, n - 2), 7);  // singular on purpose: PSD, not PD
  for (int i = 0; i < 4; ++i) {  // the first at first_utime, as LocalMap records them
    map.scan_poses.push_back({1000 + 5000 * i, Pose2(0.5 * i, 0.01 * i, -0.1 * i)});
  }
  return map;
}

CorrectedFrames make_frames() {
  CorrectedFrames frames;
  frames.utime = 5'000'000;
  frames.fusion_count = 12;
  CorrectedFrame first;
  first.robot_id = 0;
  first.map_seq = 5;  // sent as last_applied_seq 4
  first.x_WL = Pose2(10.0, -1.0, std::numbers::pi);  // pi itself is inside (-pi, pi]
  first.covariance = Eigen::Matrix3d::Zero();        // the first robot defines W
  CorrectedFrame second;
  second.robot_id = 5;
  second.map_seq = 0;  // nothing fused yet: last_applied_seq -1
  second.x_WL = Pose2(-3.0, 2.0, 0.7);
  second.covariance = random_covariance(3, 3, 3);
  frames.frames = {first, second};
  return frames;
}

RobotSighting make_sighting() {
  RobotSighting s;
  s.utime = 77;
  s.observer_id = 0;
  s.observed_id = 1;
  s.x_AB = Pose2(2.0, 0.3, -2.0);
  s.cov_AB = Eigen::Vector3d(0.01, 0.01, 0.002).asDiagonal();
  s.observer_seq = 4;
  s.x_LA = Pose2(5.0, 1.0, 0.5);
  s.cov_LA = random_covariance(3, 2, 9);
  s.observed_seq = 0;
  s.x_LB = Pose2();  // B at the origin of its local map, exactly known
  return s;
}

// Message -> bytes -> message -> core, through the public decode path.
template <class Core, class Msg>
Checked<Core> through_bytes(const Msg& msg, const DecodeLimits& limits = {}) {
  const std::vector<std::uint8_t> bytes = rt::encode_message(msg);
  return rt::decode<Core>(bytes.data(), bytes.size(), limits);
}

// Overwrites the big-endian int32 at `offset`.
void poke_i32(std::vector<std::uint8_t>& bytes, std::size_t offset, std::int32_t value) {
  const auto v = static_cast<std::uint32_t>(value);
  for (int i = 0; i < 4; ++i) bytes[offset + static_cast<std::size_t>(i)] = static_cast<std::uint8_t>(v >> (24 - 8 * i));
}

// ---- round trips -----------------------------------------------------------------

TEST(Convert, Pose2RoundTripsAndWrapsPi) {
  const Pose2 p(1.0, -2.0, -std::numbers::pi);  // -pi on the wire becomes pi
  const auto back = rt::from_message(rt::to_message(p));
  ASSERT_TRUE(back.ok());
  EXPECT_DOUBLE_EQ(back.value().x, 1.0);
  EXPECT_DOUBLE_EQ(back.value().y, -2.0);
  EXPECT_DOUBLE_EQ(back.value().phi, std::numbers::pi);
}

TEST(Convert, LaserScanRoundTripsWithinFloatPrecision) {
  const RobotScan scan = make_scan();
  const auto back = through_bytes<RobotScan>(rt::to_message(scan));
  ASSERT_TRUE(back.ok()) << back.rejection().describe();
  EXPECT_EQ(back.value().robot_id, 3);
  EXPECT_EQ(back.value().seq, 41);
  EXPECT_EQ(back.value().scan.utime, scan.scan.utime);
  EXPECT_TRUE(lmf::is_near(back.value().scan.odometry, scan.scan.odometry, 0.0, 0.0));
  EXPECT_NEAR(back.value().scan.angle_min_rad, scan.scan.angle_min_rad, 1e-7);
  EXPECT_NEAR(back.value().scan.angle_increment_rad, scan.scan.angle_increment_rad, 1e-8);
  EXPECT_DOUBLE_EQ(back.value().scan.max_range_m, 8.0);
  ASSERT_EQ(back.value().scan.ranges_m.size(), scan.scan.ranges_m.size());
  for (std::size_t i = 0; i < scan.scan.ranges_m.size(); ++i) {
    EXPECT_NEAR(back.value().scan.ranges_m[i], scan.scan.ranges_m[i], 1e-6);
  }
}

TEST(Convert, LocalMapRoundTripsAndPacksRowByRow) {
  const lmf::LocalMapSnapshot map = make_map(3);
  const auto msg = rt::to_message(map);
  ASSERT_TRUE(msg.ok()) << msg.rejection().describe();
  EXPECT_EQ(msg.value().num_scans, 4);
  EXPECT_EQ(msg.value().num_covariance, 9 * 10 / 2);
  // Row by row upper triangle: element 1 is P(0,1), element 9 is P(1,1).
  EXPECT_DOUBLE_EQ(msg.value().covariance[1], map.covariance(0, 1));
  EXPECT_DOUBLE_EQ(msg.value().covariance[9], map.covariance(1, 1));
  EXPECT_DOUBLE_EQ(msg.value().covariance[44], map.covariance(8, 8));

  const auto back = through_bytes<lmf::LocalMapSnapshot>(msg.value());
  ASSERT_TRUE(back.ok()) << back.rejection().describe();
  const lmf::LocalMapSnapshot& m = back.value();
  EXPECT_EQ(m.robot_id, 2);
  EXPECT_EQ(m.seq, 9);
  EXPECT_EQ(m.first_utime, 1000);
  EXPECT_EQ(m.last_utime, 21000);
  EXPECT_TRUE(lmf::is_near(m.x_LR, map.x_LR, 0.0, 0.0));
  ASSERT_EQ(m.segments.size(), 3u);
  for (std::size_t i = 0; i < 3; ++i) {
    EXPECT_TRUE(lmf::is_near(m.segments[i].location, map.segments[i].location, 0.0, 0.0));
    EXPECT_NEAR(m.segments[i].length_m, map.segments[i].length_m, 1e-6);
  }
  EXPECT_TRUE(lmf::testing::matrices_near(m.covariance, map.covariance, 0.0));
  ASSERT_EQ(m.scan_poses.size(), 4u);
  for (std::size_t i = 0; i < 4; ++i) {
    EXPECT_EQ(m.scan_poses[i].utime, map.scan_poses[i].utime);
    EXPECT_TRUE(lmf::is_near(m.scan_poses[i].x_LR, map.scan_poses[i].x_LR, 0.0, 0.0));
  }
}

TEST(Convert, LocalMapScanPosesAreChecked) {
  // num_scans repeats the count of scan poses and must agree with it.
  auto msg = rt::to_message(make_map(1)).value();
  msg.num_scans = 3;
  EXPECT_EQ(reason_of(through_bytes<lmf::LocalMapSnapshot>(msg)), RejectReason::kWrongSize);
  // Times and poses must have the same count (the arrays share num_scan_poses,
  // so only an in-process message can disagree).
  msg = rt::to_message(make_map(1)).value();
  msg.scan_utimes.pop_back();
  EXPECT_EQ(reason_of(rt::from_message(msg)), RejectReason::kWrongSize);
  // Times go forward within [first_scan_utime, utime].
  msg = rt::to_message(make_map(1)).value();
  std::swap(msg.scan_utimes[1], msg.scan_utimes[2]);
  EXPECT_EQ(reason_of(through_bytes<lmf::LocalMapSnapshot>(msg)), RejectReason::kOutOfRange);
  msg = rt::to_message(make_map(1)).value();
  msg.scan_utimes[3] = msg.utime + 1;
  EXPECT_EQ(reason_of(through_bytes<lmf::LocalMapSnapshot>(msg)), RejectReason::kOutOfRange);
  msg = rt::to_message(make_map(1)).value();
  msg.scan_utimes[0] = msg.first_scan_utime - 1;
  EXPECT_EQ(reason_of(through_bytes<lmf::LocalMapSnapshot>(msg)), RejectReason::kOutOfRange);
  msg = rt::to_message(make_map(1)).value();
  msg.scan_poses[2].phi = kNan;
  EXPECT_EQ(reason_of(through_bytes<lmf::LocalMapSnapshot>(msg)), RejectReason::kNonFinite);
  // The sender refuses what the receiver would.
  lmf::LocalMapSnapshot core = make_map(1);
  core.scan_poses[1].utime = 0;
  EXPECT_EQ(reason_of(rt::to_message(core)), RejectReason::kOutOfRange);
}

TEST(Convert, EmptyLocalMapRoundTrips) {
  lmf::LocalMapSnapshot map = make_map(0);
  map.covariance = Eigen::MatrixXd::Zero(3, 3);  // a fresh local map: covariance 0
  const auto msg = rt::to_message(map);
  ASSERT_TRUE(msg.ok()) << msg.rejection().describe();
  const auto back = through_bytes<lmf::LocalMapSnapshot>(msg.value());
  ASSERT_TRUE(back.ok()) << back.rejection().describe();
  EXPECT_EQ(back.value().covariance.rows(), 3);
}

TEST(Convert, CorrectedFramesRoundTrip) {
  const CorrectedFrames frames = make_frames();
  const auto msg = rt::to_message(frames);
  ASSERT_TRUE(msg.ok()) << msg.rejection().describe();
  // The wire names the last local map fused, the core the map that begins at x_WL.
  EXPECT_EQ(msg.value().last_applied_seq, (std::vector<std::int64_t>{4, -1}));
  // Neither direction overflows (found by the fuzzer under UBSan).
  auto last = msg.value();
  last.last_applied_seq[0] = std::numeric_limits<std::int64_t>::max();
  EXPECT_EQ(reason_of(rt::from_message(last)), RejectReason::kOutOfRange);
  auto negative = frames;
  negative.frames[0].map_seq = std::numeric_limits<std::int64_t>::min();
  EXPECT_EQ(reason_of(rt::to_message(negative)), RejectReason::kOutOfRange);
  const auto back = through_bytes<CorrectedFrames>(msg.value());
  ASSERT_TRUE(back.ok()) << back.rejection().describe();
  EXPECT_EQ(back.value().utime, frames.utime);
  EXPECT_EQ(back.value().fusion_count, 12);
  ASSERT_EQ(back.value().frames.size(), 2u);
  for (std::size_t i = 0; i < 2; ++i) {
    const CorrectedFrame& a = frames.frames[i];
    const CorrectedFrame& b = back.value().frames[i];
    EXPECT_EQ(b.robot_id, a.robot_id);
    EXPECT_EQ(b.map_seq, a.map_seq);
    EXPECT_TRUE(lmf::is_near(b.x_WL, a.x_WL, 0.0, 0.0));
    EXPECT_TRUE(lmf::testing::matrices_near(b.covariance, a.covariance, 0.0));
  }
}

TEST(Convert, SightingRoundTrips) {
  const RobotSighting s = make_sighting();
  const auto msg = rt::to_message(s);
  ASSERT_TRUE(msg.ok()) << msg.rejection().describe();
  const auto back = through_bytes<RobotSighting>(msg.value());
  ASSERT_TRUE(back.ok()) << back.rejection().describe();
  EXPECT_EQ(back.value().utime, 77);
  EXPECT_EQ(back.value().observer_id, 0);
  EXPECT_EQ(back.value().observed_id, 1);
  EXPECT_TRUE(lmf::is_near(back.value().x_AB, s.x_AB, 0.0, 0.0));
  EXPECT_TRUE(lmf::testing::matrices_near(back.value().cov_AB, s.cov_AB, 0.0));
  EXPECT_EQ(back.value().observer_seq, 4);
  EXPECT_TRUE(lmf::is_near(back.value().x_LA, s.x_LA, 0.0, 0.0));
  EXPECT_TRUE(lmf::testing::matrices_near(back.value().cov_LA, s.cov_LA, 0.0));
  EXPECT_EQ(back.value().observed_seq, 0);
  EXPECT_TRUE(lmf::is_near(back.value().x_LB, s.x_LB, 0.0, 0.0));
  EXPECT_TRUE(lmf::testing::matrices_near(back.value().cov_LB, Eigen::Matrix3d::Zero(), 0.0));
}

TEST(Convert, AcksRoundTrip) {
  ScanAck ack;
  ack.utime = 10;
  ack.robot_id = 1;
  ack.seq = 99;
  ack.local_map_seq = 3;
  ack.x_LR = Pose2(2.0, -1.0, 0.4);
  ack.covariance = random_covariance(3, 3, 4);
  const auto ack_msg = rt::to_message(ack);
  ASSERT_TRUE(ack_msg.ok()) << ack_msg.rejection().describe();
  const auto scan_ack = through_bytes<ScanAck>(ack_msg.value());
  ASSERT_TRUE(scan_ack.ok()) << scan_ack.rejection().describe();
  EXPECT_EQ(scan_ack.value().utime, 10);
  EXPECT_EQ(scan_ack.value().robot_id, 1);
  EXPECT_EQ(scan_ack.value().seq, 99);
  EXPECT_EQ(scan_ack.value().local_map_seq, 3);
  EXPECT_TRUE(lmf::is_near(scan_ack.value().x_LR, ack.x_LR, 0.0, 0.0));
  EXPECT_TRUE(lmf::testing::matrices_near(scan_ack.value().covariance, ack.covariance, 0.0));
  // Right after a ship the robot sits at the new map's origin, exactly known.
  EXPECT_TRUE(rt::to_message(ScanAck{}).ok());
  const auto map_ack = through_bytes<LocalMapAck>(rt::to_message(LocalMapAck{20, 2, 5, LocalMapAck::Status::kQueued}));
  ASSERT_TRUE(map_ack.ok());
  EXPECT_EQ(map_ack.value().seq, 5);
  EXPECT_EQ(map_ack.value().status, LocalMapAck::Status::kQueued);
  EXPECT_EQ(through_bytes<LocalMapAck>(rt::to_message(LocalMapAck{20, 2, 5, LocalMapAck::Status::kReceived}))
                .value()
                .status,
            LocalMapAck::Status::kReceived);
  EXPECT_EQ(through_bytes<SightingAck>(rt::to_message(SightingAck{1, 0, 1, SightingAck::Status::kReceived}))
                .value()
                .status,
            SightingAck::Status::kReceived);
  const auto sighting_ack =
      through_bytes<SightingAck>(rt::to_message(SightingAck{600'000, 1, 2, SightingAck::Status::kRejected}));
  ASSERT_TRUE(sighting_ack.ok());
  EXPECT_EQ(sighting_ack.value().utime, 600'000);
  EXPECT_EQ(sighting_ack.value().observer_id, 1);
  EXPECT_EQ(sighting_ack.value().observed_id, 2);
  EXPECT_EQ(sighting_ack.value().status, SightingAck::Status::kRejected);
}

TEST(Convert, MissionEndRoundTrips) {
  const auto msg = rt::to_message(MissionEnd{123, {0, 4, 2}});
  ASSERT_TRUE(msg.ok()) << msg.rejection().describe();
  const auto back = through_bytes<MissionEnd>(msg.value());
  ASSERT_TRUE(back.ok()) << back.rejection().describe();
  EXPECT_EQ(back.value().utime, 123);
  EXPECT_EQ(back.value().robot_ids, (std::vector<int>{0, 4, 2}));
  EXPECT_EQ(reason_of(rt::to_message(MissionEnd{1, {3, 3}})), RejectReason::kOutOfRange);
  EXPECT_EQ(reason_of(rt::to_message(MissionEnd{1, {-1}})), RejectReason::kOutOfRange);
  EXPECT_EQ(reason_of(rt::to_message(MissionEnd{-5, {1}})), RejectReason::kOutOfRange);
  EXPECT_TRUE(rt::to_message(MissionEnd{0, {}}).ok());
}

TEST(Convert, AgentStatusRoundTripsAndRefusesBadValues) {
  rt::AgentStatus status;
  status.utime = 1'700'000'000'000'000;
  status.robot_id = 3;
  status.joined = true;
  status.scans = 412;
  status.local_map_segments = 17;
  status.maps_shipped = 9;
  status.maps_acknowledged = 8;
  status.scan_time_p50_ms = 0.5;
  status.scan_time_p99_ms = 1.25;
  status.scan_time_max_ms = 4.0;
  status.window_scans = 25;
  status.x_WR = Pose2(3.0, -1.5, 0.7);
  status.odometry.model.translation_scale = 1.02;
  status.odometry.model.phi_per_m = 0.01;
  status.odometry.increments_learned = 400;
  status.odometry.increments_downweighted = 3;
  status.mission_done = true;
  status.rejects = {{"stale_sequence", 7}, {"non_finite", 1}};
  const auto msg = rt::to_message(status);
  ASSERT_TRUE(msg.ok()) << msg.rejection().describe();
  const auto back = through_bytes<rt::AgentStatus>(msg.value());
  ASSERT_TRUE(back.ok()) << back.rejection().describe();
  const rt::AgentStatus& b = back.value();
  EXPECT_EQ(b.utime, status.utime);
  EXPECT_EQ(b.robot_id, 3);
  EXPECT_TRUE(b.joined);
  EXPECT_EQ(b.scans, 412);
  EXPECT_EQ(b.maps_acknowledged, 8);
  EXPECT_DOUBLE_EQ(b.scan_time_p99_ms, 1.25);
  EXPECT_EQ(b.window_scans, 25);
  EXPECT_DOUBLE_EQ(b.x_WR.phi, 0.7);
  EXPECT_FLOAT_EQ(static_cast<float>(b.odometry.model.translation_scale), 1.02f);
  EXPECT_EQ(b.odometry.increments_downweighted, 3);
  EXPECT_TRUE(b.mission_done);
  EXPECT_EQ(b.rejects, status.rejects);

  auto bad = status;
  bad.scan_time_max_ms = std::nan("");
  EXPECT_EQ(reason_of(rt::to_message(bad)), RejectReason::kNonFinite);
  bad = status;
  bad.scan_time_p50_ms = -1.0;
  EXPECT_EQ(reason_of(rt::to_message(bad)), RejectReason::kOutOfRange);
  bad = status;
  bad.maps_shipped = -1;
  EXPECT_EQ(reason_of(rt::to_message(bad)), RejectReason::kOutOfRange);
  bad = status;
  bad.x_WR = Pose2(2e6, 0.0, 0.0);
  EXPECT_EQ(reason_of(rt::to_message(bad)), RejectReason::kOutOfRange);
  bad = status;
  bad.odometry.model.rotation_scale = std::numeric_limits<double>::infinity();
  EXPECT_EQ(reason_of(rt::to_message(bad)), RejectReason::kNonFinite);
  bad = status;
  bad.rejects = {{"decode_failed", -2}};
  EXPECT_EQ(reason_of(rt::to_message(bad)), RejectReason::kOutOfRange);
  // A float time that overflows float is refused, not sent as infinity.
  bad = status;
  bad.scan_time_max_ms = 1e300;
  EXPECT_EQ(reason_of(rt::to_message(bad)), RejectReason::kNonFinite);
}

TEST(Convert, ServerStatusRoundTripsAndRefusesBadValues) {
  rt::ServerStatus status;
  status.utime = 5;
  status.robots_joined = 2;
  status.segments = 140;
  status.submaps = 12;
  status.graph_edges = 15;
  status.fusions = 13;
  status.last_fusion_ms = 21.5;
  status.mean_fusion_ms = 14.0;
  status.queue_length = 1;
  status.covariance_ok = false;
  status.min_eigenvalue = -1e-6;  // what a failed health check reports
  status.rejects = {{"covariance_not_psd", 2}};
  const auto msg = rt::to_message(status);
  ASSERT_TRUE(msg.ok()) << msg.rejection().describe();
  const auto back = through_bytes<rt::ServerStatus>(msg.value());
  ASSERT_TRUE(back.ok()) << back.rejection().describe();
  EXPECT_EQ(back.value().segments, 140);
  EXPECT_EQ(back.value().fusions, 13);
  EXPECT_DOUBLE_EQ(back.value().last_fusion_ms, 21.5);
  EXPECT_FALSE(back.value().covariance_ok);
  EXPECT_FLOAT_EQ(static_cast<float>(back.value().min_eigenvalue), -1e-6f);
  EXPECT_EQ(back.value().rejects, status.rejects);

  auto bad = status;
  bad.queue_length = -1;
  EXPECT_EQ(reason_of(rt::to_message(bad)), RejectReason::kOutOfRange);
  bad = status;
  bad.mean_fusion_ms = std::numeric_limits<double>::infinity();
  EXPECT_EQ(reason_of(rt::to_message(bad)), RejectReason::kNonFinite);
  bad = status;
  bad.min_eigenvalue = std::nan("");
  EXPECT_EQ(reason_of(rt::to_message(bad)), RejectReason::kNonFinite);
}

TEST(Convert, GlobalMapSummaryRoundTripsAndRefusesBadEndPoints) {
  rt::GlobalMapSummary map;
  map.utime = 7;
  map.fusion_count = 4;
  map.submaps = 3;
  map.graph_edges = 2;
  map.endpoints = {{0.0, 0.0, 5.0, 0.0}, {5.0, 0.0, 5.0, 4.25}};
  const auto msg = rt::to_message(map);
  ASSERT_TRUE(msg.ok()) << msg.rejection().describe();
  const auto back = through_bytes<rt::GlobalMapSummary>(msg.value());
  ASSERT_TRUE(back.ok()) << back.rejection().describe();
  EXPECT_EQ(back.value().fusion_count, 4);
  EXPECT_EQ(back.value().endpoints, map.endpoints);  // exact in float

  auto bad = map;
  bad.endpoints[1][2] = std::nan("");
  EXPECT_EQ(reason_of(rt::to_message(bad)), RejectReason::kNonFinite);
  bad = map;
  bad.endpoints[0][0] = -3e6;
  EXPECT_EQ(reason_of(rt::to_message(bad)), RejectReason::kOutOfRange);
  bad = map;
  bad.submaps = -1;
  EXPECT_EQ(reason_of(rt::to_message(bad)), RejectReason::kOutOfRange);
  lmf::global_map_t short_row = msg.value();
  short_row.endpoints[0].pop_back();  // a hand-built message the encoder would overrun
  EXPECT_EQ(reason_of(rt::from_message(short_row)), RejectReason::kWrongSize);
}

TEST(Convert, StatusAndGlobalMapMessagesDecode) {
  lmf::server_status_t status{};
  status.num_reject_reasons = 2;
  status.reject_reasons = {"non_finite", "stale_sequence"};
  status.reject_counts = {3, 4};
  const auto bytes = rt::encode_message(status);
  const auto decoded = rt::decode_message<lmf::server_status_t>(bytes.data(), bytes.size());
  ASSERT_TRUE(decoded.ok()) << decoded.rejection().describe();
  EXPECT_EQ(decoded.value().reject_reasons[1], "stale_sequence");

  lmf::global_map_t map{};
  map.num_segments = 2;
  map.endpoints = {{0, 0, 1, 0}, {1, 0, 1, 1}};
  const auto map_bytes = rt::encode_message(map);
  const auto map_decoded = rt::decode_message<lmf::global_map_t>(map_bytes.data(), map_bytes.size());
  ASSERT_TRUE(map_decoded.ok()) << map_decoded.rejection().describe();
  EXPECT_FLOAT_EQ(map_decoded.value().endpoints[1][3], 1.0f);

  lmf::agent_status_t agent{};
  agent.robot_id = 4;
  agent.mission_done = true;
  agent.num_reject_reasons = 1;
  agent.reject_reasons = {"stale_sequence"};
  agent.reject_counts = {7};
  auto agent_bytes = rt::encode_message(agent);
  const auto agent_decoded = rt::decode_message<lmf::agent_status_t>(agent_bytes.data(), agent_bytes.size());
  ASSERT_TRUE(agent_decoded.ok()) << agent_decoded.rejection().describe();
  EXPECT_EQ(agent_decoded.value().robot_id, 4);
  EXPECT_TRUE(agent_decoded.value().mission_done);
  EXPECT_EQ(agent_decoded.value().reject_counts[0], 7);
  // Its reject list's count is pre-checked like server_status_t's.
  const std::size_t count_at = agent_bytes.size() - (4 + 15) - 8 - 4;
  poke_i32(agent_bytes, count_at, 1'000'000);
  EXPECT_EQ(reason_of(rt::decode_message<lmf::agent_status_t>(agent_bytes.data(), agent_bytes.size())),
            RejectReason::kOversized);
}

// ---- rejections ---------------------------------------------------------------------

TEST(ConvertRejects, TruncatedPaddedAndForeignBuffers) {
  const auto bytes = rt::encode_message(rt::to_message(make_scan()));
  for (const std::size_t cut : {std::size_t{0}, std::size_t{4}, std::size_t{20}, bytes.size() - 1}) {
    EXPECT_EQ(reason_of(rt::decode<RobotScan>(bytes.data(), cut)), RejectReason::kDecodeFailed) << cut;
  }
  std::vector<std::uint8_t> padded = bytes;
  padded.push_back(0);
  EXPECT_EQ(reason_of(rt::decode<RobotScan>(padded.data(), padded.size())), RejectReason::kDecodeFailed);
  // A sighting's bytes on a scan channel: wrong fingerprint.
  const auto sighting = rt::encode_message(rt::to_message(make_sighting()).value());
  EXPECT_EQ(reason_of(rt::decode<RobotScan>(sighting.data(), sighting.size())), RejectReason::kDecodeFailed);
  EXPECT_EQ(reason_of(rt::decode<RobotSighting>(sighting.data(), sighting.size() - 1)), RejectReason::kDecodeFailed);
}

TEST(ConvertRejects, ForgedCountsNeverAllocate) {
  // num_ranges sits 4 bytes before the first range: claim 2^31 - 1 beams.
  const RobotScan scan = make_scan();
  auto bytes = rt::encode_message(rt::to_message(scan));
  const std::size_t num_ranges_at = bytes.size() - 4 * scan.scan.ranges_m.size() - 4;
  poke_i32(bytes, num_ranges_at, std::numeric_limits<std::int32_t>::max());
  EXPECT_EQ(reason_of(rt::decode<RobotScan>(bytes.data(), bytes.size())), RejectReason::kOversized);
  poke_i32(bytes, num_ranges_at, 1000);  // within limits but beyond the buffer
  EXPECT_EQ(reason_of(rt::decode<RobotScan>(bytes.data(), bytes.size())), RejectReason::kDecodeFailed);
  poke_i32(bytes, num_ranges_at, -5);
  EXPECT_EQ(reason_of(rt::decode<RobotScan>(bytes.data(), bytes.size())), RejectReason::kDecodeFailed);

  // local_map_t: num_covariance is the int32 before the packed values, which
  // the scan poses (count, 8-byte times, 24-byte poses) follow.
  const auto msg = rt::to_message(make_map(2)).value();
  auto map_bytes = rt::encode_message(msg);
  const std::size_t poses_bytes = 4 + 32 * msg.scan_poses.size();
  const std::size_t num_covariance_at = map_bytes.size() - poses_bytes - 8 * msg.covariance.size() - 4;
  poke_i32(map_bytes, num_covariance_at, 200'000'000);
  EXPECT_EQ(reason_of(rt::decode<lmf::LocalMapSnapshot>(map_bytes.data(), map_bytes.size())), RejectReason::kOversized);
  poke_i32(map_bytes, num_covariance_at, static_cast<std::int32_t>(msg.covariance.size()) + 1);
  EXPECT_EQ(reason_of(rt::decode<lmf::LocalMapSnapshot>(map_bytes.data(), map_bytes.size())),
            RejectReason::kDecodeFailed);

  // num_scan_poses is the last count, before 8-byte times and 24-byte poses.
  map_bytes = rt::encode_message(msg);
  const std::size_t num_scan_poses_at = map_bytes.size() - 32 * msg.scan_poses.size() - 4;
  poke_i32(map_bytes, num_scan_poses_at, std::numeric_limits<std::int32_t>::max());
  EXPECT_EQ(reason_of(rt::decode<lmf::LocalMapSnapshot>(map_bytes.data(), map_bytes.size())), RejectReason::kOversized);
  poke_i32(map_bytes, num_scan_poses_at, static_cast<std::int32_t>(msg.scan_poses.size()) + 1);
  EXPECT_EQ(reason_of(rt::decode<lmf::LocalMapSnapshot>(map_bytes.data(), map_bytes.size())),
            RejectReason::kDecodeFailed);
  poke_i32(map_bytes, num_scan_poses_at, -1);
  EXPECT_EQ(reason_of(rt::decode<lmf::LocalMapSnapshot>(map_bytes.data(), map_bytes.size())),
            RejectReason::kDecodeFailed);

  // mission_end_t ends with its ids.
  const auto end = rt::to_message(MissionEnd{5, {0, 1}}).value();
  auto end_bytes = rt::encode_message(end);
  poke_i32(end_bytes, end_bytes.size() - 8 - 4, 1'000'000);
  EXPECT_EQ(reason_of(rt::decode<MissionEnd>(end_bytes.data(), end_bytes.size())), RejectReason::kOversized);
  poke_i32(end_bytes, end_bytes.size() - 8 - 4, 3);
  EXPECT_EQ(reason_of(rt::decode<MissionEnd>(end_bytes.data(), end_bytes.size())), RejectReason::kDecodeFailed);
}

TEST(ConvertRejects, Oversized) {
  const auto bytes = rt::encode_message(rt::to_message(make_scan()));
  DecodeLimits small;
  small.max_message_bytes = bytes.size() - 1;
  EXPECT_EQ(reason_of(rt::decode<RobotScan>(bytes.data(), bytes.size(), small)), RejectReason::kOversized);
  DecodeLimits few_beams;
  few_beams.max_beams = 100;
  EXPECT_EQ(reason_of(rt::decode<RobotScan>(bytes.data(), bytes.size(), few_beams)), RejectReason::kOversized);
  DecodeLimits few_segments;
  few_segments.max_segments = 2;
  const auto map = rt::encode_message(rt::to_message(make_map(3)).value());
  EXPECT_EQ(reason_of(rt::decode<lmf::LocalMapSnapshot>(map.data(), map.size(), few_segments)),
            RejectReason::kOversized);
  DecodeLimits one_robot;
  one_robot.max_robots = 1;
  const auto frames = rt::encode_message(rt::to_message(make_frames()).value());
  EXPECT_EQ(reason_of(rt::decode<CorrectedFrames>(frames.data(), frames.size(), one_robot)), RejectReason::kOversized);
}

TEST(ConvertRejects, NonFinite) {
  auto scan = rt::to_message(make_scan());
  scan.ranges[17] = std::numeric_limits<float>::quiet_NaN();
  EXPECT_EQ(reason_of(through_bytes<RobotScan>(scan)), RejectReason::kNonFinite);
  scan = rt::to_message(make_scan());
  scan.ranges[0] = std::numeric_limits<float>::infinity();
  EXPECT_EQ(reason_of(through_bytes<RobotScan>(scan)), RejectReason::kNonFinite);
  scan = rt::to_message(make_scan());
  scan.odometry.x = kNan;
  EXPECT_EQ(reason_of(through_bytes<RobotScan>(scan)), RejectReason::kNonFinite);

  auto map = rt::to_message(make_map(2)).value();
  map.covariance[3] = kNan;
  EXPECT_EQ(reason_of(through_bytes<lmf::LocalMapSnapshot>(map)), RejectReason::kNonFinite);
  map = rt::to_message(make_map(2)).value();
  map.segments[1].length = std::numeric_limits<float>::infinity();
  EXPECT_EQ(reason_of(through_bytes<lmf::LocalMapSnapshot>(map)), RejectReason::kNonFinite);

  auto sighting = rt::to_message(make_sighting()).value();
  sighting.covariance[5] = -std::numeric_limits<double>::infinity();
  EXPECT_EQ(reason_of(through_bytes<RobotSighting>(sighting)), RejectReason::kNonFinite);
  sighting = rt::to_message(make_sighting()).value();
  sighting.observer_in_local.y = kNan;
  EXPECT_EQ(reason_of(through_bytes<RobotSighting>(sighting)), RejectReason::kNonFinite);
  auto frames = rt::to_message(make_frames()).value();
  frames.frames[1].y = kNan;
  EXPECT_EQ(reason_of(through_bytes<CorrectedFrames>(frames)), RejectReason::kNonFinite);
  auto ack = rt::to_message(ScanAck{}).value();
  ack.x_LR.x = kNan;
  EXPECT_EQ(reason_of(through_bytes<ScanAck>(ack)), RejectReason::kNonFinite);
  ack = rt::to_message(ScanAck{}).value();
  ack.covariance[3] = kNan;
  EXPECT_EQ(reason_of(through_bytes<ScanAck>(ack)), RejectReason::kNonFinite);

  lmf::LocalMapSnapshot core = make_map(1);
  core.covariance(0, 0) = kNan;
  EXPECT_EQ(reason_of(rt::to_message(core)), RejectReason::kNonFinite);
}

TEST(ConvertRejects, WrongSize) {
  // Covariance count != n(n+1)/2: drop one value (both count and data agree).
  auto map = rt::to_message(make_map(2)).value();
  map.covariance.pop_back();
  map.num_covariance = static_cast<std::int32_t>(map.covariance.size());
  EXPECT_EQ(reason_of(through_bytes<lmf::LocalMapSnapshot>(map)), RejectReason::kWrongSize);
  // Covariance for 2 segments but only one segment.
  map = rt::to_message(make_map(2)).value();
  map.segments.pop_back();
  map.num_segments = 1;
  EXPECT_EQ(reason_of(through_bytes<lmf::LocalMapSnapshot>(map)), RejectReason::kWrongSize);
  // An in-process message whose count disagrees with its array.
  auto scan = rt::to_message(make_scan());
  scan.num_ranges = 3;
  EXPECT_EQ(reason_of(rt::from_message(scan)), RejectReason::kWrongSize);
  // A core snapshot whose covariance does not match its segments.
  lmf::LocalMapSnapshot core = make_map(2);
  core.covariance = Eigen::MatrixXd::Identity(5, 5);
  EXPECT_EQ(reason_of(rt::to_message(core)), RejectReason::kWrongSize);
  auto frames = rt::to_message(make_frames()).value();
  frames.covariance[0].resize(5);
  EXPECT_EQ(reason_of(rt::from_message(frames)), RejectReason::kWrongSize);
}

TEST(ConvertRejects, AsymmetricCovarianceCannotLeave) {
  // The wire holds an upper triangle, so symmetry is checked by the sender.
  lmf::LocalMapSnapshot map = make_map(2);
  map.covariance(1, 4) += 1e-3;
  EXPECT_EQ(reason_of(rt::to_message(map)), RejectReason::kCovarianceNotSymmetric);
  RobotSighting s = make_sighting();
  s.cov_AB(0, 2) = 0.001;
  EXPECT_EQ(reason_of(rt::to_message(s)), RejectReason::kCovarianceNotSymmetric);
  CorrectedFrames frames = make_frames();
  frames.frames[1].covariance(2, 0) += 0.5;
  EXPECT_EQ(reason_of(rt::to_message(frames)), RejectReason::kCovarianceNotSymmetric);
  ScanAck ack;
  ack.covariance(1, 0) = 0.1;
  EXPECT_EQ(reason_of(rt::to_message(ack)), RejectReason::kCovarianceNotSymmetric);
  // Rounding-level asymmetry is tolerated.
  map = make_map(2);
  map.covariance(1, 4) *= 1.0 + 1e-14;
  EXPECT_TRUE(rt::to_message(map).ok());
}

TEST(ConvertRejects, IndefiniteCovariance) {
  // Indefinite with a positive diagonal: [[1, 2], [2, 1]] has eigenvalue -1.
  auto map = rt::to_message(make_map(0)).value();
  map.covariance = {1.0, 2.0, 0.0, 1.0, 0.0, 1.0};
  EXPECT_EQ(reason_of(through_bytes<lmf::LocalMapSnapshot>(map)), RejectReason::kCovarianceNotPsd);
  auto sighting = rt::to_message(make_sighting()).value();
  sighting.covariance[5] = -1e-4;  // a negative variance
  EXPECT_EQ(reason_of(through_bytes<RobotSighting>(sighting)), RejectReason::kCovarianceNotPsd);
  sighting = rt::to_message(make_sighting()).value();
  sighting.observed_covariance[1] = 0.5;  // off-diagonal without variances
  EXPECT_EQ(reason_of(through_bytes<RobotSighting>(sighting)), RejectReason::kCovarianceNotPsd);
  auto frames = rt::to_message(make_frames()).value();
  frames.covariance[1] = {1.0, 0.0, 1.1, 1.0, 0.0, 1.0};
  EXPECT_EQ(reason_of(through_bytes<CorrectedFrames>(frames)), RejectReason::kCovarianceNotPsd);
  auto ack = rt::to_message(ScanAck{}).value();
  ack.covariance[5] = -1.0;
  EXPECT_EQ(reason_of(through_bytes<ScanAck>(ack)), RejectReason::kCovarianceNotPsd);
  // A core matrix with a slightly negative eigenvalue, far beyond rounding.
  lmf::LocalMapSnapshot core = make_map(1);
  Eigen::SelfAdjointEigenSolver<Eigen::MatrixXd> eig(core.covariance);
  Eigen::VectorXd values = eig.eigenvalues();
  values(0) = -1e-6 * values.maxCoeff();
  core.covariance = eig.eigenvectors() * values.asDiagonal() * eig.eigenvectors().transpose();
  core.covariance = (0.5 * (core.covariance + core.covariance.transpose())).eval();
  EXPECT_EQ(reason_of(rt::to_message(core)), RejectReason::kCovarianceNotPsd);
}

TEST(ConvertRejects, BadAngle) {
  auto map = rt::to_message(make_map(1)).value();
  map.robot.phi = 4.0;
  EXPECT_EQ(reason_of(through_bytes<lmf::LocalMapSnapshot>(map)), RejectReason::kBadAngle);
  map = rt::to_message(make_map(1)).value();
  map.segments[0].location.phi = -3.2;
  EXPECT_EQ(reason_of(through_bytes<lmf::LocalMapSnapshot>(map)), RejectReason::kBadAngle);
  auto scan = rt::to_message(make_scan());
  scan.angle_increment = 0.0f;
  EXPECT_EQ(reason_of(through_bytes<RobotScan>(scan)), RejectReason::kBadAngle);
  scan = rt::to_message(make_scan());
  scan.angle_increment = 0.1f;  // 180 * 0.1 rad > 2 pi
  EXPECT_EQ(reason_of(through_bytes<RobotScan>(scan)), RejectReason::kBadAngle);
  scan = rt::to_message(make_scan());
  scan.angle_min = -7.0f;
  EXPECT_EQ(reason_of(through_bytes<RobotScan>(scan)), RejectReason::kBadAngle);
}

TEST(ConvertRejects, OutOfRange) {
  auto scan = rt::to_message(make_scan());
  scan.ranges[3] = -0.5f;
  EXPECT_EQ(reason_of(through_bytes<RobotScan>(scan)), RejectReason::kOutOfRange);
  scan = rt::to_message(make_scan());
  scan.robot_id = -1;
  EXPECT_EQ(reason_of(through_bytes<RobotScan>(scan)), RejectReason::kOutOfRange);
  auto sighting = rt::to_message(make_sighting()).value();
  sighting.observed_seq = -2;
  EXPECT_EQ(reason_of(through_bytes<RobotSighting>(sighting)), RejectReason::kOutOfRange);
  // A robot "seeing itself" decodes: the server answers it REJECTED (an ack
  // needs the decoded ids), so the player stops resending it.
  sighting = rt::to_message(make_sighting()).value();
  sighting.observed_id = sighting.observer_id;
  EXPECT_TRUE(through_bytes<RobotSighting>(sighting).ok());
  auto frames = rt::to_message(make_frames()).value();
  frames.robot_ids[1] = frames.robot_ids[0];
  EXPECT_EQ(reason_of(through_bytes<CorrectedFrames>(frames)), RejectReason::kOutOfRange);
  auto ack = rt::to_message(LocalMapAck{1, 1, 1, LocalMapAck::Status::kFused});
  ack.status = 9;
  EXPECT_EQ(reason_of(through_bytes<LocalMapAck>(ack)), RejectReason::kOutOfRange);
  auto bad_sighting_ack = rt::to_message(SightingAck{1, 0, 1, SightingAck::Status::kApplied});
  bad_sighting_ack.status = 9;
  EXPECT_EQ(reason_of(through_bytes<SightingAck>(bad_sighting_ack)), RejectReason::kOutOfRange);
  bad_sighting_ack.status = lmf::sighting_ack_t::APPLIED;
  bad_sighting_ack.observer_id = -1;
  EXPECT_EQ(reason_of(through_bytes<SightingAck>(bad_sighting_ack)), RejectReason::kOutOfRange);
  auto scan_ack = rt::to_message(ScanAck{}).value();
  scan_ack.local_map_seq = -2;
  EXPECT_EQ(reason_of(through_bytes<ScanAck>(scan_ack)), RejectReason::kOutOfRange);
}

TEST(CovarianceCheck, AcceptsSingularPsdRejectsIndefinite) {
  EXPECT_FALSE(rt::check_covariance(Eigen::MatrixXd::Zero(5, 5), "zero").has_value());
  EXPECT_FALSE(rt::check_covariance(random_covariance(12, 4, 11), "rank 4").has_value());
  EXPECT_FALSE(rt::check_covariance(random_covariance(40, 40, 3), "full rank").has_value());
  // Zero diagonal with a non-zero off-diagonal: indefinite although no pivot is negative.
  Eigen::MatrixXd Z = Eigen::MatrixXd::Zero(3, 3);
  Z(0, 1) = Z(1, 0) = 1e-3;
  EXPECT_EQ(rt::check_covariance(Z, "Z")->reason, RejectReason::kCovarianceNotPsd);
  Z(2, 2) = 1.0;  // same, hidden behind a positive pivot
  EXPECT_EQ(rt::check_covariance(Z, "Z")->reason, RejectReason::kCovarianceNotPsd);
  Eigen::MatrixXd P = random_covariance(6, 6, 5);
  P(5, 5) = -P(5, 5);
  const auto r = rt::check_covariance(P, "P");
  ASSERT_TRUE(r.has_value());
  EXPECT_EQ(r->reason, RejectReason::kCovarianceNotPsd);
  EXPECT_NE(r->detail.find("P:"), std::string::npos);
}

TEST(CovarianceCheck, PackUnpackInverse) {
  const Eigen::MatrixXd P = random_covariance(7, 7, 2);
  const std::vector<double> packed = rt::pack_upper_triangle(P);
  ASSERT_EQ(packed.size(), 28u);
  EXPECT_TRUE(lmf::testing::matrices_near(rt::unpack_upper_triangle(packed, 7), P, 0.0));
}

TEST(RejectCounter, CountsAndNamesAreStable) {
  rt::RejectCounter counter;
  counter.record({RejectReason::kNonFinite, "x"}, "TEST");
  counter.record({RejectReason::kNonFinite, "y"}, "TEST");
  counter.add(RejectReason::kStaleSequence);
  EXPECT_EQ(counter.count(RejectReason::kNonFinite), 2);
  EXPECT_EQ(counter.total(), 3);
  const auto nonzero = counter.nonzero();
  ASSERT_EQ(nonzero.size(), 2u);
  EXPECT_EQ(nonzero[0].first, "non_finite");
  EXPECT_EQ(nonzero[1].first, "stale_sequence");
  const char* expected[] = {"decode_failed", "oversized", "non_finite", "wrong_size",
                            "covariance_not_symmetric", "covariance_not_psd", "bad_angle", "out_of_range",
                            "unknown_robot", "stale_sequence", "handler_error", "auth_missing",
                            "auth_bad_tag", "auth_replayed", "auth_unknown_sender", "auth_not_allowed"};
  static_assert(std::size(expected) == rt::kNumRejectReasons);
  for (std::size_t i = 0; i < rt::kNumRejectReasons; ++i) {
    EXPECT_EQ(rt::reason_name(static_cast<RejectReason>(i)), expected[i]);
  }
}

TEST(RejectCounter, MergeAddsEveryReason) {
  rt::RejectCounter node;
  node.add(RejectReason::kStaleSequence);
  node.add(RejectReason::kNonFinite);
  rt::RejectCounter bus;
  bus.add(RejectReason::kAuthBadTag);
  bus.add(RejectReason::kAuthBadTag);
  bus.add(RejectReason::kStaleSequence);
  node.merge(bus);
  EXPECT_EQ(node.count(RejectReason::kStaleSequence), 2);
  EXPECT_EQ(node.count(RejectReason::kNonFinite), 1);
  EXPECT_EQ(node.count(RejectReason::kAuthBadTag), 2);
  EXPECT_EQ(node.total(), 5);
  EXPECT_EQ(bus.total(), 3);  // the merged-in counter is unchanged
}

}  // namespace
