// Optional authenticated messages: who may say what on the
// bus, and proof that they said it.
//
// Every process holds a keys file: the 32-byte key of the principal it signs
// as, and the keys of the principals it accepts messages from. A signed
// message is the LCM encoding, untouched (so lcm-spy, lcm-logger and every
// lcm-gen decoder still read it: they ignore trailing bytes), followed by a
// trailer
//
//   principal (n bytes) | n (u8) | seq (u64) | tag (32 bytes) | version (u8) | "LMFA"
//
// read from the end. Integers are big-endian like LCM's. The tag is
// HMAC-SHA256 under the sender's key over the channel name, the payload, the
// principal and seq (each length-prefixed, after a version label), so a
// message cannot be moved to another channel, altered, or attributed to
// another sender without the key.
//
// Sequence numbers are per sender and strictly increasing, also across
// restarts: a Signer starts at the wall clock in microseconds and adds one per
// message (a restarted process starts above everything it sent before unless
// it averaged more than one message per microsecond or its clock was set
// back). A receiver keeps, per principal, a sliding window of the last
// `replay_window` sequence numbers (like IPsec/DTLS): reordering within the
// window is accepted, a repeat or anything older is refused. A receiver that
// restarts can be given the highest number it took from each sender before
// (its HighWater, which a server persists with its state): everything up to
// it is then refused, so a message captured before the restart cannot be
// replayed after it. A sender never reuses a number (a resend is signed anew),
// so this refuses nothing an honest sender still has to say.
//
// Authorization: the verified sender must be allowed to say what the message
// says, decided from the LCM type fingerprint at the start of the payload:
//   local_map_t, scan_ack_t, agent_status_t          only robot<N> with robot_id == N
//   local_map_ack_t, sighting_ack_t,
//   corrected_frames_t, global_map_t, server_status_t only server
//   laser_scan_t, sighting_t, mission_end_t          only player
//   anything else                                    nobody
//
// What this protects: integrity and origin of every message, freshness against
// replays. Not: confidentiality (payloads are in clear), availability (a
// flood is rejected but still costs a HMAC per message), nor a holder of a key
// forging its owner: HMAC keys are symmetric, so the server, player and monitor,
// which verify robots' messages, could also forge them; robots hold no other
// robot's key, so a robot cannot publish as another robot.
//
// Failure kinds: a malformed keys file or configuration throws
// std::invalid_argument naming file and line; a message that fails a check is
// a Rejection (auth_missing, auth_bad_tag, auth_replayed, auth_unknown_sender,
// auth_not_allowed), never an exception.
//
// Threading: free functions are thread-safe; a Signer or a Verifier is used
// from one thread (its Bus's).
#pragma once

#include <array>
#include <cstddef>
#include <cstdint>
#include <filesystem>
#include <map>
#include <memory>
#include <optional>
#include <span>
#include <string>
#include <string_view>
#include <vector>

#include "runtime/rejection.hpp"

namespace lmf::runtime::auth {

inline constexpr std::size_t kKeyBytes = 32;
inline constexpr std::size_t kTagBytes = 32;  // HMAC-SHA256
inline constexpr std::size_t kMaxPrincipalBytes = 32;
inline constexpr std::uint8_t kTrailerVersion = 1;
inline constexpr std::array<std::uint8_t, 4> kTrailerMagic = {'L', 'M', 'F', 'A'};
// Trailer bytes besides the principal: n, seq, tag, version, magic.
inline constexpr std::size_t kTrailerFixedBytes = 1 + 8 + kTagBytes + 1 + kTrailerMagic.size();
inline constexpr std::size_t kDefaultReplayWindow = 1024;

using Key = std::array<std::uint8_t, kKeyBytes>;
using Tag = std::array<std::uint8_t, kTagBytes>;

// ---- principals --------------------------------------------------------------
// A principal name: 1..32 characters of a-z, 0-9, '_' and '-'.
bool is_valid_principal(std::string_view name);

// What a principal may say (see the table above).
struct Role {
  enum class Kind { kServer, kPlayer, kMonitor, kRobot, kOther };
  Kind kind = Kind::kOther;
  int robot_id = -1;  // for kRobot
};
// "server", "player", "monitor", "robot<N>" (N decimal without leading zeros,
// 0 <= N <= INT32_MAX); any other valid name is kOther (may say nothing).
Role role_of(std::string_view principal);
// "robot<N>"; throws std::invalid_argument for a negative id.
std::string robot_principal(int robot_id);

// ---- keys --------------------------------------------------------------------
// Principal -> key. Overwrites its keys with zeros when destroyed.
class KeyRing {
 public:
  KeyRing() = default;
  KeyRing(const KeyRing&) = default;
  KeyRing& operator=(const KeyRing&) = default;
  KeyRing(KeyRing&&) = default;
  KeyRing& operator=(KeyRing&&) = default;
  ~KeyRing();

