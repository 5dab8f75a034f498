// THE one place where LCM messages meet core types (docs/design.md §2, §8).
//
// Three layers, each usable alone:
//  1. decode_message<Msg>(bytes): fingerprint, byte limit and array counts are
//     checked against the buffer BEFORE lcm-gen's decoder runs (it resizes
//     vectors to the claimed count before checking the length, so a forged
//     count could otherwise allocate gigabytes), then the message is decoded.
//  2. from_message(msg): validates every field and converts to the core type;
//     to_message(core): the reverse. Encoders of types that carry a covariance
//     return Checked<> too: only the sender can see an asymmetric matrix (the
//     wire holds the packed upper triangle) and an indefinite one must not leave.
//  3. decode<Core>(bytes) = 1 then 2.
// Nothing here throws on bad input, every refusal is a Rejection with a reason.
// unknown_robot and stale_sequence are decided by callers who know the robots.
//
// Conventions on the wire (lcmtypes/*.lcm): covariances as packed upper
// triangles row by row (P00 P01 .. P0n P11 .. Pnn); angles in (-pi, pi];
// times in microseconds; ids >= 0; laser angles and ranges as float.
//
// Threading: all functions are pure and thread-safe.
#pragma once

#include <cstddef>
#include <cstdint>
#include <optional>
#include <span>
#include <string_view>
#include <vector>

#include <Eigen/Core>

#include "lmf/agent_status_t.hpp"
#include "lmf/common/input_bounds.hpp"
#include "lmf/corrected_frames_t.hpp"
#include "lmf/geometry/pose2.hpp"
#include "lmf/global_map_t.hpp"
#include "lmf/laser_scan_t.hpp"
#include "lmf/local_map/local_map_snapshot.hpp"
#include "lmf/front_end/odometry_model.hpp"
#include "lmf/local_map_ack_t.hpp"
#include "lmf/local_map_t.hpp"
#include "lmf/mission_end_t.hpp"
#include "lmf/odometry_model_t.hpp"
#include "lmf/pose2_t.hpp"
#include "lmf/scan_ack_t.hpp"
#include "lmf/server_status_t.hpp"
#include "lmf/sighting_ack_t.hpp"
#include "lmf/sighting_t.hpp"
#include "runtime/messages.hpp"
#include "runtime/rejection.hpp"

