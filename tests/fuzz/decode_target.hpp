// The body shared by the decode<Core> targets: bytes -> runtime::decode<Core>
// (wire prechecks, lcm-gen decoder, field validation) and, for accepted input,
// the round trip every receiver relies on: the value re-encodes (to_message
// accepts it) and decodes to the identical value.
#pragma once

#include <cstddef>
#include <cstdint>
#include <string>
#include <type_traits>

#include "fuzz_support.hpp"
#include "runtime/convert.hpp"
#include "runtime/rejection.hpp"

namespace lmf::fuzz {

// to_message() returns Checked<Msg> for types that carry a covariance, Msg otherwise.
template <class T>
struct IsChecked : std::false_type {};
template <class T>
struct IsChecked<runtime::Checked<T>> : std::true_type {};

inline void check_rejection(const runtime::Rejection& r, std::string_view where) {
  if (static_cast<std::size_t>(r.reason) >= runtime::kNumRejectReasons) {
    fail(std::string(where) + ": rejection with an unknown reason code");
  }
  if (r.detail.empty()) fail(std::string(where) + ": rejection without a detail");
}

// Covariances in accepted values must really be symmetric PSD (an
// independent check of runtime::check_covariance).
inline void check_covariance_accepted(const Eigen::MatrixXd& P, const std::string& what) {
  if (const std::string v = covariance_violation(P); !v.empty()) fail(what + ": an accepted covariance is " + v);
}
inline void check_accepted(const LocalMapSnapshot& m) { check_covariance_accepted(m.covariance, "local_map_t"); }
inline void check_accepted(const runtime::CorrectedFrames& f) {
  for (const auto& frame : f.frames) check_covariance_accepted(frame.covariance, "corrected_frames_t");
}
inline void check_accepted(const fusion::RobotSighting& s) {
  check_covariance_accepted(s.cov_AB, "sighting_t.covariance");
  check_covariance_accepted(s.cov_LA, "sighting_t.observer_covariance");
  check_covariance_accepted(s.cov_LB, "sighting_t.observed_covariance");
}
inline void check_accepted(const runtime::ScanAck& a) { check_covariance_accepted(a.covariance, "scan_ack_t"); }
template <class Core>
void check_accepted(const Core&) {}

template <class Core>
int fuzz_decode(const std::uint8_t* data, std::size_t size) {
  using Msg = typename runtime::MessageOf<Core>::type;
  const std::string name = Msg::getTypeName();
  const runtime::Checked<Core> decoded = runtime::decode<Core>(data, size);
  if (!decoded) {
    check_rejection(decoded.rejection(), name);
    note_outcome(runtime::reason_name(decoded.rejection().reason));
    return 0;
  }
  check_accepted(decoded.value());
  const auto message = runtime::to_message(decoded.value());
  Msg again_message;
  if constexpr (IsChecked<std::decay_t<decltype(message)>>::value) {
    if (!message) fail(name + ": an accepted value does not re-encode: " + message.rejection().describe());
    again_message = message.value();
  } else {
    again_message = message;
  }
  const Bytes bytes = runtime::encode_message(again_message);
  const runtime::Checked<Core> again = runtime::decode<Core>(bytes.data(), bytes.size());
  if (!again) fail(name + ": a re-encoded accepted value is rejected: " + again.rejection().describe());
  if (const std::string d = difference(decoded.value(), again.value()); !d.empty()) {
    fail(name + ": the round trip changed the value: " + d);
  }
  note_outcome("accepted");
  return 0;
}

}  // namespace lmf::fuzz
