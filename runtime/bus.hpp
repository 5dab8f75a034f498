// The message bus of an lmf process: a thin owner of one lcm::LCM (STYLE
// "bus behind an interface"). Process logic takes a Bus&, so a test wires
// agent, server and player to ONE Bus built on "memq://" (memq is private to
// its LCM instance), while the processes use the network URL (by default
// LCM_DEFAULT_URL, else LCM's udpm://239.255.76.67:7667?ttl=0), and a monitor
// can read an lcm-logger file with "file:///path/to/log?speed=0".
//
// Handlers run inside handle_pending(), on the caller's thread. Nothing thrown
// by a handler crosses LCM's C callback: it is caught, counted
// (handler_error), logged to stderr and the message dropped.
//
// Authentication (runtime/auth.hpp), optional: with an auth::Config the Bus
// appends a signed trailer to every message it publishes, and verifies (tag,
// replay window, who may say what) every message it receives BEFORE a handler
// sees it; a message that fails is counted in rejects() under an auth_*
// reason, logged rate-limited and dropped. Handlers always get the bare LCM
// encoding. Without a Config nothing is signed or checked, and a signed
// message's trailer is removed unverified (a keyless listener still reads a
// secured system).
//
// Simulated loss (tests, SimulatedLoss): a Bus can be made to lose or
// duplicate what it publishes, as a lossy network would, from a seeded
// generator (the same publishes give the same losses). The sender is not told
// (publish still returns true), like a UDP datagram lost on the way.
//
// Threading: use a Bus from one thread (the event loop's). Do not subscribe or
// unsubscribe from inside a handler.
#pragma once

#include <cstddef>
#include <cstdint>
#include <functional>
#include <memory>
#include <optional>
#include <random>
#include <span>
#include <string>
#include <string_view>
#include <vector>

#include <lcm/lcm-cpp.hpp>

#include "runtime/auth.hpp"
#include "runtime/convert.hpp"
#include "runtime/rejection.hpp"

namespace lmf::runtime {

// A lossy, duplicating link for tests: each publish is lost with probability
// `drop`; one that is not is sent twice with probability `duplicate`.
struct SimulatedLoss {
  double drop = 0.0;       // [0, 1)
  double duplicate = 0.0;  // [0, 1)
  std::uint64_t seed = 1;
  // Throws std::invalid_argument for a probability outside [0, 1).
  void validate() const;
};

class Bus {
 public:
  // Raw bytes of one message on `channel`; valid only during the call.
  using RawHandler = std::function<void(const std::string& channel, const void* data, std::size_t size)>;

  // Empty url: LCM_DEFAULT_URL or LCM's default. Check good() afterwards: a bad
  // URL or a network without a multicast route gives a Bus that is not good.
  // `auth`: sign and verify (throws std::invalid_argument if it is not valid);
  // sequence numbers start at the wall clock in microseconds.
  explicit Bus(const std::string& url = "", std::optional<auth::Config> auth = std::nullopt);
  // Another endpoint on `network`'s LCM instance with its own authentication
  // (or none), subscriptions and rejects: for tests where several principals
  // share one memq:// "network" in one process. handle_pending() of any of them
  // dispatches to all; the LCM lives until the last of them is destroyed.
  Bus(Bus& network, std::optional<auth::Config> auth);
  // With authentication, writes one summary line to stderr (what was verified and rejected).
  ~Bus();
  Bus(const Bus&) = delete;
  Bus& operator=(const Bus&) = delete;

  bool good() const { return lcm_->good(); }
  const std::string& url() const { return url_; }

  // Encodes, signs if authenticated, and sends; false (and counted in
  // publish_failures()) if LCM refused.
  template <class Msg>
  bool publish(const std::string& channel, const Msg& msg) {
    return publish_raw(channel, encode_message(msg));
  }
  bool publish_raw(const std::string& channel, const std::vector<std::uint8_t>& bytes);

