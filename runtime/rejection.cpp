#include "runtime/rejection.hpp"

#include <iostream>

namespace lmf::runtime {

std::string_view reason_name(RejectReason reason) {
  switch (reason) {
    case RejectReason::kDecodeFailed: return "decode_failed";
    case RejectReason::kOversized: return "oversized";
    case RejectReason::kNonFinite: return "non_finite";
    case RejectReason::kWrongSize: return "wrong_size";
    case RejectReason::kCovarianceNotSymmetric: return "covariance_not_symmetric";
    case RejectReason::kCovarianceNotPsd: return "covariance_not_psd";
    case RejectReason::kBadAngle: return "bad_angle";
    case RejectReason::kOutOfRange: return "out_of_range";
    case RejectReason::kUnknownRobot: return "unknown_robot";
    case RejectReason::kStaleSequence: return "stale_sequence";
    case RejectReason::kHandlerError: return "handler_error";
    case RejectReason::kAuthMissing: return "auth_missing";
    case RejectReason::kAuthBadTag: return "auth_bad_tag";
    case RejectReason::kAuthReplayed: return "auth_replayed";
    case RejectReason::kAuthUnknownSender: return "auth_unknown_sender";
    case RejectReason::kAuthNotAllowed: return "auth_not_allowed";
  }
  return "unknown_reason";
}

std::string Rejection::describe() const {
  std::string text(reason_name(reason));
  if (!detail.empty()) text += ": " + detail;
  return text;
}

namespace {
// 1..10, then 20, 30, ... 100, then 200, 300, ...: one line per decade step.
bool should_log(std::int64_t n) {
  std::int64_t step = 1;
  while (n > 10 * step) step *= 10;
  return n % step == 0;
}
}  // namespace

void RejectCounter::add(RejectReason reason) { ++counts_[static_cast<std::size_t>(reason)]; }

void RejectCounter::merge(const RejectCounter& other) {
  for (std::size_t i = 0; i < kNumRejectReasons; ++i) counts_[i] += other.counts_[i];
}

void RejectCounter::record(const Rejection& rejection, std::string_view source) {
  add(rejection.reason);
  const std::int64_t n = count(rejection.reason);
  if (should_log(n)) {
    std::cerr << source << ": rejected " << rejection.describe() << " (" << reason_name(rejection.reason)
              << " #" << n << ")\n";
  }
}

std::int64_t RejectCounter::count(RejectReason reason) const {
  return counts_[static_cast<std::size_t>(reason)];
}

std::int64_t RejectCounter::total() const {
  std::int64_t sum = 0;
  for (const std::int64_t c : counts_) sum += c;
  return sum;
}

std::vector<std::pair<std::string, std::int64_t>> RejectCounter::nonzero() const {
  std::vector<std::pair<std::string, std::int64_t>> out;
  for (std::size_t i = 0; i < kNumRejectReasons; ++i) {
    if (counts_[i] != 0) out.emplace_back(std::string(reason_name(static_cast<RejectReason>(i))), counts_[i]);
  }
  return out;
}

}  // namespace lmf::runtime