  // Throws std::invalid_argument for an invalid name or a principal already present.
  void add(const std::string& principal, const Key& key);
  const Key* find(std::string_view principal) const;  // nullptr if absent
  std::size_t size() const { return keys_.size(); }
  std::vector<std::string> principals() const;  // sorted

 private:
  std::map<std::string, Key, std::less<>> keys_;
};

// Keys file text: one "principal hex-key" per line (64 hex digits), blank
// lines and '#' comments allowed, each principal at most once, at least one
// key. Throws std::invalid_argument "<source>:<line>: <what>".
KeyRing parse_keys(std::string_view text, std::string_view source);
// Reads and parses `path`. Refuses (std::invalid_argument) a file that is not
// a regular file or that group or others may read or write (chmod 600), as ssh
// does for private keys.
KeyRing load_keys_file(const std::filesystem::path& path);
// The keys file text of `keys` (parse_keys reads it back), with a comment header.
std::string format_keys(const KeyRing& keys, std::string_view comment = {});
// Creates `path` with mode 0600 and writes format_keys(keys, comment). Throws
// std::invalid_argument if it exists (unless `overwrite`) or cannot be written.
void write_keys_file(const std::filesystem::path& path, const KeyRing& keys, std::string_view comment = {},
                     bool overwrite = false);

// 32 bytes from OpenSSL's CSPRNG; throws std::runtime_error if it fails.
Key random_key();

// The keys files of one system (what lmf-keygen writes), keyed by the
// process's principal: a fresh random key per principal, and in each file only
// the keys that process needs, its own and those of the senders it reads:
//   server     server, player, every robot            (local maps, sightings)
//   player     player, server, every robot            (scan acks, sighting acks)
//   monitor    monitor, server, player, every robot   (it reads every channel)
//   robot<N>   robot<N>, server, player               (acks, frames, scans, mission end)
// so no robot holds another robot's key. Throws std::invalid_argument for a
// negative or repeated robot id.
std::map<std::string, KeyRing> make_system_keys(const std::vector<int>& robot_ids);
std::string to_hex(std::span<const std::uint8_t> bytes);
std::optional<Key> key_from_hex(std::string_view hex);  // exactly 64 hex digits (either case)

// ---- trailer -----------------------------------------------------------------
// HMAC-SHA256(key, label | channel | payload | principal | seq), each part length-prefixed.
Tag compute_tag(const Key& key, std::string_view channel, std::span<const std::uint8_t> payload,
                std::string_view principal, std::uint64_t seq);

// Appends the trailer of (channel, message-so-far as payload, principal, seq) to
// `message`. Requires a valid principal (asserts).
void append_trailer(std::vector<std::uint8_t>& message, std::string_view channel, std::string_view principal,
                    const Key& key, std::uint64_t seq);

// A trailer as read, not yet verified. Views into the message.
struct TrailerView {
  std::size_t payload_size = 0;
  std::string_view principal;
  std::uint64_t seq = 0;
  std::span<const std::uint8_t> tag;
};
// nullopt unless `message` ends with a well-formed trailer of this version
// (magic, version, principal length and characters).
std::optional<TrailerView> parse_trailer(std::span<const std::uint8_t> message);
// The LCM part of a message: `size` minus a well-formed trailer if there is
// one. NOT a verification: for reading captures offline and for processes
// running without keys.
std::size_t unverified_payload_size(const void* data, std::size_t size);

// ---- replay window -------------------------------------------------------------
// Per sender, the highest sequence number taken: the durable form of a
// receiver's replay windows.
using HighWater = std::map<std::string, std::uint64_t, std::less<>>;

// Who signed a message, as its trailer says.
struct SignedBy {
  std::string principal;
  std::uint64_t seq = 0;
};
// nullopt unless `message` ends with a well-formed trailer (NOT a verification).
std::optional<SignedBy> signed_by(std::span<const std::uint8_t> message);

// Raises high_water[principal] to seq (adds it if absent).
void raise(HighWater& high_water, const SignedBy& signer);

// The anti-replay window of one sender (RFC 4303 §3.4.3 style): the highest
// sequence number seen and a bitmap of the `width` numbers up to it.
class ReplayWindow {
 public:
  enum class Verdict { kFresh, kReplayed, kTooOld };
  // Throws std::invalid_argument unless width is a positive multiple of 64.
  explicit ReplayWindow(std::size_t width = kDefaultReplayWindow);

