#include "runtime/auth.hpp"

#include <fcntl.h>
#include <sys/stat.h>
#include <unistd.h>

#include <algorithm>
#include <cassert>
#include <cerrno>
#include <charconv>
#include <chrono>
#include <cstring>
#include <fstream>
#include <limits>
#include <sstream>
#include <stdexcept>
#include <utility>

#include <openssl/core_names.h>
#include <openssl/crypto.h>
#include <openssl/evp.h>
#include <openssl/params.h>
#include <openssl/rand.h>

#include "lmf/agent_status_t.hpp"
#include "lmf/corrected_frames_t.hpp"
#include "lmf/global_map_t.hpp"
#include "lmf/laser_scan_t.hpp"
#include "lmf/local_map_ack_t.hpp"
#include "lmf/local_map_t.hpp"
#include "lmf/mission_end_t.hpp"
#include "lmf/scan_ack_t.hpp"
#include "lmf/server_status_t.hpp"
#include "lmf/sighting_ack_t.hpp"
#include "lmf/sighting_t.hpp"

namespace lmf::runtime::auth {

namespace {

constexpr std::string_view kTagLabel = "lmf-auth-v1";  // domain separation; changes with the version

bool is_principal_char(char c) { return (c >= 'a' && c <= 'z') || (c >= '0' && c <= '9') || c == '_' || c == '-'; }

void put_be(std::vector<std::uint8_t>& out, std::uint64_t value, int bytes) {
  for (int i = bytes - 1; i >= 0; --i) out.push_back(static_cast<std::uint8_t>(value >> (8 * i)));
}

std::uint64_t get_be(const std::uint8_t* p, int bytes) {
  std::uint64_t value = 0;
  for (int i = 0; i < bytes; ++i) value = (value << 8) | p[i];
  return value;
}

std::string trim(std::string_view s) {
  const auto first = s.find_first_not_of(" \t\r");
  if (first == std::string_view::npos) return {};
  const auto last = s.find_last_not_of(" \t\r");
  return std::string(s.substr(first, last - first + 1));
}

// OpenSSL failing to compute a HMAC is not bad input: the library is broken.
void require(int ok, const char* what) {
  if (ok != 1) throw std::runtime_error(std::string("OpenSSL: ") + what + " failed");
}

EVP_MAC* hmac_algorithm() {
  // Fetched once (thread-safe static init), freed at exit.
  static const std::unique_ptr<EVP_MAC, decltype(&EVP_MAC_free)> mac(EVP_MAC_fetch(nullptr, "HMAC", nullptr),
                                                                    &EVP_MAC_free);
  if (!mac) throw std::runtime_error("OpenSSL: HMAC is not available");
  return mac.get();
}

}  // namespace

// ---- principals --------------------------------------------------------------

bool is_valid_principal(std::string_view name) {
  return !name.empty() && name.size() <= kMaxPrincipalBytes && std::all_of(name.begin(), name.end(), is_principal_char);
}

Role role_of(std::string_view principal) {
  if (principal == "server") return {Role::Kind::kServer, -1};
  if (principal == "player") return {Role::Kind::kPlayer, -1};
  if (principal == "monitor") return {Role::Kind::kMonitor, -1};
  constexpr std::string_view kRobot = "robot";
  if (principal.size() > kRobot.size() && principal.substr(0, kRobot.size()) == kRobot) {
    const std::string_view digits = principal.substr(kRobot.size());
    const bool all_digits = std::all_of(digits.begin(), digits.end(), [](char c) { return c >= '0' && c <= '9'; });
    if (all_digits && (digits.size() == 1 || digits.front() != '0')) {
      int id = 0;
      const auto [end, error] = std::from_chars(digits.data(), digits.data() + digits.size(), id);
      if (error == std::errc() && end == digits.data() + digits.size()) return {Role::Kind::kRobot, id};
    }
  }
  return {};
}

std::string robot_principal(int robot_id) {
  if (robot_id < 0) throw std::invalid_argument("robot id " + std::to_string(robot_id) + " is negative");
  return "robot" + std::to_string(robot_id);
}

// ---- keys --------------------------------------------------------------------

KeyRing::~KeyRing() {
  for (auto& entry : keys_) OPENSSL_cleanse(entry.second.data(), entry.second.size());
}

void KeyRing::add(const std::string& principal, const Key& key) {
  if (!is_valid_principal(principal)) {
    throw std::invalid_argument("invalid principal name '" + principal + "' (1 to " +
                                std::to_string(kMaxPrincipalBytes) + " characters of a-z, 0-9, '_', '-')");
  }
  if (!keys_.emplace(principal, key).second) throw std::invalid_argument("principal '" + principal + "' given twice");
}

const Key* KeyRing::find(std::string_view principal) const {
  const auto it = keys_.find(principal);
  return it == keys_.end() ? nullptr : &it->second;
}

std::vector<std::string> KeyRing::principals() const {
  std::vector<std::string> names;
  names.reserve(keys_.size());
  for (const auto& entry : keys_) names.push_back(entry.first);
  return names;
}

KeyRing parse_keys(std::string_view text, std::string_view source) {
  KeyRing ring;
  std::map<std::string, int, std::less<>> first_line;
  int line_number = 0;
  std::size_t pos = 0;
  while (pos < text.size()) {
    const std::size_t end = std::min(text.find('\n', pos), text.size());
    std::string_view line = text.substr(pos, end - pos);
    pos = end + 1;
    ++line_number;
    const auto where = [&] { return std::string(source) + ":" + std::to_string(line_number) + ": "; };
    if (const auto hash = line.find('#'); hash != std::string_view::npos) line = line.substr(0, hash);
    std::istringstream fields(trim(line));
    std::vector<std::string> words;
    for (std::string word; fields >> word;) words.push_back(word);
    if (words.empty()) continue;
    if (words.size() != 2) {
      throw std::invalid_argument(where() + "expected 'principal hex-key', found " + std::to_string(words.size()) +
                                  (words.size() == 1 ? " field" : " fields"));
    }
    const std::string& principal = words[0];
    if (!is_valid_principal(principal)) {
      throw std::invalid_argument(where() + "invalid principal name '" + principal + "' (1 to " +
                                  std::to_string(kMaxPrincipalBytes) + " characters of a-z, 0-9, '_', '-')");
    }
    // The key itself is never echoed: it may be a real key with a typo.
    const std::optional<Key> key = key_from_hex(words[1]);
    if (!key) {
      throw std::invalid_argument(where() + "the key of '" + principal + "' is not 64 hex digits (a 32-byte key; " +
                                  std::to_string(words[1].size()) + " characters found)");
    }
    if (const auto it = first_line.find(principal); it != first_line.end()) {
      throw std::invalid_argument(where() + "principal '" + principal + "' already given on line " +
                                  std::to_string(it->second));
    }
    first_line.emplace(principal, line_number);
    ring.add(principal, *key);
  }
  if (ring.size() == 0) throw std::invalid_argument(std::string(source) + ": no keys");
  return ring;
}

KeyRing load_keys_file(const std::filesystem::path& path) {
  struct stat info {};
  if (::stat(path.c_str(), &info) != 0) {
    throw std::invalid_argument(path.string() + ": cannot read keys file: " + std::strerror(errno));
  }
  if (!S_ISREG(info.st_mode)) throw std::invalid_argument(path.string() + ": keys file is not a regular file");
  if ((info.st_mode & 077) != 0) {
    std::ostringstream mode;
    mode << std::oct << (info.st_mode & 0777);
    throw std::invalid_argument(path.string() + ": keys file is accessible by group or others (mode 0" + mode.str() +
                                "); secret keys need 'chmod 600 " + path.string() + "'");
  }
  std::ifstream in(path, std::ios::binary);
  std::ostringstream text;
  text << in.rdbuf();
  if (!in.good() && !in.eof()) throw std::invalid_argument(path.string() + ": cannot read keys file");
  const std::string content = text.str();
  KeyRing ring = parse_keys(content, path.string());
  return ring;
}

std::string format_keys(const KeyRing& keys, std::string_view comment) {
  std::string text;
  std::size_t pos = 0;
  while (pos < comment.size()) {
    const std::size_t end = std::min(comment.find('\n', pos), comment.size());
    text += "# " + std::string(comment.substr(pos, end - pos)) + "\n";
    pos = end + 1;
  }
  for (const std::string& principal : keys.principals()) {
    text += principal + " " + to_hex(*keys.find(principal)) + "\n";
  }
  return text;
}

void write_keys_file(const std::filesystem::path& path, const KeyRing& keys, std::string_view comment,
                     bool overwrite) {
  std::string text = format_keys(keys, comment);
  const int flags = O_WRONLY | O_CREAT | O_CLOEXEC | (overwrite ? O_TRUNC : O_EXCL);
  const int fd = ::open(path.c_str(), flags, 0600);
  if (fd < 0) throw std::invalid_argument(path.string() + ": cannot create keys file: " + std::strerror(errno));
  bool ok = ::fchmod(fd, 0600) == 0;  // an overwritten file keeps its old mode otherwise
  std::size_t written = 0;
  while (ok && written < text.size()) {
    const ssize_t n = ::write(fd, text.data() + written, text.size() - written);
    if (n < 0 && errno == EINTR) continue;
    ok = n > 0;
    if (ok) written += static_cast<std::size_t>(n);
  }
  ok = ::close(fd) == 0 && ok;
  OPENSSL_cleanse(text.data(), text.size());
  if (!ok) throw std::invalid_argument(path.string() + ": cannot write keys file: " + std::strerror(errno));
}

Key random_key() {
  Key key{};
  if (RAND_bytes(key.data(), static_cast<int>(key.size())) != 1) {
    throw std::runtime_error("OpenSSL: RAND_bytes failed to give a key");
  }
  return key;
}

std::map<std::string, KeyRing> make_system_keys(const std::vector<int>& robot_ids) {
  std::vector<std::string> robots;
  for (const int id : robot_ids) robots.push_back(robot_principal(id));
  std::map<std::string, Key> key;
  for (const std::string& principal : {std::string("server"), std::string("player"), std::string("monitor")}) {
    key[principal] = random_key();
  }
  for (const std::string& robot : robots) {
    if (key.count(robot) != 0) throw std::invalid_argument("robot id of '" + robot + "' given twice");
    key[robot] = random_key();
  }
  std::map<std::string, KeyRing> files;
  const auto file = [&](const std::string& owner, std::vector<std::string> readers_of) {
    KeyRing& ring = files[owner];
    ring.add(owner, key[owner]);
    for (const std::string& principal : readers_of) ring.add(principal, key[principal]);
  };
  std::vector<std::string> player_and_robots = robots;
  player_and_robots.insert(player_and_robots.begin(), "player");
  file("server", player_and_robots);
  std::vector<std::string> server_and_robots = robots;
  server_and_robots.insert(server_and_robots.begin(), "server");
  file("player", server_and_robots);  // scan acks, sighting acks
  std::vector<std::string> everyone = player_and_robots;
  everyone.insert(everyone.begin(), "server");
  file("monitor", everyone);
  for (const std::string& robot : robots) file(robot, {"server", "player"});
  for (auto& entry : key) OPENSSL_cleanse(entry.second.data(), entry.second.size());
  return files;
}

std::string to_hex(std::span<const std::uint8_t> bytes) {
  static constexpr char kDigits[] = "0123456789abcdef";
  std::string hex;
  hex.reserve(2 * bytes.size());
  for (const std::uint8_t b : bytes) {
    hex.push_back(kDigits[b >> 4]);
    hex.push_back(kDigits[b & 0xf]);
  }
  return hex;
}

std::optional<Key> key_from_hex(std::string_view hex) {
  if (hex.size() != 2 * kKeyBytes) return std::nullopt;
  const auto nibble = [](char c) -> int {
    if (c >= '0' && c <= '9') return c - '0';
    if (c >= 'a' && c <= 'f') return c - 'a' + 10;
    if (c >= 'A' && c <= 'F') return c - 'A' + 10;
    return -1;
  };
  Key key{};
  for (std::size_t i = 0; i < kKeyBytes; ++i) {
    const int hi = nibble(hex[2 * i]);
    const int lo = nibble(hex[2 * i + 1]);
    if (hi < 0 || lo < 0) return std::nullopt;
    key[i] = static_cast<std::uint8_t>((hi << 4) | lo);
  }
  return key;
}

// ---- trailer -----------------------------------------------------------------

Tag compute_tag(const Key& key, std::string_view channel, std::span<const std::uint8_t> payload,
                std::string_view principal, std::uint64_t seq) {
  std::unique_ptr<EVP_MAC_CTX, decltype(&EVP_MAC_CTX_free)> ctx(EVP_MAC_CTX_new(hmac_algorithm()),
                                                                 &EVP_MAC_CTX_free);
  if (!ctx) throw std::runtime_error("OpenSSL: EVP_MAC_CTX_new failed");
  char digest[] = "SHA256";
  const OSSL_PARAM params[] = {OSSL_PARAM_construct_utf8_string(OSSL_MAC_PARAM_DIGEST, digest, 0),
                               OSSL_PARAM_construct_end()};
  require(EVP_MAC_init(ctx.get(), key.data(), key.size(), params), "EVP_MAC_init");
  // Every variable-length part is length-prefixed so no two inputs share a MAC input.
  std::vector<std::uint8_t> header;
  header.reserve(kTagLabel.size() + 4 + channel.size() + 8);
  header.insert(header.end(), kTagLabel.begin(), kTagLabel.end());
  put_be(header, channel.size(), 4);
  header.insert(header.end(), channel.begin(), channel.end());
  put_be(header, payload.size(), 8);
  require(EVP_MAC_update(ctx.get(), header.data(), header.size()), "EVP_MAC_update");
  if (!payload.empty()) require(EVP_MAC_update(ctx.get(), payload.data(), payload.size()), "EVP_MAC_update");
  std::vector<std::uint8_t> footer;
  footer.reserve(1 + principal.size() + 8);
  put_be(footer, principal.size(), 1);
  footer.insert(footer.end(), principal.begin(), principal.end());
  put_be(footer, seq, 8);
  require(EVP_MAC_update(ctx.get(), footer.data(), footer.size()), "EVP_MAC_update");
  Tag tag{};
  std::size_t length = 0;
  require(EVP_MAC_final(ctx.get(), tag.data(), &length, tag.size()), "EVP_MAC_final");
  if (length != tag.size()) throw std::runtime_error("OpenSSL: HMAC-SHA256 gave " + std::to_string(length) + " bytes");
  return tag;
}

void append_trailer(std::vector<std::uint8_t>& message, std::string_view channel, std::string_view principal,
                    const Key& key, std::uint64_t seq) {
  assert(is_valid_principal(principal));
  const std::size_t payload_size = message.size();
  const Tag tag = compute_tag(key, channel, std::span<const std::uint8_t>(message.data(), payload_size), principal, seq);
  message.reserve(payload_size + principal.size() + kTrailerFixedBytes);
  message.insert(message.end(), principal.begin(), principal.end());
  put_be(message, principal.size(), 1);
  put_be(message, seq, 8);
  message.insert(message.end(), tag.begin(), tag.end());
  message.push_back(kTrailerVersion);
  message.insert(message.end(), kTrailerMagic.begin(), kTrailerMagic.end());
}

std::optional<TrailerView> parse_trailer(std::span<const std::uint8_t> message) {
  const std::size_t size = message.size();
  if (size < kTrailerFixedBytes) return std::nullopt;
  const std::uint8_t* end = message.data() + size;
  if (!std::equal(kTrailerMagic.begin(), kTrailerMagic.end(), end - kTrailerMagic.size())) return std::nullopt;
  const std::uint8_t* version = end - kTrailerMagic.size() - 1;
  if (*version != kTrailerVersion) return std::nullopt;
  const std::uint8_t* tag = version - kTagBytes;
  const std::uint8_t* seq = tag - 8;
  const std::uint8_t* length = seq - 1;
  const std::size_t n = *length;
  if (n == 0 || n > kMaxPrincipalBytes || size < kTrailerFixedBytes + n) return std::nullopt;
  const std::string_view principal(reinterpret_cast<const char*>(length - n), n);
  if (!is_valid_principal(principal)) return std::nullopt;
  TrailerView view;
  view.payload_size = size - kTrailerFixedBytes - n;
  view.principal = principal;
  view.seq = get_be(seq, 8);
  view.tag = std::span<const std::uint8_t>(tag, kTagBytes);
  return view;
}

std::size_t unverified_payload_size(const void* data, std::size_t size) {
  const auto trailer = parse_trailer(std::span<const std::uint8_t>(static_cast<const std::uint8_t*>(data), size));
  return trailer ? trailer->payload_size : size;
}

// ---- replay window -------------------------------------------------------------

ReplayWindow::ReplayWindow(std::size_t width) {
  if (width == 0 || width % 64 != 0) {
    throw std::invalid_argument("replay window of " + std::to_string(width) + ": must be a positive multiple of 64");
  }
  bits_.assign(width / 64, 0);
}

bool ReplayWindow::test(std::uint64_t seq) const {
  const std::uint64_t bit = seq % width();
  return ((bits_[bit / 64] >> (bit % 64)) & 1u) != 0;
}

void ReplayWindow::set(std::uint64_t seq) {
  const std::uint64_t bit = seq % width();
  bits_[bit / 64] |= std::uint64_t{1} << (bit % 64);
}

void ReplayWindow::clear(std::uint64_t seq) {
  const std::uint64_t bit = seq % width();
  bits_[bit / 64] &= ~(std::uint64_t{1} << (bit % 64));
}

ReplayWindow::Verdict ReplayWindow::check(std::uint64_t seq) const {
  if (!highest_ || seq > *highest_) return Verdict::kFresh;
  if (*highest_ - seq >= width()) return Verdict::kTooOld;
  return test(seq) ? Verdict::kReplayed : Verdict::kFresh;
}

void ReplayWindow::accept(std::uint64_t seq) {
  assert(check(seq) == Verdict::kFresh);
  if (!highest_ || seq > *highest_) {
    // The numbers that slide into the window were never seen.
    const std::uint64_t advance = highest_ ? seq - *highest_ : width();
    if (advance >= width()) {
      std::fill(bits_.begin(), bits_.end(), 0);
    } else {
      for (std::uint64_t s = *highest_ + 1; s <= seq; ++s) clear(s);
    }
    highest_ = seq;
  }
  set(seq);
}

void ReplayWindow::refuse_through(std::uint64_t seq) {
  if (!highest_ || seq > *highest_) {
    highest_ = seq;
    std::fill(bits_.begin(), bits_.end(), ~std::uint64_t{0});
    return;
  }
  if (*highest_ - seq >= width()) return;  // already too old
  const std::uint64_t oldest_in_window = *highest_ - (width() - 1);
  for (std::uint64_t s = seq;; --s) {
    set(s);
    if (s == oldest_in_window || s == 0) break;
  }
}

std::optional<SignedBy> signed_by(std::span<const std::uint8_t> message) {
  const std::optional<TrailerView> trailer = parse_trailer(message);
  if (!trailer) return std::nullopt;
  return SignedBy{std::string(trailer->principal), trailer->seq};
}

void raise(HighWater& high_water, const SignedBy& signer) {
  const auto it = high_water.find(signer.principal);
  if (it == high_water.end()) {
    high_water.emplace(signer.principal, signer.seq);
  } else {
    it->second = std::max(it->second, signer.seq);
  }
}

// ---- authorization ------------------------------------------------------------

namespace {

enum class Speaker { kRobotInMessage, kServer, kPlayer };

struct Rule {
  std::uint64_t fingerprint;
  std::string_view type;
  Speaker speaker;
};

template <class Msg>
Rule rule(std::string_view type, Speaker speaker) {
  return {static_cast<std::uint64_t>(Msg::getHash()), type, speaker};
}

const std::vector<Rule>& rules() {
  static const std::vector<Rule> table = {
      rule<lmf::local_map_t>("local_map_t", Speaker::kRobotInMessage),
      rule<lmf::scan_ack_t>("scan_ack_t", Speaker::kRobotInMessage),
      rule<lmf::agent_status_t>("agent_status_t", Speaker::kRobotInMessage),
      rule<lmf::local_map_ack_t>("local_map_ack_t", Speaker::kServer),
      rule<lmf::sighting_ack_t>("sighting_ack_t", Speaker::kServer),
      rule<lmf::corrected_frames_t>("corrected_frames_t", Speaker::kServer),
      rule<lmf::global_map_t>("global_map_t", Speaker::kServer),
      rule<lmf::server_status_t>("server_status_t", Speaker::kServer),
      rule<lmf::laser_scan_t>("laser_scan_t", Speaker::kPlayer),
      rule<lmf::sighting_t>("sighting_t", Speaker::kPlayer),
      rule<lmf::mission_end_t>("mission_end_t", Speaker::kPlayer),
  };
  return table;
}

// In local_map_t, scan_ack_t and agent_status_t the robot id is the int32 right
// after the fingerprint and `int64_t utime` (STYLE: utime first, then ids);
// tests check this offset against lcm-gen's encoding.
constexpr std::size_t kRobotIdOffset = 8 + 8;

Rejection not_allowed(std::string detail) { return Rejection{RejectReason::kAuthNotAllowed, std::move(detail)}; }

}  // namespace

std::optional<Rejection> authorize(std::string_view principal, std::span<const std::uint8_t> payload) {
  const std::string who = "'" + std::string(principal) + "'";
  if (payload.size() < 8) return not_allowed(who + " sent " + std::to_string(payload.size()) + " bytes, no LCM message");
  const std::uint64_t fingerprint = get_be(payload.data(), 8);
  const auto& table = rules();
  const auto it = std::find_if(table.begin(), table.end(), [&](const Rule& r) { return r.fingerprint == fingerprint; });
  if (it == table.end()) {
    std::ostringstream hex;
    hex << std::hex << fingerprint;
    return not_allowed(who + " sent a message of unknown type (fingerprint 0x" + hex.str() + ")");
  }
  const Role role = role_of(principal);
  const std::string type(it->type);
  switch (it->speaker) {
    case Speaker::kServer:
      if (role.kind == Role::Kind::kServer) return std::nullopt;
      return not_allowed(who + " may not send " + type + " (only server)");
    case Speaker::kPlayer:
      if (role.kind == Role::Kind::kPlayer) return std::nullopt;
      return not_allowed(who + " may not send " + type + " (only player)");
    case Speaker::kRobotInMessage: {
      if (role.kind != Role::Kind::kRobot) return not_allowed(who + " may not send " + type + " (only robot<N>)");
      if (payload.size() < kRobotIdOffset + 4) return not_allowed(who + " sent a truncated " + type);
      const auto robot_id = static_cast<std::int32_t>(static_cast<std::uint32_t>(get_be(payload.data() + kRobotIdOffset, 4)));
      if (robot_id == role.robot_id) return std::nullopt;
      return not_allowed(who + " may not send " + type + " for robot " + std::to_string(robot_id));
    }
  }
  return not_allowed(who + ": no rule");  // unreachable: every Speaker is handled above
}

// ---- Config, Signer, Verifier -------------------------------------------------------

void Config::validate(std::string_view source) const {
  if (!is_valid_principal(identity)) {
    throw std::invalid_argument("invalid identity '" + identity + "' (1 to " + std::to_string(kMaxPrincipalBytes) +
                                " characters of a-z, 0-9, '_', '-')");
  }
  if (!keys || keys->find(identity) == nullptr) {
    throw std::invalid_argument(std::string(source) + ": no key for '" + identity +
                                "', the principal this process signs as (see --identity)");
  }
  ReplayWindow check(replay_window);  // throws for a bad width
}

Signer::Signer(std::string principal, const Key& key, std::uint64_t first_seq)
    : principal_(std::move(principal)), key_(key), next_seq_(first_seq) {
  if (!is_valid_principal(principal_)) throw std::invalid_argument("invalid principal '" + principal_ + "'");
}

Signer::~Signer() { OPENSSL_cleanse(key_.data(), key_.size()); }

void Signer::sign(std::string_view channel, std::span<const std::uint8_t> payload, std::vector<std::uint8_t>& out) {
  out.clear();
  out.reserve(payload.size() + principal_.size() + kTrailerFixedBytes);
  out.insert(out.end(), payload.begin(), payload.end());
  append_trailer(out, channel, principal_, key_, next_seq_++);
}

Verifier::Verifier(std::shared_ptr<const KeyRing> keys, std::size_t replay_window)
    : keys_(std::move(keys)), replay_window_(replay_window) {
  if (!keys_) throw std::invalid_argument("Verifier: no keys");
  ReplayWindow check(replay_window_);  // throws for a bad width
}

Checked<std::span<const std::uint8_t>> Verifier::verify(std::string_view channel,
                                                        std::span<const std::uint8_t> message) {
  const std::optional<TrailerView> trailer = parse_trailer(message);
  if (!trailer) {
    const bool has_magic = message.size() >= kTrailerMagic.size() &&
                           std::equal(kTrailerMagic.begin(), kTrailerMagic.end(), message.end() - 4);
    return Rejection{RejectReason::kAuthMissing,
                     (has_magic ? "malformed or unsupported authentication trailer ("
                                : "no authentication trailer (") +
                         std::to_string(message.size()) + " bytes)"};
  }
  const std::string who = "'" + std::string(trailer->principal) + "' seq " + std::to_string(trailer->seq);
  const Key* key = keys_->find(trailer->principal);
  if (key == nullptr) {
    return Rejection{RejectReason::kAuthUnknownSender, who + ": no key for this sender here"};
  }
  const auto payload = message.first(trailer->payload_size);
  const Tag expected = compute_tag(*key, channel, payload, trailer->principal, trailer->seq);
  if (CRYPTO_memcmp(expected.data(), trailer->tag.data(), kTagBytes) != 0) {
    return Rejection{RejectReason::kAuthBadTag, who + ": tag does not match (forged, altered or wrong key)"};
  }
  const auto window = windows_.try_emplace(std::string(trailer->principal), replay_window_).first;
  switch (window->second.check(trailer->seq)) {
    case ReplayWindow::Verdict::kFresh: break;
    case ReplayWindow::Verdict::kReplayed:
      return Rejection{RejectReason::kAuthReplayed, who + ": already received"};
    case ReplayWindow::Verdict::kTooOld:
      return Rejection{RejectReason::kAuthReplayed,
                       who + ": older than the replay window (highest " + std::to_string(*window->second.highest()) +
                           ", width " + std::to_string(window->second.width()) +
                           "; a sender restarted with its clock set back needs this process restarted too)"};
  }
  window->second.accept(trailer->seq);
  if (auto refused = authorize(trailer->principal, payload)) return *std::move(refused);
  ++verified_;
  return payload;
}

void Verifier::refuse_through(const HighWater& high_water) {
  for (const auto& [principal, seq] : high_water) {
    windows_.try_emplace(principal, replay_window_).first->second.refuse_through(seq);
  }
}

std::uint64_t wall_clock_first_seq() {
  const auto now = std::chrono::system_clock::now().time_since_epoch();
  return static_cast<std::uint64_t>(std::chrono::duration_cast<std::chrono::microseconds>(now).count());
}

}  // namespace lmf::runtime::auth
