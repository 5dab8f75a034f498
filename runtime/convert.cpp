#include "runtime/convert.hpp"

#include <algorithm>
#include <array>
#include <cassert>
#include <cmath>
#include <limits>
#include <numbers>
#include <set>
#include <string>
#include <utility>

#include <Eigen/Cholesky>

namespace lmf::runtime {

namespace {

using std::to_string;

Rejection reject(RejectReason reason, std::string detail) { return Rejection{reason, std::move(detail)}; }

// Angles on the wire are in (-pi, pi]; float fields get float rounding slack.
constexpr double kAngleSlackDouble = 1e-9;
constexpr double kAngleSlackFloat = 1e-6;

std::int64_t packed_size(std::int64_t n) { return n * (n + 1) / 2; }

// ---- wire prechecks ----------------------------------------------------------
// Offsets are measured on the generated encoder (an empty message's size), so
// adding a field in front of an array keeps them right; the round-trip tests
// fail if a .lcm change breaks an assumption stated below.

std::int32_t read_i32_be(const std::uint8_t* p) {
  const std::uint32_t v = (std::uint32_t{p[0]} << 24) | (std::uint32_t{p[1]} << 16) |
                          (std::uint32_t{p[2]} << 8) | std::uint32_t{p[3]};
  return static_cast<std::int32_t>(v);
}

template <class Msg>
std::size_t empty_size() {
  static const std::size_t size = static_cast<std::size_t>(Msg{}.getEncodedSize());
  return size;
}

// A count read at `offset` must be >= 0, within `limit` (oversized) and, with
// `element_bytes` per element, fit in the buffer (else decode_failed).
std::optional<Rejection> check_count(const std::uint8_t* bytes, std::size_t size, std::size_t offset,
                                     std::size_t element_bytes, std::int64_t limit, std::string_view what) {
  if (offset + 4 > size) return reject(RejectReason::kDecodeFailed, std::string(what) + ": truncated");
  const std::int32_t count = read_i32_be(bytes + offset);
  if (count < 0) return reject(RejectReason::kDecodeFailed, std::string(what) + ": negative count " + to_string(count));
  if (count > limit) {
    return reject(RejectReason::kOversized, std::string(what) + ": " + to_string(count) + " > limit " + to_string(limit));
  }
  if (static_cast<std::size_t>(count) * element_bytes > size - offset - 4) {
    return reject(RejectReason::kDecodeFailed,
                  std::string(what) + ": count " + to_string(count) + " exceeds the " + to_string(size) + "-byte buffer");
  }
  return std::nullopt;
}

// Assumption: the message ends with `int32_t num; T array[num]`.
template <class Msg>
std::optional<Rejection> check_trailing_array(const std::uint8_t* bytes, std::size_t size, std::size_t element_bytes,
                                              std::int64_t limit, std::string_view what) {
  const std::size_t base = empty_size<Msg>();
  if (size < base) return reject(RejectReason::kDecodeFailed, std::string(what) + ": truncated");
  return check_count(bytes, size, base - 4, element_bytes, limit, what);
}

// Fixed-size messages need no precheck.
std::optional<Rejection> precheck(std::type_identity<lmf::sighting_t>, const std::uint8_t*, std::size_t,
                                  const DecodeLimits&) { return std::nullopt; }
std::optional<Rejection> precheck(std::type_identity<lmf::scan_ack_t>, const std::uint8_t*, std::size_t,
                                  const DecodeLimits&) { return std::nullopt; }
std::optional<Rejection> precheck(std::type_identity<lmf::local_map_ack_t>, const std::uint8_t*, std::size_t,
                                  const DecodeLimits&) { return std::nullopt; }
std::optional<Rejection> precheck(std::type_identity<lmf::sighting_ack_t>, const std::uint8_t*, std::size_t,
                                  const DecodeLimits&) { return std::nullopt; }

std::optional<Rejection> precheck(std::type_identity<lmf::mission_end_t>, const std::uint8_t* bytes, std::size_t size,
                                  const DecodeLimits& limits) {
  return check_trailing_array<lmf::mission_end_t>(bytes, size, sizeof(std::int32_t), limits.max_robots,
                                                  "mission_end_t.num_robots");
}

std::optional<Rejection> precheck(std::type_identity<lmf::laser_scan_t>, const std::uint8_t* bytes, std::size_t size,
                                  const DecodeLimits& limits) {
  return check_trailing_array<lmf::laser_scan_t>(bytes, size, sizeof(float), limits.max_beams, "laser_scan_t.num_ranges");
}

std::optional<Rejection> precheck(std::type_identity<lmf::global_map_t>, const std::uint8_t* bytes, std::size_t size,
                                  const DecodeLimits& limits) {
  return check_trailing_array<lmf::global_map_t>(bytes, size, 4 * sizeof(float),
                                                 std::int64_t{limits.max_segments} * limits.max_robots * 8,
                                                 "global_map_t.num_segments");
}

// Assumption: the message ends with `int32_t num; string names[num]; int64_t
// counts[num]` (the reject counts of the status messages). lcm-gen's string
// decoder trusts each length (0 or INT32_MIN make it compute `length - 1`: a
// huge assign or a signed overflow) and keeps embedded NULs, which its encoder
// then drops, so a status would not survive a re-publication. Reason names are
// short lower_snake ASCII (rejection.hpp); a string of anything else but
// printable ASCII (a monitor writes them into JSON) is decode_failed here.
template <class Msg>
std::optional<Rejection> check_reason_strings(const std::uint8_t* bytes, std::size_t size, std::string_view what) {
  constexpr std::int32_t kMaxNameBytes = 64 + 1;  // with the NUL
  // Each reason is a string (>= 5 bytes: length + NUL) and an int64 count.
  if (auto r = check_trailing_array<Msg>(bytes, size, 5 + 8, 1024, what)) return r;
  const std::size_t base = empty_size<Msg>();
  const std::int32_t count = read_i32_be(bytes + base - 4);
  std::size_t pos = base;
  for (std::int32_t i = 0; i < count; ++i) {
    const std::string name = std::string(what) + ": string " + to_string(i);
    if (size - pos < 4) return reject(RejectReason::kDecodeFailed, name + " truncated");
    const std::int32_t length = read_i32_be(bytes + pos);
    if (length < 1 || length > kMaxNameBytes) {
      return reject(RejectReason::kDecodeFailed, name + ": length " + to_string(length) + " outside 1.." +
                                                     to_string(kMaxNameBytes));
    }
    pos += 4;
    const auto n = static_cast<std::size_t>(length);
    if (size - pos < n) return reject(RejectReason::kDecodeFailed, name + " truncated");
    if (bytes[pos + n - 1] != 0) return reject(RejectReason::kDecodeFailed, name + " is not NUL-terminated");
    for (std::size_t k = 0; k + 1 < n; ++k) {
      if (bytes[pos + k] < 0x21 || bytes[pos + k] > 0x7e) {
        return reject(RejectReason::kDecodeFailed, name + ": byte " + to_string(bytes[pos + k]) + " is not printable ASCII");
      }
    }
    pos += n;
  }
  return std::nullopt;
}

std::optional<Rejection> precheck(std::type_identity<lmf::server_status_t>, const std::uint8_t* bytes,
                                  std::size_t size, const DecodeLimits&) {
  return check_reason_strings<lmf::server_status_t>(bytes, size, "server_status_t.num_reject_reasons");
}

std::optional<Rejection> precheck(std::type_identity<lmf::agent_status_t>, const std::uint8_t* bytes,
                                  std::size_t size, const DecodeLimits&) {
  return check_reason_strings<lmf::agent_status_t>(bytes, size, "agent_status_t.num_reject_reasons");
}

// Assumption: corrected_frames_t ends with `int32_t num_robots` followed by
// arrays of num_robots fixed-size elements.
std::optional<Rejection> precheck(std::type_identity<lmf::corrected_frames_t>, const std::uint8_t* bytes,
                                  std::size_t size, const DecodeLimits& limits) {
  static const std::size_t per_robot = [] {
    lmf::corrected_frames_t one{};
    one.num_robots = 1;
    one.robot_ids.resize(1);
    one.last_applied_seq.resize(1);
    one.frames.resize(1);
    one.covariance.assign(1, std::vector<double>(6, 0.0));
    return static_cast<std::size_t>(one.getEncodedSize()) - empty_size<lmf::corrected_frames_t>();
  }();
  return check_trailing_array<lmf::corrected_frames_t>(bytes, size, per_robot, limits.max_robots,
                                                       "corrected_frames_t.num_robots");
}

// Assumption: local_map_t ends with `int32_t num_segments; segment_t
// segments[num_segments]; int32_t num_covariance; double covariance[...];
// int32_t num_scan_poses; int64_t scan_utimes[...]; pose2_t scan_poses[...]`.
// Each count is checked against the bytes left after the arrays before it.
std::optional<Rejection> precheck(std::type_identity<lmf::local_map_t>, const std::uint8_t* bytes, std::size_t size,
                                  const DecodeLimits& limits) {
  const std::size_t base = empty_size<lmf::local_map_t>();
  if (size < base) return reject(RejectReason::kDecodeFailed, "local_map_t: truncated");
  const std::size_t segment_bytes = static_cast<std::size_t>(lmf::segment_t{}._getEncodedSizeNoHash());
  const std::size_t pose_bytes = static_cast<std::size_t>(lmf::pose2_t{}._getEncodedSizeNoHash());
  const std::size_t segments_offset = base - 12;
  if (auto r = check_count(bytes, size, segments_offset, segment_bytes, limits.max_segments, "local_map_t.num_segments")) {
    return r;
  }
  const std::int64_t num_segments = read_i32_be(bytes + segments_offset);
  const std::int64_t max_covariance = packed_size(3 + 2 * std::int64_t{limits.max_segments});
  const std::size_t covariance_offset = segments_offset + 4 + static_cast<std::size_t>(num_segments) * segment_bytes;
  if (auto r = check_count(bytes, size, covariance_offset, sizeof(double), max_covariance, "local_map_t.num_covariance")) {
    return r;
  }
  const std::int64_t num_covariance = read_i32_be(bytes + covariance_offset);
  const std::size_t poses_offset = covariance_offset + 4 + static_cast<std::size_t>(num_covariance) * sizeof(double);
  return check_count(bytes, size, poses_offset, sizeof(std::int64_t) + pose_bytes, limits.max_scan_poses,
                     "local_map_t.num_scan_poses");
}

// ---- field checks --------------------------------------------------------------

std::optional<Rejection> check_finite(double value, std::string_view what) {
  if (!std::isfinite(value)) return reject(RejectReason::kNonFinite, std::string(what) + " = " + to_string(value));
  return std::nullopt;
}

std::optional<Rejection> check_nonnegative(std::int64_t value, std::string_view what) {
  if (value < 0) return reject(RejectReason::kOutOfRange, std::string(what) + " = " + to_string(value) + " < 0");
  return std::nullopt;
}

std::optional<Rejection> check_angle(double angle_rad, double slack, std::string_view what) {
  if (auto r = check_finite(angle_rad, what)) return r;
  if (std::abs(angle_rad) > std::numbers::pi + slack) {
    return reject(RejectReason::kBadAngle, std::string(what) + " = " + to_string(angle_rad) + " rad outside (-pi, pi]");
  }
  return std::nullopt;
}

Checked<Pose2> pose_from(const lmf::pose2_t& msg, std::string_view what, const DecodeLimits& limits) {
  if (auto r = check_finite(msg.x, std::string(what) + ".x")) return *r;
  if (auto r = check_finite(msg.y, std::string(what) + ".y")) return *r;
  if (std::abs(msg.x) > limits.max_coordinate_m || std::abs(msg.y) > limits.max_coordinate_m) {
    return reject(RejectReason::kOutOfRange, std::string(what) + " = (" + to_string(msg.x) + ", " + to_string(msg.y) +
                                                 ") m beyond " + to_string(limits.max_coordinate_m) + " m");
  }
  if (auto r = check_angle(msg.phi, kAngleSlackDouble, std::string(what) + ".phi")) return *r;
  return Pose2(msg.x, msg.y, wrap_angle(msg.phi));
}

// A 3x3 covariance packed in 6 values.
Checked<Eigen::Matrix3d> covariance3_from(const double* packed, std::size_t count, std::string_view what) {
  if (count != 6) {
    return reject(RejectReason::kWrongSize, std::string(what) + ": " + to_string(count) + " values, expected 6");
  }
  for (std::size_t i = 0; i < 6; ++i) {
    if (auto r = check_finite(packed[i], std::string(what) + "[" + to_string(i) + "]")) return *r;
  }
  const Eigen::MatrixXd P = unpack_upper_triangle(std::span<const double>(packed, 6), 3);
  if (auto r = check_covariance(P, what)) return *r;
  return Eigen::Matrix3d(P);
}

}  // namespace

// ---- decode_message -------------------------------------------------------------

template <class Msg>
Checked<Msg> decode_message(const void* data, std::size_t size, const DecodeLimits& limits) {
  const std::string_view name = Msg::getTypeName();
  if (size > limits.max_message_bytes) {
    return reject(RejectReason::kOversized, std::string(name) + ": " + to_string(size) + " bytes > limit " +
                                                to_string(limits.max_message_bytes));
  }
  if (data == nullptr && size != 0) return reject(RejectReason::kDecodeFailed, std::string(name) + ": no data");
  const auto* bytes = static_cast<const std::uint8_t*>(data);
  if (size < 8) return reject(RejectReason::kDecodeFailed, std::string(name) + ": " + to_string(size) + " bytes");
  if (auto r = precheck(std::type_identity<Msg>{}, bytes, size, limits)) return *r;
  Msg msg;
  int used = -1;
  try {
    used = msg.decode(data, 0, static_cast<int>(size));
  } catch (const std::exception& e) {  // e.g. bad_alloc from a count the precheck let through
    return reject(RejectReason::kDecodeFailed, std::string(name) + ": " + e.what());
  }
  if (used < 0) {
    return reject(RejectReason::kDecodeFailed, std::string(name) + ": wrong fingerprint or truncated (" +
                                                   to_string(size) + " bytes)");
  }
  if (static_cast<std::size_t>(used) != size) {
    return reject(RejectReason::kDecodeFailed,
                  std::string(name) + ": " + to_string(size - static_cast<std::size_t>(used)) + " trailing bytes");
  }
  return msg;
}

template Checked<lmf::laser_scan_t> decode_message(const void*, std::size_t, const DecodeLimits&);
template Checked<lmf::local_map_t> decode_message(const void*, std::size_t, const DecodeLimits&);
template Checked<lmf::local_map_ack_t> decode_message(const void*, std::size_t, const DecodeLimits&);
template Checked<lmf::sighting_ack_t> decode_message(const void*, std::size_t, const DecodeLimits&);
template Checked<lmf::corrected_frames_t> decode_message(const void*, std::size_t, const DecodeLimits&);
template Checked<lmf::sighting_t> decode_message(const void*, std::size_t, const DecodeLimits&);
template Checked<lmf::scan_ack_t> decode_message(const void*, std::size_t, const DecodeLimits&);
template Checked<lmf::global_map_t> decode_message(const void*, std::size_t, const DecodeLimits&);
template Checked<lmf::agent_status_t> decode_message(const void*, std::size_t, const DecodeLimits&);
template Checked<lmf::server_status_t> decode_message(const void*, std::size_t, const DecodeLimits&);
template Checked<lmf::mission_end_t> decode_message(const void*, std::size_t, const DecodeLimits&);

// ---- covariance helpers ------------------------------------------------------------

std::vector<double> pack_upper_triangle(const Eigen::MatrixXd& P) {
  assert(P.rows() == P.cols());
  const Eigen::Index n = P.rows();
  std::vector<double> packed;
  packed.reserve(static_cast<std::size_t>(packed_size(n)));
  for (Eigen::Index i = 0; i < n; ++i) {
    for (Eigen::Index j = i; j < n; ++j) packed.push_back(P(i, j));
  }
  return packed;
}

Eigen::MatrixXd unpack_upper_triangle(std::span<const double> packed, int n) {
  assert(n >= 0 && static_cast<std::int64_t>(packed.size()) == packed_size(n));
  Eigen::MatrixXd P(n, n);
  std::size_t k = 0;
  for (int i = 0; i < n; ++i) {
    for (int j = i; j < n; ++j) {
      P(i, j) = packed[k];
      P(j, i) = packed[k];
      ++k;
    }
  }
  return P;
}

std::optional<Rejection> check_covariance(const Eigen::MatrixXd& P, std::string_view what,
                                          const CovarianceTolerance& tolerance) {
  if (P.rows() != P.cols()) {
    return reject(RejectReason::kWrongSize,
                  std::string(what) + ": " + to_string(P.rows()) + " x " + to_string(P.cols()) + " is not square");
  }
  if (P.size() == 0) return std::nullopt;
  if (!P.allFinite()) return reject(RejectReason::kNonFinite, std::string(what) + ": NaN or infinity");
  const double scale = P.cwiseAbs().maxCoeff();
  const double asymmetry = (P - P.transpose()).cwiseAbs().maxCoeff();
  if (asymmetry > tolerance.symmetry * scale) {
    return reject(RejectReason::kCovarianceNotSymmetric,
                  std::string(what) + ": max |P - P^T| = " + to_string(asymmetry) + " (max |P| = " + to_string(scale) + ")");
  }
  // PSD within tolerance <=> P + delta I is positive definite, delta = psd * max P_ii.
  // A pivoted LDLᵀ of the shifted matrix completes with all pivots > 0 exactly
  // then (inertia); rounding (~n eps max P_ii) stays far below delta. The shift
  // matters: an unshifted singular PSD matrix makes Eigen's LDLT meet zero
  // pivots over rounding-level columns and report failure.
  const double max_diagonal = P.diagonal().maxCoeff();
  if (max_diagonal > tolerance.max_variance) {
    return reject(RejectReason::kOutOfRange, std::string(what) + ": variance " + to_string(max_diagonal) + " above " +
                                                 to_string(tolerance.max_variance));
  }
  if (max_diagonal <= 0.0) {
    if (max_diagonal == 0.0 && scale == 0.0) return std::nullopt;  // the zero matrix
    return reject(RejectReason::kCovarianceNotPsd,
                  std::string(what) + ": largest diagonal entry " + to_string(max_diagonal) + " with max |P| = " +
                      to_string(scale));
  }
  const double delta = tolerance.psd * max_diagonal;
  Eigen::MatrixXd shifted = P;
  shifted.diagonal().array() += delta;
  const Eigen::LDLT<Eigen::MatrixXd> ldlt(shifted);
  const double min_pivot = ldlt.vectorD().minCoeff();
  // Huge entries can overflow inside the factorisation; inf - inf = NaN then
  // slips through every comparison, so a factor with NaN or inf refuses too.
  if (ldlt.info() != Eigen::Success || !(min_pivot > 0.0) || !ldlt.vectorD().allFinite() ||
      !ldlt.matrixLDLT().allFinite()) {
    return reject(RejectReason::kCovarianceNotPsd,
                  std::string(what) + ": LDL^T of P + " + to_string(delta) + " I has pivot " + to_string(min_pivot) +
                      " (max P_ii = " + to_string(max_diagonal) + ")");
  }
  return std::nullopt;
}

// ---- pose2 -------------------------------------------------------------------------

Checked<Pose2> from_message(const lmf::pose2_t& msg, const DecodeLimits& limits) {
  return pose_from(msg, "pose2_t", limits);
}

lmf::pose2_t to_message(const Pose2& pose) {
  lmf::pose2_t msg;
  msg.x = pose.x;
  msg.y = pose.y;
  msg.phi = pose.phi;
  return msg;
}

OdometryModelReport odometry_model_report(const OdometryErrorModel& model, const OdometryLearningStats& stats) {
  return OdometryModelReport{model, static_cast<std::int64_t>(stats.increments),
                             static_cast<std::int64_t>(stats.downweighted)};
}

Checked<OdometryModelReport> from_message(const lmf::odometry_model_t& msg, const DecodeLimits&) {
  const std::pair<const char*, float> values[] = {
      {"translation_scale", msg.translation_scale}, {"rotation_scale", msg.rotation_scale},
      {"heading_bias_rad_per_m", msg.heading_bias_rad_per_m}, {"x_step_m", msg.x_step_m},
      {"x_per_m", msg.x_per_m}, {"y_step_m", msg.y_step_m}, {"y_per_m", msg.y_per_m},
      {"phi_step_rad", msg.phi_step_rad}, {"phi_per_m", msg.phi_per_m}, {"phi_per_rad", msg.phi_per_rad},
      {"phi_turn_distance", msg.phi_turn_distance}};
  for (const auto& [name, value] : values) {
    if (auto r = check_finite(value, std::string("odometry_model_t.") + name)) return *r;
  }
  if (auto r = check_nonnegative(msg.increments_learned, "odometry_model_t.increments_learned")) return *r;
  if (auto r = check_nonnegative(msg.increments_downweighted, "odometry_model_t.increments_downweighted")) return *r;
  OdometryModelReport report;
  OdometryErrorModel& m = report.model;
  m.translation_scale = msg.translation_scale;
  m.rotation_scale = msg.rotation_scale;
  m.heading_bias_rad_per_m = msg.heading_bias_rad_per_m;
  m.x_step_m = msg.x_step_m;
  m.x_per_m = msg.x_per_m;
  m.y_step_m = msg.y_step_m;
  m.y_per_m = msg.y_per_m;
  m.phi_step_rad = msg.phi_step_rad;
  m.phi_per_m = msg.phi_per_m;
  m.phi_per_rad = msg.phi_per_rad;
  m.phi_turn_distance = msg.phi_turn_distance;
  report.increments_learned = msg.increments_learned;
  report.increments_downweighted = msg.increments_downweighted;
  return report;
}

lmf::odometry_model_t to_message(const OdometryModelReport& report) {
  const OdometryErrorModel& m = report.model;
  lmf::odometry_model_t msg;
  msg.translation_scale = static_cast<float>(m.translation_scale);
  msg.rotation_scale = static_cast<float>(m.rotation_scale);
  msg.heading_bias_rad_per_m = static_cast<float>(m.heading_bias_rad_per_m);
  msg.x_step_m = static_cast<float>(m.x_step_m);
  msg.x_per_m = static_cast<float>(m.x_per_m);
  msg.y_step_m = static_cast<float>(m.y_step_m);
  msg.y_per_m = static_cast<float>(m.y_per_m);
  msg.phi_step_rad = static_cast<float>(m.phi_step_rad);
  msg.phi_per_m = static_cast<float>(m.phi_per_m);
  msg.phi_per_rad = static_cast<float>(m.phi_per_rad);
  msg.phi_turn_distance = static_cast<float>(m.phi_turn_distance);
  msg.increments_learned = report.increments_learned;
  msg.increments_downweighted = report.increments_downweighted;
  return msg;
}

// ---- laser scan ----------------------------------------------------------------------

Checked<RobotScan> from_message(const lmf::laser_scan_t& msg, const DecodeLimits& limits) {
  if (msg.num_ranges > limits.max_beams) {
    return reject(RejectReason::kOversized, "laser_scan_t: " + to_string(msg.num_ranges) + " beams > limit " +
                                                to_string(limits.max_beams));
  }
  if (msg.num_ranges < 0 || static_cast<std::size_t>(msg.num_ranges) != msg.ranges.size()) {
    return reject(RejectReason::kWrongSize, "laser_scan_t: num_ranges " + to_string(msg.num_ranges) + " but " +
                                                to_string(msg.ranges.size()) + " ranges");
  }
  if (auto r = check_nonnegative(msg.utime, "laser_scan_t.utime")) return *r;
  if (auto r = check_nonnegative(msg.robot_id, "laser_scan_t.robot_id")) return *r;
  if (auto r = check_nonnegative(msg.seq, "laser_scan_t.seq")) return *r;
  auto odometry = pose_from(msg.odometry, "laser_scan_t.odometry", limits);
  if (!odometry) return odometry.rejection();

  if (auto r = check_angle(msg.angle_min, kAngleSlackFloat, "laser_scan_t.angle_min")) return *r;
  if (auto r = check_finite(msg.angle_increment, "laser_scan_t.angle_increment")) return *r;
  const double span = static_cast<double>(msg.angle_increment) * std::max(0, msg.num_ranges - 1);
  if (msg.angle_increment <= 0.0f || span > 2.0 * std::numbers::pi + kAngleSlackFloat) {
    return reject(RejectReason::kBadAngle, "laser_scan_t.angle_increment = " + to_string(msg.angle_increment) +
                                               " rad: must be > 0 with the scan spanning at most 2 pi");
  }
  if (auto r = check_finite(msg.max_range, "laser_scan_t.max_range")) return *r;
  if (msg.max_range <= 0.0f) {
    return reject(RejectReason::kOutOfRange, "laser_scan_t.max_range = " + to_string(msg.max_range) + " m <= 0");
  }

  RobotScan out;
  out.robot_id = msg.robot_id;
  out.seq = msg.seq;
  out.scan.utime = msg.utime;
  out.scan.odometry = odometry.value();
  out.scan.angle_min_rad = msg.angle_min;
  out.scan.angle_increment_rad = msg.angle_increment;
  out.scan.max_range_m = msg.max_range;
  out.scan.ranges_m.reserve(msg.ranges.size());
  for (std::size_t i = 0; i < msg.ranges.size(); ++i) {
    const float range = msg.ranges[i];
    if (!std::isfinite(range)) {
      return reject(RejectReason::kNonFinite, "laser_scan_t.ranges[" + to_string(i) + "] = " + to_string(range));
    }
    if (range < 0.0f) {
      return reject(RejectReason::kOutOfRange, "laser_scan_t.ranges[" + to_string(i) + "] = " + to_string(range) + " m < 0");
    }
    out.scan.ranges_m.push_back(range);
  }
  return out;
}

lmf::laser_scan_t to_message(const RobotScan& scan) {
  lmf::laser_scan_t msg;
  msg.utime = scan.scan.utime;
  msg.robot_id = scan.robot_id;
  msg.seq = scan.seq;
  msg.odometry = to_message(scan.scan.odometry);
  msg.angle_min = static_cast<float>(scan.scan.angle_min_rad);
  msg.angle_increment = static_cast<float>(scan.scan.angle_increment_rad);
  msg.max_range = static_cast<float>(scan.scan.max_range_m);
  msg.num_ranges = static_cast<std::int32_t>(scan.scan.ranges_m.size());
  msg.ranges.reserve(scan.scan.ranges_m.size());
  for (const double r : scan.scan.ranges_m) msg.ranges.push_back(static_cast<float>(r));
  return msg;
}

// ---- local map -------------------------------------------------------------------------

Checked<LocalMapSnapshot> from_message(const lmf::local_map_t& msg, const DecodeLimits& limits) {
  if (msg.num_segments > limits.max_segments) {
    return reject(RejectReason::kOversized, "local_map_t: " + to_string(msg.num_segments) + " segments > limit " +
                                                to_string(limits.max_segments));
  }
  if (msg.num_segments < 0 || static_cast<std::size_t>(msg.num_segments) != msg.segments.size()) {
    return reject(RejectReason::kWrongSize, "local_map_t: num_segments " + to_string(msg.num_segments) + " but " +
                                                to_string(msg.segments.size()) + " segments");
  }
  const int n = 3 + 2 * msg.num_segments;  // docs/design.md §7: robot (3) then 2 per segment
  if (msg.num_covariance != packed_size(n) || msg.covariance.size() != static_cast<std::size_t>(packed_size(n))) {
    return reject(RejectReason::kWrongSize, "local_map_t.covariance: num_covariance " + to_string(msg.num_covariance) +
                                                " with " + to_string(msg.covariance.size()) + " values; n = " +
                                                to_string(n) + " needs " + to_string(packed_size(n)));
  }
  if (auto r = check_nonnegative(msg.utime, "local_map_t.utime")) return *r;
  if (auto r = check_nonnegative(msg.robot_id, "local_map_t.robot_id")) return *r;
  if (auto r = check_nonnegative(msg.seq, "local_map_t.seq")) return *r;
  if (auto r = check_nonnegative(msg.first_scan_utime, "local_map_t.first_scan_utime")) return *r;
  if (msg.num_scan_poses > limits.max_scan_poses) {
    return reject(RejectReason::kOversized, "local_map_t: " + to_string(msg.num_scan_poses) + " scan poses > limit " +
                                                to_string(limits.max_scan_poses));
  }
  const auto num_poses = static_cast<std::size_t>(std::max(msg.num_scan_poses, 0));
  if (msg.num_scan_poses < 0 || msg.scan_utimes.size() != num_poses || msg.scan_poses.size() != num_poses ||
      msg.num_scans != msg.num_scan_poses) {
    return reject(RejectReason::kWrongSize, "local_map_t: num_scan_poses " + to_string(msg.num_scan_poses) + " with " +
                                                to_string(msg.scan_utimes.size()) + " times, " +
                                                to_string(msg.scan_poses.size()) + " poses and num_scans " +
                                                to_string(msg.num_scans));
  }
  if (msg.first_scan_utime > msg.utime) {
    return reject(RejectReason::kOutOfRange, "local_map_t: first_scan_utime " + to_string(msg.first_scan_utime) +
                                                 " after utime " + to_string(msg.utime));
  }
  auto robot = pose_from(msg.robot, "local_map_t.robot", limits);
  if (!robot) return robot.rejection();

  LocalMapSnapshot out;
  out.robot_id = msg.robot_id;
  out.seq = msg.seq;
  out.first_utime = msg.first_scan_utime;
  out.last_utime = msg.utime;
  out.x_LR = robot.value();
  out.segments.reserve(msg.segments.size());
  for (std::size_t i = 0; i < msg.segments.size(); ++i) {
    const std::string what = "local_map_t.segments[" + to_string(i) + "]";
    auto location = pose_from(msg.segments[i].location, what + ".location", limits);
    if (!location) return location.rejection();
    const float length = msg.segments[i].length;
    if (auto r = check_finite(length, what + ".length")) return *r;
    if (length < 0.0f || length > limits.max_coordinate_m) {
      return reject(RejectReason::kOutOfRange, what + ".length = " + to_string(length) + " m outside [0, " +
                                                   to_string(limits.max_coordinate_m) + "]");
    }
    out.segments.push_back(SegmentEstimate{location.value(), length});
  }
  for (std::size_t i = 0; i < msg.covariance.size(); ++i) {
    if (auto r = check_finite(msg.covariance[i], "local_map_t.covariance[" + to_string(i) + "]")) return *r;
  }
  out.covariance = unpack_upper_triangle(msg.covariance, n);
  if (auto r = check_covariance(out.covariance, "local_map_t.covariance")) return *r;
  out.scan_poses.reserve(num_poses);
  std::int64_t previous_utime = msg.first_scan_utime;
  for (std::size_t i = 0; i < num_poses; ++i) {
    const std::string what = "local_map_t.scan_poses[" + to_string(i) + "]";
    const std::int64_t utime = msg.scan_utimes[i];
    if (utime < previous_utime || utime > msg.utime) {
      return reject(RejectReason::kOutOfRange, what + ": utime " + to_string(utime) + " outside [" +
                                                   to_string(previous_utime) + ", " + to_string(msg.utime) + "]");
    }
    previous_utime = utime;
    auto pose = pose_from(msg.scan_poses[i], what, limits);
    if (!pose) return pose.rejection();
    out.scan_poses.push_back(ScanPose{utime, pose.value()});
  }
  return out;
}

Checked<lmf::local_map_t> to_message(const LocalMapSnapshot& map, const CovarianceTolerance& tolerance) {
  const Eigen::Index n = 3 + 2 * static_cast<Eigen::Index>(map.segments.size());
  if (map.covariance.rows() != n || map.covariance.cols() != n) {
    return reject(RejectReason::kWrongSize, "LocalMapSnapshot.covariance: " + to_string(map.covariance.rows()) + " x " +
                                                to_string(map.covariance.cols()) + " for " +
                                                to_string(map.segments.size()) + " segments (n = " + to_string(n) + ")");
  }
  if (auto r = check_covariance(map.covariance, "LocalMapSnapshot.covariance", tolerance)) return *r;
  lmf::local_map_t msg;
  msg.utime = map.last_utime;
  msg.robot_id = map.robot_id;
  msg.seq = map.seq;
  msg.first_scan_utime = map.first_utime;
  msg.num_scans = static_cast<std::int32_t>(map.scan_poses.size());
  msg.robot = to_message(map.x_LR);
  msg.num_segments = static_cast<std::int32_t>(map.segments.size());
  msg.segments.reserve(map.segments.size());
  for (const SegmentEstimate& s : map.segments) {
    lmf::segment_t segment;
    segment.location = to_message(s.location);
    segment.length = static_cast<float>(s.length_m);
    msg.segments.push_back(segment);
  }
  msg.covariance = pack_upper_triangle(map.covariance);
  msg.num_covariance = static_cast<std::int32_t>(msg.covariance.size());
  msg.num_scan_poses = static_cast<std::int32_t>(map.scan_poses.size());
  msg.scan_utimes.reserve(map.scan_poses.size());
  msg.scan_poses.reserve(map.scan_poses.size());
  for (const ScanPose& pose : map.scan_poses) {
    msg.scan_utimes.push_back(pose.utime);
    msg.scan_poses.push_back(to_message(pose.x_LR));
  }
  // Everything else the receiver will check, checked here first.
  if (auto checked = from_message(msg, DecodeLimits{}); !checked) return checked.rejection();
  return msg;
}

// ---- corrected frames ---------------------------------------------------------------------

Checked<CorrectedFrames> from_message(const lmf::corrected_frames_t& msg, const DecodeLimits& limits) {
  if (msg.num_robots > limits.max_robots) {
    return reject(RejectReason::kOversized, "corrected_frames_t: " + to_string(msg.num_robots) + " robots > limit " +
                                                to_string(limits.max_robots));
  }
  const auto count = static_cast<std::size_t>(std::max(msg.num_robots, 0));
  if (msg.num_robots < 0 || msg.robot_ids.size() != count || msg.last_applied_seq.size() != count ||
      msg.frames.size() != count || msg.covariance.size() != count) {
    return reject(RejectReason::kWrongSize, "corrected_frames_t: arrays disagree with num_robots " +
                                                to_string(msg.num_robots));
  }
  if (auto r = check_nonnegative(msg.utime, "corrected_frames_t.utime")) return *r;
  if (auto r = check_nonnegative(msg.fusion_count, "corrected_frames_t.fusion_count")) return *r;
  CorrectedFrames out;
  out.utime = msg.utime;
  out.fusion_count = msg.fusion_count;
  std::set<int> seen;
  for (std::size_t i = 0; i < count; ++i) {
    const std::string what = "corrected_frames_t[" + to_string(i) + "]";
    fusion::CorrectedFrame frame;
    frame.robot_id = msg.robot_ids[i];
    if (auto r = check_nonnegative(frame.robot_id, what + ".robot_id")) return *r;
    if (!seen.insert(frame.robot_id).second) {
      return reject(RejectReason::kOutOfRange, what + ": robot " + to_string(frame.robot_id) + " listed twice");
    }
    // The wire names the last local map fused; the frame is where the next one begins.
    if (msg.last_applied_seq[i] < -1 || msg.last_applied_seq[i] == std::numeric_limits<std::int64_t>::max()) {
      return reject(RejectReason::kOutOfRange, what + ".last_applied_seq = " + to_string(msg.last_applied_seq[i]));
    }
    frame.map_seq = msg.last_applied_seq[i] + 1;
    auto pose = pose_from(msg.frames[i], what + ".frame", limits);
    if (!pose) return pose.rejection();
    frame.x_WL = pose.value();
    auto covariance = covariance3_from(msg.covariance[i].data(), msg.covariance[i].size(), what + ".covariance");
    if (!covariance) return covariance.rejection();
    frame.covariance = covariance.value();
    out.frames.push_back(frame);
  }
  return out;
}

Checked<lmf::corrected_frames_t> to_message(const CorrectedFrames& frames, const CovarianceTolerance& tolerance) {
  lmf::corrected_frames_t msg;
  msg.utime = frames.utime;
  msg.fusion_count = frames.fusion_count;
  msg.num_robots = static_cast<std::int32_t>(frames.frames.size());
  for (const fusion::CorrectedFrame& frame : frames.frames) {
    if (auto r = check_covariance(frame.covariance, "CorrectedFrame.covariance of robot " + to_string(frame.robot_id),
                                  tolerance)) {
      return *r;
    }
    if (frame.map_seq < 0) {
      return reject(RejectReason::kOutOfRange, "CorrectedFrame.map_seq = " + to_string(frame.map_seq) + " of robot " +
                                                   to_string(frame.robot_id));
    }
    msg.robot_ids.push_back(frame.robot_id);
    msg.last_applied_seq.push_back(frame.map_seq - 1);
    msg.frames.push_back(to_message(frame.x_WL));
    msg.covariance.push_back(pack_upper_triangle(frame.covariance));
  }
  if (auto checked = from_message(msg, DecodeLimits{}); !checked) return checked.rejection();
  return msg;
}

// ---- sighting ----------------------------------------------------------------------------------

Checked<fusion::RobotSighting> from_message(const lmf::sighting_t& msg, const DecodeLimits& limits) {
  if (auto r = check_nonnegative(msg.utime, "sighting_t.utime")) return *r;
  if (auto r = check_nonnegative(msg.observer_id, "sighting_t.observer_id")) return *r;
  if (auto r = check_nonnegative(msg.observed_id, "sighting_t.observed_id")) return *r;
  if (auto r = check_nonnegative(msg.observer_seq, "sighting_t.observer_seq")) return *r;
  if (auto r = check_nonnegative(msg.observed_seq, "sighting_t.observed_seq")) return *r;
  auto x_AB = pose_from(msg.relative, "sighting_t.relative", limits);
  if (!x_AB) return x_AB.rejection();
  auto x_LA = pose_from(msg.observer_in_local, "sighting_t.observer_in_local", limits);
  if (!x_LA) return x_LA.rejection();
  auto x_LB = pose_from(msg.observed_in_local, "sighting_t.observed_in_local", limits);
  if (!x_LB) return x_LB.rejection();
  auto cov_AB = covariance3_from(msg.covariance, 6, "sighting_t.covariance");
  if (!cov_AB) return cov_AB.rejection();
  auto cov_LA = covariance3_from(msg.observer_covariance, 6, "sighting_t.observer_covariance");
  if (!cov_LA) return cov_LA.rejection();
  auto cov_LB = covariance3_from(msg.observed_covariance, 6, "sighting_t.observed_covariance");
  if (!cov_LB) return cov_LB.rejection();
  fusion::RobotSighting out;
  out.utime = msg.utime;
  out.observer_id = msg.observer_id;
  out.observed_id = msg.observed_id;
  out.x_AB = x_AB.value();
  out.cov_AB = cov_AB.value();
  out.observer_seq = msg.observer_seq;
  out.x_LA = x_LA.value();
  out.cov_LA = cov_LA.value();
  out.observed_seq = msg.observed_seq;
  out.x_LB = x_LB.value();
  out.cov_LB = cov_LB.value();
  return out;
}

Checked<lmf::sighting_t> to_message(const fusion::RobotSighting& sighting, const CovarianceTolerance& tolerance) {
  if (auto r = check_covariance(sighting.cov_AB, "RobotSighting.cov_AB", tolerance)) return *r;
  if (auto r = check_covariance(sighting.cov_LA, "RobotSighting.cov_LA", tolerance)) return *r;
  if (auto r = check_covariance(sighting.cov_LB, "RobotSighting.cov_LB", tolerance)) return *r;
  lmf::sighting_t msg;
  msg.utime = sighting.utime;
  msg.observer_id = sighting.observer_id;
  msg.observed_id = sighting.observed_id;
  msg.relative = to_message(sighting.x_AB);
  const auto pack3 = [](const Eigen::Matrix3d& P, double* out) {
    const std::vector<double> packed = pack_upper_triangle(P);
    std::copy(packed.begin(), packed.end(), out);
  };
  pack3(sighting.cov_AB, msg.covariance);
  msg.observer_seq = sighting.observer_seq;
  msg.observer_in_local = to_message(sighting.x_LA);
  pack3(sighting.cov_LA, msg.observer_covariance);
  msg.observed_seq = sighting.observed_seq;
  msg.observed_in_local = to_message(sighting.x_LB);
  pack3(sighting.cov_LB, msg.observed_covariance);
  if (auto checked = from_message(msg, DecodeLimits{}); !checked) return checked.rejection();
  return msg;
}

// ---- acknowledgements ----------------------------------------------------------------------------

Checked<ScanAck> from_message(const lmf::scan_ack_t& msg, const DecodeLimits& limits) {
  if (auto r = check_nonnegative(msg.utime, "scan_ack_t.utime")) return *r;
  if (auto r = check_nonnegative(msg.robot_id, "scan_ack_t.robot_id")) return *r;
  if (auto r = check_nonnegative(msg.seq, "scan_ack_t.seq")) return *r;
  if (auto r = check_nonnegative(msg.local_map_seq, "scan_ack_t.local_map_seq")) return *r;
  auto x_LR = pose_from(msg.x_LR, "scan_ack_t.x_LR", limits);
  if (!x_LR) return x_LR.rejection();
  auto covariance = covariance3_from(msg.covariance, 6, "scan_ack_t.covariance");
  if (!covariance) return covariance.rejection();
  return ScanAck{msg.utime, msg.robot_id, msg.seq, msg.local_map_seq, x_LR.value(), covariance.value()};
}

Checked<lmf::scan_ack_t> to_message(const ScanAck& ack, const CovarianceTolerance& tolerance) {
  if (auto r = check_covariance(ack.covariance, "ScanAck.covariance", tolerance)) return *r;
  lmf::scan_ack_t msg;
  msg.utime = ack.utime;
  msg.robot_id = ack.robot_id;
  msg.seq = ack.seq;
  msg.local_map_seq = ack.local_map_seq;
  msg.x_LR = to_message(ack.x_LR);
  const std::vector<double> packed = pack_upper_triangle(ack.covariance);
  std::copy(packed.begin(), packed.end(), msg.covariance);
  if (auto checked = from_message(msg, DecodeLimits{}); !checked) return checked.rejection();
  return msg;
}

// ---- mission end -----------------------------------------------------------------------------------

Checked<MissionEnd> from_message(const lmf::mission_end_t& msg, const DecodeLimits& limits) {
  if (msg.num_robots > limits.max_robots) {
    return reject(RejectReason::kOversized, "mission_end_t: " + to_string(msg.num_robots) + " robots > limit " +
                                                to_string(limits.max_robots));
  }
  if (msg.num_robots < 0 || msg.robot_ids.size() != static_cast<std::size_t>(msg.num_robots)) {
    return reject(RejectReason::kWrongSize, "mission_end_t: num_robots " + to_string(msg.num_robots) + " but " +
                                                to_string(msg.robot_ids.size()) + " ids");
  }
  if (auto r = check_nonnegative(msg.utime, "mission_end_t.utime")) return *r;
  std::set<int> seen;
  for (std::size_t i = 0; i < msg.robot_ids.size(); ++i) {
    const std::string what = "mission_end_t.robot_ids[" + to_string(i) + "]";
    if (auto r = check_nonnegative(msg.robot_ids[i], what)) return *r;
    if (!seen.insert(msg.robot_ids[i]).second) {
      return reject(RejectReason::kOutOfRange, what + ": robot " + to_string(msg.robot_ids[i]) + " listed twice");
    }
  }
  return MissionEnd{msg.utime, std::vector<int>(msg.robot_ids.begin(), msg.robot_ids.end())};
}

Checked<lmf::mission_end_t> to_message(const MissionEnd& end) {
  lmf::mission_end_t msg;
  msg.utime = end.utime;
  msg.num_robots = static_cast<std::int32_t>(end.robot_ids.size());
  msg.robot_ids.assign(end.robot_ids.begin(), end.robot_ids.end());
  if (auto checked = from_message(msg, DecodeLimits{}); !checked) return checked.rejection();
  return msg;
}

Checked<LocalMapAck> from_message(const lmf::local_map_ack_t& msg, const DecodeLimits&) {
  if (auto r = check_nonnegative(msg.utime, "local_map_ack_t.utime")) return *r;
  if (auto r = check_nonnegative(msg.robot_id, "local_map_ack_t.robot_id")) return *r;
  if (auto r = check_nonnegative(msg.seq, "local_map_ack_t.seq")) return *r;
  if (msg.status != lmf::local_map_ack_t::FUSED && msg.status != lmf::local_map_ack_t::DUPLICATE &&
      msg.status != lmf::local_map_ack_t::QUEUED && msg.status != lmf::local_map_ack_t::RECEIVED) {
    return reject(RejectReason::kOutOfRange, "local_map_ack_t.status = " + to_string(msg.status));
  }
  return LocalMapAck{msg.utime, msg.robot_id, msg.seq, static_cast<LocalMapAck::Status>(msg.status)};
}

lmf::local_map_ack_t to_message(const LocalMapAck& ack) {
  lmf::local_map_ack_t msg;
  msg.utime = ack.utime;
  msg.robot_id = ack.robot_id;
  msg.seq = ack.seq;
  msg.status = static_cast<std::int8_t>(ack.status);
  return msg;
}

Checked<SightingAck> from_message(const lmf::sighting_ack_t& msg, const DecodeLimits&) {
  if (auto r = check_nonnegative(msg.utime, "sighting_ack_t.utime")) return *r;
  if (auto r = check_nonnegative(msg.observer_id, "sighting_ack_t.observer_id")) return *r;
  if (auto r = check_nonnegative(msg.observed_id, "sighting_ack_t.observed_id")) return *r;
  if (msg.status != lmf::sighting_ack_t::APPLIED && msg.status != lmf::sighting_ack_t::DUPLICATE &&
      msg.status != lmf::sighting_ack_t::REJECTED && msg.status != lmf::sighting_ack_t::RECEIVED) {
    return reject(RejectReason::kOutOfRange, "sighting_ack_t.status = " + to_string(msg.status));
  }
  return SightingAck{msg.utime, msg.observer_id, msg.observed_id, static_cast<SightingAck::Status>(msg.status)};
}

lmf::sighting_ack_t to_message(const SightingAck& ack) {
  lmf::sighting_ack_t msg;
  msg.utime = ack.utime;
  msg.observer_id = ack.observer_id;
  msg.observed_id = ack.observed_id;
  msg.status = static_cast<std::int8_t>(ack.status);
  return msg;
}

// ---- status and map summary --------------------------------------------------------------

namespace {

// The (reason, count) pairs of a status; the strings were checked by precheck.
Checked<RejectCounts> reject_counts_from(const std::vector<std::string>& reasons,
                                         const std::vector<std::int64_t>& counts, std::string_view what) {
  if (reasons.size() != counts.size()) {
    return reject(RejectReason::kWrongSize, std::string(what) + ": " + to_string(reasons.size()) + " reasons but " +
                                                to_string(counts.size()) + " counts");
  }
  RejectCounts out;
  out.reserve(reasons.size());
  for (std::size_t i = 0; i < reasons.size(); ++i) {
    if (auto r = check_nonnegative(counts[i], std::string(what) + ".reject_counts[" + to_string(i) + "]")) return *r;
    out.emplace_back(reasons[i], counts[i]);
  }
  return out;
}

template <class Msg>
void put_reject_counts(const RejectCounts& rejects, Msg& msg) {
  for (const auto& [reason, count] : rejects) {
    msg.reject_reasons.push_back(reason);
    msg.reject_counts.push_back(count);
  }
  msg.num_reject_reasons = static_cast<std::int32_t>(msg.reject_reasons.size());
}

// v as a float; beyond float's range +-infinity (which from_message refuses),
// not the undefined behaviour of a plain cast.
float to_float(double v) {
  constexpr double kMax = std::numeric_limits<float>::max();
  if (v > kMax) return std::numeric_limits<float>::infinity();
  if (v < -kMax) return -std::numeric_limits<float>::infinity();
  return static_cast<float>(v);
}

// A duration or a time statistic: finite and >= 0.
std::optional<Rejection> check_duration(double ms, std::string_view what) {
  if (auto r = check_finite(ms, what)) return r;
  if (ms < 0.0) return reject(RejectReason::kOutOfRange, std::string(what) + " = " + to_string(ms) + " < 0");
  return std::nullopt;
}

}  // namespace

Checked<AgentStatus> from_message(const lmf::agent_status_t& msg, const DecodeLimits& limits) {
  const std::pair<const char*, std::int64_t> counts[] = {
      {"agent_status_t.utime", msg.utime}, {"agent_status_t.robot_id", msg.robot_id},
      {"agent_status_t.scans", msg.scans}, {"agent_status_t.local_map_segments", msg.local_map_segments},
      {"agent_status_t.maps_shipped", msg.maps_shipped}, {"agent_status_t.maps_acknowledged", msg.maps_acknowledged},
      {"agent_status_t.window_scans", msg.window_scans}};
  for (const auto& [what, value] : counts) {
    if (auto r = check_nonnegative(value, what)) return *r;
  }
  if (auto r = check_duration(msg.scan_time_p50_ms, "agent_status_t.scan_time_p50_ms")) return *r;
  if (auto r = check_duration(msg.scan_time_p99_ms, "agent_status_t.scan_time_p99_ms")) return *r;
  if (auto r = check_duration(msg.scan_time_max_ms, "agent_status_t.scan_time_max_ms")) return *r;
  auto x_WR = pose_from(msg.global_pose, "agent_status_t.global_pose", limits);
  if (!x_WR) return x_WR.rejection();
  auto odometry = from_message(msg.odometry_model, limits);
  if (!odometry) return odometry.rejection();
  auto rejects = reject_counts_from(msg.reject_reasons, msg.reject_counts, "agent_status_t");
  if (!rejects) return rejects.rejection();
  AgentStatus s;
  s.utime = msg.utime;
  s.robot_id = msg.robot_id;
  s.joined = msg.joined;
  s.scans = msg.scans;
  s.local_map_segments = msg.local_map_segments;
  s.maps_shipped = msg.maps_shipped;
  s.maps_acknowledged = msg.maps_acknowledged;
  s.scan_time_p50_ms = msg.scan_time_p50_ms;
  s.scan_time_p99_ms = msg.scan_time_p99_ms;
  s.scan_time_max_ms = msg.scan_time_max_ms;
  s.window_scans = msg.window_scans;
  s.covariance_ok = msg.covariance_ok;
  s.x_WR = x_WR.value();
  s.odometry = odometry.value();
  s.mission_done = msg.mission_done;
  s.rejects = std::move(rejects).value();
  return s;
}

Checked<lmf::agent_status_t> to_message(const AgentStatus& s) {
  lmf::agent_status_t msg;
  msg.utime = s.utime;
  msg.robot_id = s.robot_id;
  msg.joined = s.joined;
  msg.scans = s.scans;
  msg.local_map_segments = s.local_map_segments;
  msg.maps_shipped = s.maps_shipped;
  msg.maps_acknowledged = s.maps_acknowledged;
  msg.scan_time_p50_ms = to_float(s.scan_time_p50_ms);
  msg.scan_time_p99_ms = to_float(s.scan_time_p99_ms);
  msg.scan_time_max_ms = to_float(s.scan_time_max_ms);
  msg.window_scans = s.window_scans;
  msg.covariance_ok = s.covariance_ok;
  msg.global_pose = to_message(s.x_WR);
  msg.odometry_model = to_message(s.odometry);
  msg.mission_done = s.mission_done;
  put_reject_counts(s.rejects, msg);
  if (auto checked = from_message(msg, DecodeLimits{}); !checked) return checked.rejection();
  return msg;
}

Checked<ServerStatus> from_message(const lmf::server_status_t& msg, const DecodeLimits&) {
  const std::pair<const char*, std::int64_t> counts[] = {
      {"server_status_t.utime", msg.utime}, {"server_status_t.num_robots_joined", msg.num_robots_joined},
      {"server_status_t.num_segments", msg.num_segments}, {"server_status_t.num_submaps", msg.num_submaps},
      {"server_status_t.num_graph_edges", msg.num_graph_edges}, {"server_status_t.fusions", msg.fusions},
      {"server_status_t.queue_length", msg.queue_length}};
  for (const auto& [what, value] : counts) {
    if (auto r = check_nonnegative(value, what)) return *r;
  }
  if (auto r = check_duration(msg.last_fusion_ms, "server_status_t.last_fusion_ms")) return *r;
  if (auto r = check_duration(msg.mean_fusion_ms, "server_status_t.mean_fusion_ms")) return *r;
  if (auto r = check_finite(msg.min_eigenvalue, "server_status_t.min_eigenvalue")) return *r;
  auto rejects = reject_counts_from(msg.reject_reasons, msg.reject_counts, "server_status_t");
  if (!rejects) return rejects.rejection();
  ServerStatus s;
  s.utime = msg.utime;
  s.robots_joined = msg.num_robots_joined;
  s.segments = msg.num_segments;
  s.submaps = msg.num_submaps;
  s.graph_edges = msg.num_graph_edges;
  s.fusions = msg.fusions;
  s.last_fusion_ms = msg.last_fusion_ms;
  s.mean_fusion_ms = msg.mean_fusion_ms;
  s.queue_length = msg.queue_length;
  s.covariance_ok = msg.covariance_ok;
  s.min_eigenvalue = msg.min_eigenvalue;
  s.rejects = std::move(rejects).value();
  return s;
}

Checked<lmf::server_status_t> to_message(const ServerStatus& s) {
  lmf::server_status_t msg;
  msg.utime = s.utime;
  msg.num_robots_joined = s.robots_joined;
  msg.num_segments = s.segments;
  msg.num_submaps = s.submaps;
  msg.num_graph_edges = s.graph_edges;
  msg.fusions = s.fusions;
  msg.last_fusion_ms = to_float(s.last_fusion_ms);
  msg.mean_fusion_ms = to_float(s.mean_fusion_ms);
  msg.queue_length = s.queue_length;
  msg.covariance_ok = s.covariance_ok;
  msg.min_eigenvalue = to_float(s.min_eigenvalue);
  put_reject_counts(s.rejects, msg);
  if (auto checked = from_message(msg, DecodeLimits{}); !checked) return checked.rejection();
  return msg;
}

Checked<GlobalMapSummary> from_message(const lmf::global_map_t& msg, const DecodeLimits& limits) {
  if (msg.num_segments < 0 || msg.endpoints.size() != static_cast<std::size_t>(msg.num_segments)) {
    return reject(RejectReason::kWrongSize, "global_map_t: num_segments " + to_string(msg.num_segments) + " but " +
                                                to_string(msg.endpoints.size()) + " end point rows");
  }
  if (auto r = check_nonnegative(msg.utime, "global_map_t.utime")) return *r;
  if (auto r = check_nonnegative(msg.fusion_count, "global_map_t.fusion_count")) return *r;
  if (auto r = check_nonnegative(msg.num_submaps, "global_map_t.num_submaps")) return *r;
  if (auto r = check_nonnegative(msg.num_graph_edges, "global_map_t.num_graph_edges")) return *r;
  GlobalMapSummary map;
  map.utime = msg.utime;
  map.fusion_count = msg.fusion_count;
  map.submaps = msg.num_submaps;
  map.graph_edges = msg.num_graph_edges;
  map.endpoints.reserve(msg.endpoints.size());
  for (std::size_t i = 0; i < msg.endpoints.size(); ++i) {
    if (msg.endpoints[i].size() != 4) {
      return reject(RejectReason::kWrongSize, "global_map_t.endpoints[" + to_string(i) + "]: " +
                                                  to_string(msg.endpoints[i].size()) + " values, expected 4");
    }
    std::array<double, 4> e{};
    for (std::size_t k = 0; k < 4; ++k) {
      const std::string what = "global_map_t.endpoints[" + to_string(i) + "][" + to_string(k) + "]";
      if (auto r = check_finite(msg.endpoints[i][k], what)) return *r;
      if (std::abs(msg.endpoints[i][k]) > limits.max_coordinate_m) {
        return reject(RejectReason::kOutOfRange, what + " = " + to_string(msg.endpoints[i][k]) + " m beyond " +
                                                     to_string(limits.max_coordinate_m) + " m");
      }
      e[k] = msg.endpoints[i][k];
    }
    map.endpoints.push_back(e);
  }
  return map;
}

Checked<lmf::global_map_t> to_message(const GlobalMapSummary& map) {
  lmf::global_map_t msg;
  msg.utime = map.utime;
  msg.fusion_count = map.fusion_count;
  msg.num_submaps = map.submaps;
  msg.num_graph_edges = map.graph_edges;
  msg.num_segments = static_cast<std::int32_t>(map.endpoints.size());
  msg.endpoints.reserve(map.endpoints.size());
  for (const auto& e : map.endpoints) {
    msg.endpoints.push_back({to_float(e[0]), to_float(e[1]), to_float(e[2]),
                             to_float(e[3])});
  }
  if (auto checked = from_message(msg, DecodeLimits{}); !checked) return checked.rejection();
  return msg;
}

}  // namespace lmf::runtime

// lcm-gen declares message constants as `static const` members with an
// initializer but no definition. Code that binds one to a reference (gtest's
// EXPECT_EQ, a std::tuple built from it) odr-uses it and needs this
// definition: optimised builds fold it away, the sanitizer build does not
// link without it. Every user of the messages links lmf::runtime.
namespace lmf {
const std::int8_t local_map_ack_t::FUSED;
const std::int8_t local_map_ack_t::DUPLICATE;
const std::int8_t local_map_ack_t::QUEUED;
const std::int8_t local_map_ack_t::RECEIVED;
const std::int8_t sighting_ack_t::APPLIED;
const std::int8_t sighting_ack_t::DUPLICATE;
const std::int8_t sighting_ack_t::REJECTED;
const std::int8_t sighting_ack_t::RECEIVED;
}  // namespace lmf