  Verdict check(std::uint64_t seq) const;
  // Records `seq` as seen; requires check(seq) == kFresh (asserts).
  void accept(std::uint64_t seq);
  // Marks every number up to `seq` as seen (those already in the window and
  // older ones alike): a window restored from a high-water mark.
  void refuse_through(std::uint64_t seq);
  std::optional<std::uint64_t> highest() const { return highest_; }
  std::size_t width() const { return bits_.size() * 64; }

 private:
  bool test(std::uint64_t seq) const;
  void set(std::uint64_t seq);
  void clear(std::uint64_t seq);
  std::optional<std::uint64_t> highest_;
  std::vector<std::uint64_t> bits_;  // bit (seq mod width) for seq in (highest - width, highest]
};

// ---- authorization ------------------------------------------------------------
// nullopt if `principal` may send `payload` (an LCM encoding, type told by its
// fingerprint), else an auth_not_allowed rejection saying why.
std::optional<Rejection> authorize(std::string_view principal, std::span<const std::uint8_t> payload);

// ---- what a Bus uses -------------------------------------------------------------
struct Config {
  std::string identity;                // the principal this process signs as
  std::shared_ptr<const KeyRing> keys;  // its own key and those of accepted senders
  std::size_t replay_window = kDefaultReplayWindow;

  // Throws std::invalid_argument unless identity is valid and has a key in
  // `keys` and the window is valid; `source` names the keys file in the message.
  void validate(std::string_view source = "keys") const;
};

// Signs as one principal with consecutive sequence numbers.
class Signer {
 public:
  Signer(std::string principal, const Key& key, std::uint64_t first_seq);
  ~Signer();
  Signer(const Signer&) = delete;
  Signer& operator=(const Signer&) = delete;

  // `out` = payload + trailer (reusing out's capacity).
  void sign(std::string_view channel, std::span<const std::uint8_t> payload, std::vector<std::uint8_t>& out);
  const std::string& principal() const { return principal_; }
  std::uint64_t next_seq() const { return next_seq_; }

 private:
  std::string principal_;
  Key key_;
  std::uint64_t next_seq_;
};

// Checks trailer, tag, freshness and authorization, in that order; only a
// message with a valid tag moves its sender's window.
class Verifier {
 public:
  explicit Verifier(std::shared_ptr<const KeyRing> keys, std::size_t replay_window = kDefaultReplayWindow);

  // The LCM payload (a prefix of `message`) or the rejection.
  Checked<std::span<const std::uint8_t>> verify(std::string_view channel, std::span<const std::uint8_t> message);

  std::int64_t verified() const { return verified_; }  // messages accepted so far

  // From now on refuses, per sender, every number up to its high-water mark
  // (restored state of a restarted receiver); senders not named are unchanged.
  void refuse_through(const HighWater& high_water);

 private:
  std::shared_ptr<const KeyRing> keys_;
  std::size_t replay_window_;
  std::map<std::string, ReplayWindow, std::less<>> windows_;
  std::int64_t verified_ = 0;
};

// Microseconds since the Unix epoch: where a process's sequence numbers start.
std::uint64_t wall_clock_first_seq();

}  // namespace lmf::runtime::auth