  // Subscribes to every channel matching the LCM regex `channel` (anchored).
  // The returned id stays valid until unsubscribe() or the Bus dies.
  int subscribe(const std::string& channel, RawHandler handler);

  // Subscribes and decodes into Msg before calling `on_message`; a message
  // that does not decode is recorded in rejects() and logged, never delivered.
  template <class Msg>
  int subscribe_message(const std::string& channel,
                        std::function<void(const std::string& channel, const Msg& msg)> on_message,
                        const DecodeLimits& limits = {}) {
    return subscribe(channel, [this, on_message = std::move(on_message), limits](
                                  const std::string& ch, const void* data, std::size_t size) {
      auto msg = decode_message<Msg>(data, size, limits);
      if (!msg) {
        rejects_.record(msg.rejection(), ch);
        return;
      }
      on_message(ch, msg.value());
    });
  }

  void unsubscribe(int subscription_id);

  // Dispatches the messages already queued, never blocking; stops after
  // `max_messages`. Returns how many were dispatched (negative on an LCM error).
  int handle_pending(int max_messages = 1000);

  // The descriptor that becomes readable when a message is queued (a pipe for
  // memq:// in LCM 1.3.1); -1 if the provider has none. Owned by LCM.
  int fileno();

  // Authentication and decode failures from subscribe_message and handler errors, by reason.
  RejectCounter& rejects() { return rejects_; }
  const RejectCounter& rejects() const { return rejects_; }
  std::int64_t handler_errors() const { return rejects_.count(RejectReason::kHandlerError); }
  std::int64_t publish_failures() const { return publish_failures_; }

  // The principal this Bus signs as, if authenticated.
  const std::string* identity() const { return signer_ ? &signer_->principal() : nullptr; }
  bool authenticated() const { return verifier_ != nullptr; }
  // Messages that passed verification (0 without authentication).
  std::int64_t messages_verified() const { return verifier_ ? verifier_->verified() : 0; }
  // A restarted receiver's persisted state: refuses every message up to each
  // sender's mark (auth::Verifier::refuse_through). No-op without authentication.
  void refuse_through(const auth::HighWater& high_water);

  // From now on loses and duplicates what this Bus publishes (tests).
  void simulate_loss(const SimulatedLoss& loss);
  std::int64_t publishes_dropped() const { return publishes_dropped_; }        // by simulate_loss
  std::int64_t publishes_duplicated() const { return publishes_duplicated_; }  // by simulate_loss

  // Inside a handler: the message being handled as it arrived, authentication
  // trailer included (the handler's bytes are its prefix). Empty elsewhere.
  std::span<const std::uint8_t> message_as_received() const { return as_received_; }

  // The underlying LCM instance, for what the Bus does not wrap (e.g. queue
  // capacity). Bypasses authentication both ways.
  lcm::LCM& lcm() { return *lcm_; }

 private:
  struct Subscription;
  static void dispatch(const lcm::ReceiveBuffer* buffer, const std::string& channel, Subscription* subscription);

  void configure_auth(std::optional<auth::Config> auth);

  std::string url_;
  std::shared_ptr<lcm::LCM> lcm_;
  std::unique_ptr<auth::Signer> signer_;
  std::unique_ptr<auth::Verifier> verifier_;
  std::vector<std::uint8_t> signed_;  // reused buffer: payload + trailer
  std::span<const std::uint8_t> as_received_;  // set while a handler runs
  std::uint64_t first_seq_ = 0;
  std::vector<std::unique_ptr<Subscription>> subscriptions_;
  int next_id_ = 1;
  RejectCounter rejects_;
  std::int64_t publish_failures_ = 0;
  std::optional<SimulatedLoss> loss_;
  std::mt19937_64 loss_rng_;
  std::int64_t publishes_dropped_ = 0;
  std::int64_t publishes_duplicated_ = 0;
};

}  // namespace lmf::runtime