namespace lmf::runtime {

// Bounds that keep one message from exhausting memory or time (oversized).
struct DecodeLimits {
  std::size_t max_message_bytes = 8u << 20;  // 8 MiB: a 512-segment local map is ~4.2 MB
  int max_beams = 8192;                      // per laser scan
  int max_segments = 512;                    // per local map (n = 1027 state dims)
  int max_robots = 256;                      // per corrected_frames_t and mission_end_t
  int max_scan_poses = 65536;                // per local map (a parked robot keeps scanning)
  // |x|, |y| of every pose beyond this are garbage (out_of_range), as for the
  // GlobalMap (GlobalMapConfig::max_coordinate_m, the same default): a finite
  // but absurd odometry jump would otherwise overflow an agent's covariance.
  double max_coordinate_m = kDefaultMaxCoordinateM;
};

// Tolerances of the covariance checks (relative to the matrix's own scale).
struct CovarianceTolerance {
  double symmetry = 1e-9;  // |P_ij - P_ji| <= symmetry * max |P|
  double psd = 1e-9;       // eigenvalues >= -psd * max P_ii (tested as P + psd max P_ii I > 0)
  // Largest variance (m², rad²): a standard deviation beyond 1e6 (the
  // coordinate bound, DecodeLimits::max_coordinate_m) is garbage, and a finite
  // but absurd one (1e268) overflowed the fusion into NaN (found by fuzzing).
  double max_variance = 1e12;
};

// ---- 1. bytes <-> LCM messages ---------------------------------------------
// Defined for every message type in lcmtypes/ except the nested pose2_t and
// segment_t. A truncated, padded or foreign buffer is decode_failed.
template <class Msg>
Checked<Msg> decode_message(const void* data, std::size_t size, const DecodeLimits& limits = {});

template <class Msg>
std::vector<std::uint8_t> encode_message(const Msg& msg) {
  std::vector<std::uint8_t> bytes(static_cast<std::size_t>(msg.getEncodedSize()));
  msg.encode(bytes.data(), 0, static_cast<int>(bytes.size()));
  return bytes;
}

// ---- covariance helpers ------------------------------------------------------
// Row-by-row upper triangle of the n x n matrix P (n(n+1)/2 values).
std::vector<double> pack_upper_triangle(const Eigen::MatrixXd& P);
// The symmetric n x n matrix of a packed upper triangle; requires
// packed.size() == n(n+1)/2 (checked by callers; asserts).
Eigen::MatrixXd unpack_upper_triangle(std::span<const double> packed, int n);
// nullopt when P is square, finite, symmetric and PSD within tolerance with
// no variance above tolerance.max_variance, else the rejection (wrong_size,
// non_finite, covariance_not_symmetric, covariance_not_psd, out_of_range)
// naming `what`. PSD is decided by a pivoted LDLᵀ
// factorisation of the slightly shifted matrix (no eigen-decomposition).
std::optional<Rejection> check_covariance(const Eigen::MatrixXd& P, std::string_view what,
                                          const CovarianceTolerance& tolerance = {});

// ---- 2. LCM messages <-> core values ----------------------------------------
Checked<Pose2> from_message(const lmf::pose2_t& msg, const DecodeLimits& limits = {});
lmf::pose2_t to_message(const Pose2& pose);

// An agent's odometry model for its status (values become float). Every
// value must be finite and the counts >= 0.
Checked<OdometryModelReport> from_message(const lmf::odometry_model_t& msg, const DecodeLimits& limits = {});
lmf::odometry_model_t to_message(const OdometryModelReport& report);
OdometryModelReport odometry_model_report(const OdometryErrorModel& model, const OdometryLearningStats& stats);

Checked<RobotScan> from_message(const lmf::laser_scan_t& msg, const DecodeLimits& limits = {});
lmf::laser_scan_t to_message(const RobotScan& scan);  // ranges and angles become float

// The snapshot's scan_poses travel at the end of the message (the fusion does
// not need them; the server writes trajectories from them). num_scans repeats
// their count and must agree with it.
Checked<LocalMapSnapshot> from_message(const lmf::local_map_t& msg, const DecodeLimits& limits = {});
Checked<lmf::local_map_t> to_message(const LocalMapSnapshot& map, const CovarianceTolerance& tolerance = {});

Checked<CorrectedFrames> from_message(const lmf::corrected_frames_t& msg, const DecodeLimits& limits = {});
Checked<lmf::corrected_frames_t> to_message(const CorrectedFrames& frames,
                                            const CovarianceTolerance& tolerance = {});

Checked<fusion::RobotSighting> from_message(const lmf::sighting_t& msg, const DecodeLimits& limits = {});
Checked<lmf::sighting_t> to_message(const fusion::RobotSighting& sighting, const CovarianceTolerance& tolerance = {});

Checked<ScanAck> from_message(const lmf::scan_ack_t& msg, const DecodeLimits& limits = {});
Checked<lmf::scan_ack_t> to_message(const ScanAck& ack, const CovarianceTolerance& tolerance = {});

Checked<MissionEnd> from_message(const lmf::mission_end_t& msg, const DecodeLimits& limits = {});
Checked<lmf::mission_end_t> to_message(const MissionEnd& end);

Checked<LocalMapAck> from_message(const lmf::local_map_ack_t& msg, const DecodeLimits& limits = {});
lmf::local_map_ack_t to_message(const LocalMapAck& ack);

Checked<SightingAck> from_message(const lmf::sighting_ack_t& msg, const DecodeLimits& limits = {});
lmf::sighting_ack_t to_message(const SightingAck& ack);

// Status and map summary: times and counts >= 0, numbers finite (times in ms
// become float), reject counts >= 0; the agent's pose within the coordinate
// bound, the map's end points too.
Checked<AgentStatus> from_message(const lmf::agent_status_t& msg, const DecodeLimits& limits = {});
Checked<lmf::agent_status_t> to_message(const AgentStatus& status);

Checked<ServerStatus> from_message(const lmf::server_status_t& msg, const DecodeLimits& limits = {});
Checked<lmf::server_status_t> to_message(const ServerStatus& status);

Checked<GlobalMapSummary> from_message(const lmf::global_map_t& msg, const DecodeLimits& limits = {});
Checked<lmf::global_map_t> to_message(const GlobalMapSummary& map);  // end points become float

// ---- 3. bytes -> core values -------------------------------------------------
template <class Core>
struct MessageOf;  // the LCM type that carries Core
template <> struct MessageOf<RobotScan> { using type = lmf::laser_scan_t; };
template <> struct MessageOf<LocalMapSnapshot> { using type = lmf::local_map_t; };
template <> struct MessageOf<CorrectedFrames> { using type = lmf::corrected_frames_t; };
template <> struct MessageOf<fusion::RobotSighting> { using type = lmf::sighting_t; };
template <> struct MessageOf<ScanAck> { using type = lmf::scan_ack_t; };
template <> struct MessageOf<LocalMapAck> { using type = lmf::local_map_ack_t; };
template <> struct MessageOf<SightingAck> { using type = lmf::sighting_ack_t; };
template <> struct MessageOf<MissionEnd> { using type = lmf::mission_end_t; };
template <> struct MessageOf<AgentStatus> { using type = lmf::agent_status_t; };
template <> struct MessageOf<ServerStatus> { using type = lmf::server_status_t; };
template <> struct MessageOf<GlobalMapSummary> { using type = lmf::global_map_t; };

template <class Core>
Checked<Core> decode(const void* data, std::size_t size, const DecodeLimits& limits = {}) {
  auto msg = decode_message<typename MessageOf<Core>::type>(data, size, limits);
  if (!msg) return msg.rejection();
  return from_message(msg.value(), limits);
}

}  // namespace lmf::runtime
