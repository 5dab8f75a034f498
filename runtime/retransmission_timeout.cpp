#include "runtime/retransmission_timeout.hpp"

#include <algorithm>
#include <stdexcept>

namespace lmf::runtime {

void RetransmissionConfig::validate() const {
  if (min.count() <= 0) throw std::invalid_argument("retransmission min must be > 0 ms");
  if (max < min) throw std::invalid_argument("retransmission max must be >= min");
  if (initial.count() <= 0) throw std::invalid_argument("retransmission initial must be > 0 ms");
}

RetransmissionTimeout::RetransmissionTimeout(RetransmissionConfig config) : config_(config) { config_.validate(); }

void RetransmissionTimeout::on_round_trip(Duration round_trip) {
  if (round_trip < Duration::zero()) return;
  if (!srtt_) {  // RFC 6298 (2.2)
    srtt_ = round_trip;
    rttvar_ = round_trip / 2;
    return;
  }
  const Duration error = *srtt_ > round_trip ? *srtt_ - round_trip : round_trip - *srtt_;  // (2.3)
  rttvar_ = (3 * rttvar_ + error) / 4;
  srtt_ = (7 * *srtt_ + round_trip) / 8;
}

RetransmissionTimeout::Duration RetransmissionTimeout::timeout(int sends) const {
  const Duration max = config_.max;
  const Duration first = srtt_ ? Duration(*srtt_ + 4 * rttvar_) : Duration(config_.initial);
  Duration rto = std::clamp<Duration>(first, config_.min, max);
  for (int i = 1; i < sends && rto < max; ++i) rto = std::min(2 * rto, max);  // (5.5)
  return rto;
}

}  // namespace lmf::runtime
