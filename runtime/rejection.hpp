// Why an incoming message was refused, and how often (docs/design.md §8).
//
// Every decode and every conversion in runtime/convert.hpp returns a Checked<T>:
// either the value or a Rejection with a stable reason code. Processes count
// rejections per reason in a RejectCounter and publish the counts in their
// status messages, so the reason names below are part of the status format:
// never rename one, only add.
//
// Threading: none of these types is synchronised; each process uses them from
// its event-loop thread.
#pragma once

#include <array>
#include <cstddef>
#include <cstdint>
#include <string>
#include <string_view>
#include <utility>
#include <variant>
#include <vector>

namespace lmf::runtime {

enum class RejectReason : std::uint8_t {
  kDecodeFailed,             // bad fingerprint, truncated or malformed bytes
  kOversized,                // more bytes, beams, segments or robots than the limits allow
  kNonFinite,                // NaN or infinity in a number
  kWrongSize,                // array count mismatch (e.g. covariance count != n(n+1)/2)
  kCovarianceNotSymmetric,   // |P - Pᵀ| beyond tolerance (only a sender can see this)
  kCovarianceNotPsd,         // an eigenvalue below -tolerance (found by an LDLᵀ test)
  kBadAngle,                 // an angle outside (-pi, pi] or a non-positive beam step
  kOutOfRange,               // a value outside its domain (negative id, range, length, ...)
  kUnknownRobot,             // decided by the caller: a robot it does not know
  kStaleSequence,            // decided by the caller: a replayed or old sequence number
  kHandlerError,             // a subscription handler threw; the message was dropped
  // Authentication (runtime/auth.hpp), only when the Bus has keys:
  kAuthMissing,              // no (well-formed) authentication trailer
  kAuthBadTag,               // the HMAC does not match: forged, corrupted or signed with another key
  kAuthReplayed,             // a sequence number already seen or older than the replay window
  kAuthUnknownSender,        // signed by a principal whose key this process does not hold
  kAuthNotAllowed,           // an authentic sender saying what it may not (robot1 sending robot 2's map)
};
inline constexpr std::size_t kNumRejectReasons = 16;

// Stable lower_snake names ("decode_failed", "covariance_not_psd", ...).
std::string_view reason_name(RejectReason reason);

struct Rejection {
  RejectReason reason = RejectReason::kDecodeFailed;
  std::string detail;  // what and where, for logs ("local_map_t.covariance: 14 values for n = 5")
  std::string describe() const;  // "<reason>: <detail>"
};

// Either a value or the reason it was refused.
template <class T>
class Checked {
 public:
  Checked(T value) : state_(std::move(value)) {}          // NOLINT: implicit on purpose
  Checked(Rejection rejection) : state_(std::move(rejection)) {}  // NOLINT

  bool ok() const { return state_.index() == 0; }
  explicit operator bool() const { return ok(); }

  // Calling value() on a rejection (or rejection() on a value) is a programming
  // error: std::get throws std::bad_variant_access.
  const T& value() const& { return std::get<0>(state_); }
  T& value() & { return std::get<0>(state_); }
  T&& value() && { return std::get<0>(std::move(state_)); }
  const Rejection& rejection() const { return std::get<1>(state_); }

 private:
  std::variant<T, Rejection> state_;
};

// Rejections per reason, for status messages; logs to stderr with a rate limit
// (the first 10 of each reason, then every 10th, 100th, ... one) so a flood of
// bad input cannot flood the log.
class RejectCounter {
 public:
  // Counts one rejection and maybe logs "<source>: rejected <reason>: <detail>".
  void record(const Rejection& rejection, std::string_view source);
  // Counts without logging.
  void add(RejectReason reason);
  // Adds every count of `other` (a node's own refusals plus its Bus's).
  void merge(const RejectCounter& other);

  std::int64_t count(RejectReason reason) const;
  std::int64_t total() const;
  // (name, count) of every reason with a non-zero count, in enum order.
  std::vector<std::pair<std::string, std::int64_t>> nonzero() const;

 private:
  std::array<std::int64_t, kNumRejectReasons> counts_{};
};

}  // namespace lmf::runtime
