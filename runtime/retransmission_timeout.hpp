// How long to wait for an answer before sending again, learned from the
// answers (the smoothed round trip of RFC 6298). The player's lockstep scans
// and sightings and the agent's local maps use it (docs/reliability.md). It waits
//
//   RTO = clamp(SRTT + 4 RTTVAR, min, max),  SRTT ← 7/8 SRTT + 1/8 R,
//                                             RTTVAR ← 3/4 RTTVAR + 1/4 |SRTT − R|,
//
// after a first send, doubled after each further send of the same message
// (backoff) and never beyond `max`. Before the first answer it waits
// `initial` (clamped to [min, max]), backed off the same way: a lost first
// message then costs a fraction of a second rather than `max`, while a peer
// that is not up yet is asked less and less often. The default, 200 ms, is
// the floor Linux puts under TCP's RTO: far above a LAN's round trip, and a
// resend that crosses a late first answer only costs a duplicate the
// receiver answers again.
// Only answers to a message sent once are samples (Karn's rule: an answer
// after a resend may answer either send). On loopback, where an answer takes
// a millisecond, a lost datagram then costs a few milliseconds, not `max`.
// Pure and synchronous; the caller measures R.
#pragma once

#include <chrono>
#include <optional>

namespace lmf::runtime {

struct RetransmissionConfig {
  std::chrono::milliseconds min{10};    // > 0: the shortest wait (scheduling noise, a slow peer)
  std::chrono::milliseconds max{2000};  // >= min: the longest wait
  std::chrono::milliseconds initial{200};  // > 0: the first wait before any answer, clamped to [min, max]
  // Throws std::invalid_argument naming the bad field.
  void validate() const;
};

class RetransmissionTimeout {
 public:
  using Duration = std::chrono::steady_clock::duration;

  // Throws std::invalid_argument for a bad config.
  explicit RetransmissionTimeout(RetransmissionConfig config);

  // R: the time from the (only) send of a message to its answer. Negative
  // samples are ignored.
  void on_round_trip(Duration round_trip);

  // The wait after the `sends`-th send (>= 1) of one message.
  Duration timeout(int sends) const;

  std::optional<Duration> smoothed_round_trip() const { return srtt_; }
  const RetransmissionConfig& config() const { return config_; }

 private:
  RetransmissionConfig config_;
  std::optional<Duration> srtt_;
  Duration rttvar_{0};
};

}  // namespace lmf::runtime
