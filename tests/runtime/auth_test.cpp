// runtime/auth: keys files, trailer sign/verify, the replay window, who may
// say what, and the Bus signing and verifying over memq://.
#include <sys/stat.h>
#include <unistd.h>

#include <algorithm>
#include <cctype>
#include <cstdint>
#include <filesystem>
#include <fstream>
#include <functional>
#include <memory>
#include <random>
#include <set>
#include <stdexcept>
#include <string>
#include <vector>

#include <boost/program_options.hpp>
#include <gtest/gtest.h>

#include "runtime/auth.hpp"
#include "runtime/bus.hpp"
#include "runtime/channels.hpp"
#include "runtime/convert.hpp"
#include "runtime/options.hpp"

namespace {

namespace rt = lmf::runtime;
namespace auth = lmf::runtime::auth;
using Bytes = std::vector<std::uint8_t>;
using rt::RejectReason;

auth::Key key_of(std::uint8_t fill) {
  auth::Key key{};
  for (std::size_t i = 0; i < key.size(); ++i) key[i] = static_cast<std::uint8_t>(fill + i);
  return key;
}

std::shared_ptr<const auth::KeyRing> ring(std::initializer_list<std::pair<std::string, auth::Key>> entries) {
  auto keys = std::make_shared<auth::KeyRing>();
  for (const auto& [principal, key] : entries) keys->add(principal, key);
  return keys;
}

// The keys of a small system: every principal's key derived from its index.
const auth::Key kServer = key_of(1), kPlayer = key_of(2), kRobot0 = key_of(3), kRobot1 = key_of(4);

lmf::local_map_ack_t an_ack(int robot_id, std::int64_t seq) {
  lmf::local_map_ack_t ack;
  ack.utime = 123456789;
  ack.robot_id = robot_id;
  ack.seq = seq;
  ack.status = lmf::local_map_ack_t::FUSED;
  return ack;
}

lmf::local_map_t a_local_map(int robot_id, std::int64_t seq) {
  lmf::local_map_t map;
  map.utime = 2000000;
  map.robot_id = robot_id;
  map.seq = seq;
  map.first_scan_utime = 1000000;
  map.num_scans = 1;
  map.robot = lmf::pose2_t{0.5, 0.25, 0.1};
  map.num_segments = 0;
  map.num_covariance = 6;
  map.covariance = {1e-4, 0, 0, 1e-4, 0, 1e-5};
  map.num_scan_poses = 1;
  map.scan_utimes = {2000000};
  map.scan_poses = {map.robot};
  return map;
}

rt::RejectReason reason_of(const rt::Checked<std::span<const std::uint8_t>>& result) {
  EXPECT_FALSE(result.ok()) << "accepted";
  return result.ok() ? RejectReason::kHandlerError : result.rejection().reason;
}

class TempDir {
 public:
  TempDir() {
    std::string pattern = (std::filesystem::temp_directory_path() / "lmf-auth-test-XXXXXX").string();
    if (::mkdtemp(pattern.data()) == nullptr) throw std::runtime_error("mkdtemp failed");
    path_ = pattern;
  }
  ~TempDir() { std::filesystem::remove_all(path_); }
  const std::filesystem::path& path() const { return path_; }
  std::filesystem::path write(const std::string& name, const std::string& text, mode_t mode = 0600) const {
    const auto file = path_ / name;
    std::ofstream(file) << text;
    ::chmod(file.c_str(), mode);
    return file;
  }

 private:
  std::filesystem::path path_;
};

std::string error_of(const std::function<void()>& f) {
  try {
    f();
  } catch (const std::invalid_argument& e) {
    return e.what();
  }
  return "(no std::invalid_argument thrown)";
}

// ---- principals and keys ---------------------------------------------------------

TEST(AuthPrincipal, NamesAndRoles) {
  EXPECT_TRUE(auth::is_valid_principal("robot12"));
  EXPECT_TRUE(auth::is_valid_principal("lab-logger_2"));
  EXPECT_FALSE(auth::is_valid_principal(""));
  EXPECT_FALSE(auth::is_valid_principal("Robot1"));
  EXPECT_FALSE(auth::is_valid_principal("robot 1"));
  EXPECT_FALSE(auth::is_valid_principal(std::string(33, 'a')));
  EXPECT_TRUE(auth::is_valid_principal(std::string(32, 'a')));

  EXPECT_EQ(auth::role_of("server").kind, auth::Role::Kind::kServer);
  EXPECT_EQ(auth::role_of("player").kind, auth::Role::Kind::kPlayer);
  EXPECT_EQ(auth::role_of("monitor").kind, auth::Role::Kind::kMonitor);
  EXPECT_EQ(auth::role_of("robot0").kind, auth::Role::Kind::kRobot);
  EXPECT_EQ(auth::role_of("robot0").robot_id, 0);
  EXPECT_EQ(auth::role_of("robot2147483647").robot_id, 2147483647);
  for (const char* other : {"robot", "robot01", "robot-1", "robot2147483648", "robot1x", "servers", "xrobot1"}) {
    EXPECT_EQ(auth::role_of(other).kind, auth::Role::Kind::kOther) << other;
  }
  EXPECT_EQ(auth::robot_principal(7), "robot7");
  EXPECT_THROW(auth::robot_principal(-1), std::invalid_argument);
}

TEST(AuthKeys, HexRoundTripAndRandomKeys) {
  const auth::Key key = key_of(200);
  EXPECT_EQ(auth::key_from_hex(auth::to_hex(key)), key);
  std::string upper = auth::to_hex(key);
  std::transform(upper.begin(), upper.end(), upper.begin(), [](char c) { return static_cast<char>(std::toupper(c)); });
  EXPECT_EQ(auth::key_from_hex(upper), key);
  EXPECT_FALSE(auth::key_from_hex(auth::to_hex(key).substr(2)).has_value());
  EXPECT_FALSE(auth::key_from_hex(auth::to_hex(key) + "00").has_value());
  std::string bad = auth::to_hex(key);
  bad[10] = 'g';
  EXPECT_FALSE(auth::key_from_hex(bad).has_value());
  EXPECT_NE(auth::random_key(), auth::random_key());
}

TEST(AuthKeys, ParsesCommentsBlankLinesAndCrlf) {
  const std::string text = "# keys of robot0\n\n  robot0 " + auth::to_hex(kRobot0) + "   # its own\r\nserver\t" +
                           auth::to_hex(kServer) + "\nplayer " + auth::to_hex(kPlayer);
  const auth::KeyRing keys = auth::parse_keys(text, "robot0.keys");
  ASSERT_EQ(keys.size(), 3u);
  EXPECT_EQ(*keys.find("robot0"), kRobot0);
  EXPECT_EQ(*keys.find("server"), kServer);
  EXPECT_EQ(*keys.find("player"), kPlayer);
  EXPECT_EQ(keys.find("robot1"), nullptr);
  EXPECT_EQ(keys.principals(), (std::vector<std::string>{"player", "robot0", "server"}));
  // format_keys reads back.
  const auth::KeyRing again = auth::parse_keys(auth::format_keys(keys, "two\nlines"), "again");
  EXPECT_EQ(again.principals(), keys.principals());
  EXPECT_EQ(*again.find("robot0"), kRobot0);
}

TEST(AuthKeys, MalformedFilesNameFileAndLine) {
  const std::string k = auth::to_hex(kServer);
  const auto error = [](const std::string& text) { return error_of([&] { auth::parse_keys(text, "f.keys"); }); };
  EXPECT_EQ(error("server " + k + "\nrobot0\n"), "f.keys:2: expected 'principal hex-key', found 1 field");
  EXPECT_EQ(error("# c\nserver " + k + " extra\n"), "f.keys:2: expected 'principal hex-key', found 3 fields");
  EXPECT_NE(error("Server " + k).find("f.keys:1: invalid principal name 'Server'"), std::string::npos);
  EXPECT_EQ(error("server " + k.substr(1)),
            "f.keys:1: the key of 'server' is not 64 hex digits (a 32-byte key; 63 characters found)");
  EXPECT_NE(error("server " + k.substr(0, 63) + "z").find("f.keys:1: the key of 'server'"), std::string::npos);
  EXPECT_EQ(error("server " + k + "\n\nserver " + k), "f.keys:3: principal 'server' already given on line 1");
  EXPECT_EQ(error("# nothing\n\n"), "f.keys: no keys");
  EXPECT_EQ(error(""), "f.keys: no keys");
  // The key is never echoed in an error.
  EXPECT_EQ(error("server " + k + "0").find(k), std::string::npos);
}

TEST(AuthKeys, FilesMustBePrivate) {
  TempDir dir;
  const std::string text = "server " + auth::to_hex(kServer) + "\n";
  EXPECT_EQ(auth::load_keys_file(dir.write("ok.keys", text, 0600)).size(), 1u);
  EXPECT_EQ(auth::load_keys_file(dir.write("ro.keys", text, 0400)).size(), 1u);
  const auto open = dir.write("open.keys", text, 0644);
  EXPECT_EQ(error_of([&] { auth::load_keys_file(open); }),
            open.string() + ": keys file is accessible by group or others (mode 0644); secret keys need 'chmod 600 " +
                open.string() + "'");
  EXPECT_NE(error_of([&] { auth::load_keys_file(dir.write("g.keys", text, 0620)); }).find("mode 0620"),
            std::string::npos);
  EXPECT_NE(error_of([&] { auth::load_keys_file(dir.path() / "absent.keys"); }).find("absent.keys: cannot read"),
            std::string::npos);
  EXPECT_NE(error_of([&] { auth::load_keys_file(dir.path()); }).find("not a regular file"), std::string::npos);
  EXPECT_NE(error_of([&] { auth::load_keys_file(dir.write("bad.keys", text + "x\n")); }).find("bad.keys:2: "),
            std::string::npos);
}

TEST(AuthKeys, WriteCreatesMode600AndRefusesToOverwrite) {
  TempDir dir;
  const auto keys = ring({{"robot0", kRobot0}, {"server", kServer}});
  const auto file = dir.path() / "robot0.keys";
  auth::write_keys_file(file, *keys, "keys of robot0");
  struct stat info {};
  ASSERT_EQ(::stat(file.c_str(), &info), 0);
  EXPECT_EQ(info.st_mode & 0777, 0600u);
  EXPECT_EQ(*auth::load_keys_file(file).find("robot0"), kRobot0);
  EXPECT_THROW(auth::write_keys_file(file, *keys), std::invalid_argument);
  ::chmod(file.c_str(), 0644);
  auth::write_keys_file(file, *ring({{"player", kPlayer}}), {}, true);
  ASSERT_EQ(::stat(file.c_str(), &info), 0);
  EXPECT_EQ(info.st_mode & 0777, 0600u);  // an overwritten file is private again
  EXPECT_EQ(auth::load_keys_file(file).principals(), std::vector<std::string>{"player"});
}

TEST(AuthKeys, ConfigNeedsAKeyForItsIdentity) {
  auth::Config config{"robot1", ring({{"robot0", kRobot0}, {"server", kServer}})};
  EXPECT_EQ(error_of([&] { config.validate("r.keys"); }),
            "r.keys: no key for 'robot1', the principal this process signs as (see --identity)");
  config.identity = "robot0";
  EXPECT_NO_THROW(config.validate());
  config.replay_window = 100;
  EXPECT_THROW(config.validate(), std::invalid_argument);
  config.replay_window = 1024;
  config.identity = "Robot0";
  EXPECT_THROW(config.validate(), std::invalid_argument);
}

// ---- trailer -----------------------------------------------------------------------

TEST(AuthTrailer, SignVerifyRoundTripLeavesTheLcmEncodingUntouched) {
  const Bytes payload = rt::encode_message(a_local_map(0, 3));
  auth::Signer signer("robot0", kRobot0, 1000);
  Bytes message;
  signer.sign("LMF_LOCAL_MAP", payload, message);
  EXPECT_EQ(signer.next_seq(), 1001u);
  ASSERT_EQ(message.size(), payload.size() + auth::kTrailerFixedBytes + 6);
  EXPECT_TRUE(std::equal(payload.begin(), payload.end(), message.begin()));

  const auto trailer = auth::parse_trailer(message);
  ASSERT_TRUE(trailer.has_value());
  EXPECT_EQ(trailer->payload_size, payload.size());
  EXPECT_EQ(trailer->principal, "robot0");
  EXPECT_EQ(trailer->seq, 1000u);
  EXPECT_EQ(auth::unverified_payload_size(message.data(), message.size()), payload.size());
  EXPECT_EQ(auth::unverified_payload_size(payload.data(), payload.size()), payload.size());

  // What lcm-spy and every lcm-gen decoder do: read the fields, ignore the rest.
  lmf::local_map_t decoded;
  EXPECT_EQ(decoded.decode(message.data(), 0, static_cast<int>(message.size())), static_cast<int>(payload.size()));
  EXPECT_EQ(decoded.seq, 3);

  auth::Verifier verifier(ring({{"robot0", kRobot0}, {"server", kServer}}));
  const auto verified = verifier.verify("LMF_LOCAL_MAP", message);
  ASSERT_TRUE(verified.ok()) << verified.rejection().describe();
  EXPECT_EQ(verified.value().data(), message.data());
  EXPECT_EQ(verified.value().size(), payload.size());
  EXPECT_EQ(verifier.verified(), 1);
}

TEST(AuthTrailer, WrongKeyUnknownSenderOtherChannelAndMissingTrailer) {
  const Bytes payload = rt::encode_message(a_local_map(0, 0));
  Bytes message;
  auth::Signer("robot0", key_of(99), 1).sign("LMF_LOCAL_MAP", payload, message);
  auth::Verifier verifier(ring({{"robot0", kRobot0}, {"server", kServer}}));
  EXPECT_EQ(reason_of(verifier.verify("LMF_LOCAL_MAP", message)), RejectReason::kAuthBadTag);

  auth::Signer("robot0", kRobot0, 2).sign("LMF_LOCAL_MAP", payload, message);
  EXPECT_EQ(reason_of(verifier.verify("LMF_SCAN_ACK", message)), RejectReason::kAuthBadTag);  // moved channel

  auth::Signer("robot5", key_of(5), 3).sign("LMF_LOCAL_MAP", payload, message);
  EXPECT_EQ(reason_of(verifier.verify("LMF_LOCAL_MAP", message)), RejectReason::kAuthUnknownSender);

  EXPECT_EQ(reason_of(verifier.verify("LMF_LOCAL_MAP", payload)), RejectReason::kAuthMissing);
  EXPECT_EQ(reason_of(verifier.verify("LMF_LOCAL_MAP", {})), RejectReason::kAuthMissing);
  EXPECT_EQ(verifier.verified(), 0);
}

TEST(AuthTrailer, EveryFlippedBitIsRejected) {
  const Bytes payload = rt::encode_message(an_ack(1, 7));
  Bytes genuine;
  auth::Signer("server", kServer, 500).sign("LMF_LOCAL_MAP_ACK", payload, genuine);
  const auto keys = ring({{"server", kServer}, {"robot1", kRobot1}});
  for (std::size_t byte = 0; byte < genuine.size(); ++byte) {
    for (int bit = 0; bit < 8; ++bit) {
      Bytes message = genuine;
      message[byte] ^= static_cast<std::uint8_t>(1u << bit);
      auth::Verifier verifier(keys);  // fresh: only the flip can make it fail
      const auto result = verifier.verify("LMF_LOCAL_MAP_ACK", message);
      ASSERT_FALSE(result.ok()) << "byte " << byte << " bit " << bit;
      const RejectReason reason = result.rejection().reason;
      EXPECT_TRUE(reason == RejectReason::kAuthBadTag || reason == RejectReason::kAuthMissing ||
                  reason == RejectReason::kAuthUnknownSender)
          << "byte " << byte << " bit " << bit << ": " << result.rejection().describe();
    }
  }
  // Where the flips land: payload and tag and seq give bad tags.
  const std::size_t seq_at = payload.size() + 6 + 1;
  const std::size_t tag_at = seq_at + 8;
  for (const std::size_t byte : {std::size_t{0}, payload.size() / 2, payload.size() - 1, seq_at + 7, tag_at, tag_at + 31}) {
    Bytes message = genuine;
    message[byte] ^= 0x10;
    EXPECT_EQ(reason_of(auth::Verifier(keys).verify("LMF_LOCAL_MAP_ACK", message)), RejectReason::kAuthBadTag)
        << "byte " << byte;
  }
  EXPECT_TRUE(auth::Verifier(keys).verify("LMF_LOCAL_MAP_ACK", genuine).ok());
}

TEST(AuthTrailer, EveryTruncationAndExtensionIsRejected) {
  const Bytes payload = rt::encode_message(an_ack(1, 7));
  Bytes genuine;
  auth::Signer("server", kServer, 500).sign("LMF_LOCAL_MAP_ACK", payload, genuine);
  const auto keys = ring({{"server", kServer}});
  for (std::size_t size = 0; size < genuine.size(); ++size) {
    const Bytes message(genuine.begin(), genuine.begin() + static_cast<std::ptrdiff_t>(size));
    EXPECT_FALSE(auth::Verifier(keys).verify("LMF_LOCAL_MAP_ACK", message).ok()) << size << " bytes";
  }
  Bytes longer = genuine;
  longer.push_back(0);
  EXPECT_EQ(reason_of(auth::Verifier(keys).verify("LMF_LOCAL_MAP_ACK", longer)), RejectReason::kAuthMissing);
  // A genuine trailer appended twice (the outer one is verified; the payload then has junk).
  Bytes twice = genuine;
  auth::append_trailer(twice, "LMF_LOCAL_MAP_ACK", "server", kServer, 501);
  const auto result = auth::Verifier(keys).verify("LMF_LOCAL_MAP_ACK", twice);
  ASSERT_TRUE(result.ok());  // authentic: the server signed exactly these bytes...
  EXPECT_EQ(result.value().size(), genuine.size());
  EXPECT_FALSE(rt::decode_message<lmf::local_map_ack_t>(result.value().data(), result.value().size()).ok())
      << "...and the decoder refuses the padded payload";
}

// ---- replay window ---------------------------------------------------------------------

TEST(AuthReplayWindow, AcceptsEachNumberOnceAndReorderingWithinTheWindow) {
  auth::ReplayWindow window(64);
  EXPECT_THROW(auth::ReplayWindow(0), std::invalid_argument);
  EXPECT_THROW(auth::ReplayWindow(100), std::invalid_argument);
  EXPECT_FALSE(window.highest().has_value());
  EXPECT_EQ(window.check(1000), auth::ReplayWindow::Verdict::kFresh);
  window.accept(1000);
  EXPECT_EQ(window.check(1000), auth::ReplayWindow::Verdict::kReplayed);
  EXPECT_EQ(window.check(999), auth::ReplayWindow::Verdict::kFresh);    // late, inside the window
  EXPECT_EQ(window.check(937), auth::ReplayWindow::Verdict::kFresh);    // 1000 - 63
  EXPECT_EQ(window.check(936), auth::ReplayWindow::Verdict::kTooOld);   // 1000 - 64
  EXPECT_EQ(window.check(0), auth::ReplayWindow::Verdict::kTooOld);
  window.accept(990);
  EXPECT_EQ(window.check(990), auth::ReplayWindow::Verdict::kReplayed);
  window.accept(1010);  // slides by 10: 990 and 1000 stay known
  EXPECT_EQ(*window.highest(), 1010u);
  EXPECT_EQ(window.check(990), auth::ReplayWindow::Verdict::kReplayed);
  EXPECT_EQ(window.check(1000), auth::ReplayWindow::Verdict::kReplayed);
  EXPECT_EQ(window.check(1005), auth::ReplayWindow::Verdict::kFresh);
  EXPECT_EQ(window.check(946), auth::ReplayWindow::Verdict::kTooOld);
  window.accept(1010 + 63);  // 1010 is now the oldest in the window, 1000 fell out
  EXPECT_EQ(window.check(1010), auth::ReplayWindow::Verdict::kReplayed);
  EXPECT_EQ(window.check(1000), auth::ReplayWindow::Verdict::kTooOld);
  EXPECT_EQ(window.check(1011), auth::ReplayWindow::Verdict::kFresh);
  window.accept(5'000'000);  // a restarted sender: far ahead, everything before is too old
  EXPECT_EQ(window.check(1073), auth::ReplayWindow::Verdict::kTooOld);
  EXPECT_EQ(window.check(5'000'000 - 1), auth::ReplayWindow::Verdict::kFresh);
  EXPECT_EQ(window.check(5'000'000), auth::ReplayWindow::Verdict::kReplayed);
}

TEST(AuthReplayWindow, ShuffledSequenceMatchesASetReference) {
  // Random arrivals (duplicates, reordering, old numbers) against the obvious
  // definition: fresh iff never accepted and within width of the highest.
  std::mt19937_64 rng(7);
  for (const std::size_t width : {64u, 128u, 1024u}) {
    auth::ReplayWindow window(width);
    std::set<std::uint64_t> accepted;
    std::uint64_t highest = 0;
    for (int i = 0; i < 20000; ++i) {
      // Mostly ahead of the sender's progress i/2, sometimes up to 2 widths behind it.
      const std::uint64_t seq = 100000 + static_cast<std::uint64_t>(i) / 2 + rng() % (3 * width) - 2 * width;
      const bool fresh = accepted.empty() || seq > highest || (highest - seq < width && accepted.count(seq) == 0);
      ASSERT_EQ(window.check(seq) == auth::ReplayWindow::Verdict::kFresh, fresh) << "width " << width << " i " << i;
      if (fresh) {
        window.accept(seq);
        accepted.insert(seq);
        highest = std::max(highest, seq);
      }
    }
    EXPECT_GT(accepted.size(), 1000u);
  }
}

TEST(AuthReplayWindow, RefuseThroughMarksEverythingUpToTheMark) {
  auth::ReplayWindow fresh(64);
  fresh.refuse_through(1000);  // a restored window: all of it seen
  EXPECT_EQ(fresh.highest(), 1000u);
  for (std::uint64_t seq = 937; seq <= 1000; ++seq) EXPECT_EQ(fresh.check(seq), auth::ReplayWindow::Verdict::kReplayed);
  EXPECT_EQ(fresh.check(936), auth::ReplayWindow::Verdict::kTooOld);
  EXPECT_EQ(fresh.check(1001), auth::ReplayWindow::Verdict::kFresh);

  auth::ReplayWindow running(64);  // behind what it already saw: the gaps below the mark close
  running.accept(1000);
  running.refuse_through(990);
  for (std::uint64_t seq = 937; seq <= 990; ++seq) EXPECT_EQ(running.check(seq), auth::ReplayWindow::Verdict::kReplayed);
  for (std::uint64_t seq = 991; seq < 1000; ++seq) EXPECT_EQ(running.check(seq), auth::ReplayWindow::Verdict::kFresh);
  running.refuse_through(5);  // long gone: nothing changes
  EXPECT_EQ(running.check(995), auth::ReplayWindow::Verdict::kFresh);

  auth::ReplayWindow small(64);  // marks near zero do not wrap
  small.refuse_through(3);
  for (std::uint64_t seq = 0; seq <= 3; ++seq) EXPECT_EQ(small.check(seq), auth::ReplayWindow::Verdict::kReplayed);
  EXPECT_EQ(small.check(4), auth::ReplayWindow::Verdict::kFresh);
}

TEST(AuthVerifier, RefusesEverythingUpToARestoredHighWaterMark) {
  const auto keys = ring({{"server", kServer}, {"robot0", kRobot0}});
  auth::Signer signer("robot0", kRobot0, 1'700'000'000'000'000);
  std::vector<Bytes> sent(4);
  for (std::size_t i = 0; i < sent.size(); ++i) {
    signer.sign("LMF_LOCAL_MAP", rt::encode_message(a_local_map(0, static_cast<std::int64_t>(i))), sent[i]);
  }
  auth::Verifier before(keys, 64);
  auth::HighWater marks;
  for (std::size_t i = 0; i < 3; ++i) {
    ASSERT_TRUE(before.verify("LMF_LOCAL_MAP", sent[i]).ok());
    const auto signer_of = auth::signed_by(sent[i]);
    ASSERT_TRUE(signer_of.has_value());
    EXPECT_EQ(signer_of->principal, "robot0");
    auth::raise(marks, *signer_of);
  }
  EXPECT_EQ(marks, (auth::HighWater{{"robot0", 1'700'000'000'000'002}}));

  auth::Verifier restarted(keys, 64);
  restarted.refuse_through(marks);
  for (std::size_t i = 0; i < 3; ++i) {
    EXPECT_EQ(reason_of(restarted.verify("LMF_LOCAL_MAP", sent[i])), RejectReason::kAuthReplayed) << i;
  }
  EXPECT_TRUE(restarted.verify("LMF_LOCAL_MAP", sent[3]).ok());
  EXPECT_FALSE(auth::signed_by(rt::encode_message(a_local_map(0, 0))).has_value());
}

TEST(AuthVerifier, RejectsReplaysAndTolerantOfReordering) {
  const auto keys = ring({{"server", kServer}, {"robot0", kRobot0}});
  auth::Verifier verifier(keys, 64);
  auth::Signer signer("robot0", kRobot0, 1'700'000'000'000'000);
  std::vector<Bytes> sent(80);
  for (std::size_t i = 0; i < sent.size(); ++i) {
    signer.sign("LMF_LOCAL_MAP", rt::encode_message(a_local_map(0, static_cast<std::int64_t>(i))), sent[i]);
  }
  // 10..19 arrive in reverse order after 20: all accepted once.
  EXPECT_TRUE(verifier.verify("LMF_LOCAL_MAP", sent[20]).ok());
  for (int i = 19; i >= 10; --i) EXPECT_TRUE(verifier.verify("LMF_LOCAL_MAP", sent[static_cast<std::size_t>(i)]).ok()) << i;
  for (int i = 10; i <= 20; ++i) {
    EXPECT_EQ(reason_of(verifier.verify("LMF_LOCAL_MAP", sent[static_cast<std::size_t>(i)])), RejectReason::kAuthReplayed) << i;
  }
  EXPECT_TRUE(verifier.verify("LMF_LOCAL_MAP", sent[79]).ok());
  EXPECT_EQ(reason_of(verifier.verify("LMF_LOCAL_MAP", sent[16])), RejectReason::kAuthReplayed);  // still in the window
  EXPECT_TRUE(verifier.verify("LMF_LOCAL_MAP", sent[21]).ok());               // 79 - 21 = 58 < 64: late but fresh
  EXPECT_EQ(reason_of(verifier.verify("LMF_LOCAL_MAP", sent[9])), RejectReason::kAuthReplayed);  // older than the window
  EXPECT_EQ(verifier.verified(), 13);
  // A forged copy of a fresh number does not use it up.
  Bytes forged = sent[60];
  forged[20] ^= 1;
  EXPECT_EQ(reason_of(verifier.verify("LMF_LOCAL_MAP", forged)), RejectReason::kAuthBadTag);
  EXPECT_TRUE(verifier.verify("LMF_LOCAL_MAP", sent[60]).ok());
  // Windows are per sender: the server's numbers are independent.
  Bytes ack;
  auth::Signer("server", kServer, 5).sign("LMF_LOCAL_MAP_ACK", rt::encode_message(an_ack(0, 0)), ack);
  EXPECT_TRUE(verifier.verify("LMF_LOCAL_MAP_ACK", ack).ok());
}

// ---- authorization -----------------------------------------------------------------------

template <class Msg>
std::optional<rt::Rejection> may(std::string_view principal, const Msg& msg) {
  return auth::authorize(principal, rt::encode_message(msg));
}

TEST(AuthAuthorize, RobotMessagesOnlyFromThatRobot) {
  lmf::scan_ack_t scan_ack{};
  scan_ack.robot_id = 7;
  lmf::agent_status_t status{};
  status.robot_id = 7;
  for (const Bytes& bytes : {rt::encode_message(a_local_map(7, 0)), rt::encode_message(scan_ack),
                             rt::encode_message(status)}) {
    EXPECT_FALSE(auth::authorize("robot7", bytes).has_value());
    for (const char* other : {"robot1", "robot70", "server", "player", "monitor", "logger"}) {
      const auto refused = auth::authorize(other, bytes);
      ASSERT_TRUE(refused.has_value()) << other;
      EXPECT_EQ(refused->reason, RejectReason::kAuthNotAllowed);
    }
  }
  EXPECT_EQ(may("robot1", a_local_map(2, 0))->detail, "'robot1' may not send local_map_t for robot 2");
  EXPECT_EQ(may("player", a_local_map(2, 0))->detail, "'player' may not send local_map_t (only robot<N>)");
}

TEST(AuthAuthorize, ServerAndPlayerMessages) {
  lmf::corrected_frames_t frames{};
  lmf::global_map_t map{};
  lmf::server_status_t server_status{};
  lmf::sighting_ack_t sighting_ack{};
  for (const Bytes& bytes : {rt::encode_message(an_ack(0, 0)), rt::encode_message(frames), rt::encode_message(map),
                             rt::encode_message(server_status), rt::encode_message(sighting_ack)}) {
    EXPECT_FALSE(auth::authorize("server", bytes).has_value());
    for (const char* other : {"robot0", "player", "monitor"}) EXPECT_TRUE(auth::authorize(other, bytes).has_value());
  }
  lmf::laser_scan_t scan{};
  lmf::sighting_t sighting{};
  lmf::mission_end_t end{};
  for (const Bytes& bytes : {rt::encode_message(scan), rt::encode_message(sighting), rt::encode_message(end)}) {
    EXPECT_FALSE(auth::authorize("player", bytes).has_value());
    for (const char* other : {"robot0", "server", "monitor"}) EXPECT_TRUE(auth::authorize(other, bytes).has_value());
  }
  EXPECT_EQ(may("robot0", scan)->detail, "'robot0' may not send laser_scan_t (only player)");
  EXPECT_EQ(may("player", an_ack(0, 0))->detail, "'player' may not send local_map_ack_t (only server)");
  // Unknown types and non-messages: nobody.
  lmf::pose2_t pose{};
  EXPECT_NE(may("server", pose)->detail.find("unknown type"), std::string::npos);
  EXPECT_TRUE(auth::authorize("server", Bytes{1, 2, 3}).has_value());
  Bytes truncated = rt::encode_message(a_local_map(0, 0));
  truncated.resize(18);
  EXPECT_EQ(auth::authorize("robot0", truncated)->detail, "'robot0' sent a truncated local_map_t");
}

TEST(AuthVerifier, AuthorizationFollowsVerification) {
  const auto keys = ring({{"robot0", kRobot0}, {"robot1", kRobot1}, {"server", kServer}});
  auth::Verifier verifier(keys);
  Bytes message;
  auth::Signer robot1("robot1", kRobot1, 10);
  robot1.sign("LMF_LOCAL_MAP", rt::encode_message(a_local_map(0, 5)), message);  // robot1 claims robot 0's map
  EXPECT_EQ(reason_of(verifier.verify("LMF_LOCAL_MAP", message)), RejectReason::kAuthNotAllowed);
  robot1.sign("LMF_LOCAL_MAP", rt::encode_message(a_local_map(1, 5)), message);
  EXPECT_TRUE(verifier.verify("LMF_LOCAL_MAP", message).ok());
}

// ---- the Bus -------------------------------------------------------------------------------

TEST(AuthBus, SignsVerifiesAndStripsOverMemq) {
  const auto server_keys = ring({{"server", kServer}, {"robot0", kRobot0}, {"robot1", kRobot1}});
  const auto robot0_keys = ring({{"robot0", kRobot0}, {"server", kServer}});
  rt::Bus network("memq://");
  ASSERT_TRUE(network.good());
  rt::Bus server(network, auth::Config{"server", server_keys});
  rt::Bus robot0(network, auth::Config{"robot0", robot0_keys});
  rt::Bus robot1_forger(network, auth::Config{"robot1", ring({{"robot1", kRobot1}})});
  rt::Bus outsider(network, std::nullopt);
  EXPECT_EQ(*server.identity(), "server");
  EXPECT_TRUE(server.authenticated());
  EXPECT_EQ(outsider.identity(), nullptr);
  EXPECT_THROW(rt::Bus(network, auth::Config{"robot2", robot0_keys}), std::invalid_argument);

  std::vector<std::int64_t> maps_at_server;
  server.subscribe_message<lmf::local_map_t>(
      "LMF_LOCAL_MAP", [&](const std::string&, const lmf::local_map_t& m) { maps_at_server.push_back(m.seq); });
  std::vector<std::int64_t> acks_at_robot0, acks_at_outsider;
  robot0.subscribe_message<lmf::local_map_ack_t>(
      "LMF_LOCAL_MAP_ACK", [&](const std::string&, const lmf::local_map_ack_t& a) { acks_at_robot0.push_back(a.seq); });
  outsider.subscribe_message<lmf::local_map_ack_t>(
      "LMF_LOCAL_MAP_ACK", [&](const std::string&, const lmf::local_map_ack_t& a) { acks_at_outsider.push_back(a.seq); });
  std::vector<Bytes> captured;  // what is on the wire
  network.lcm().subscribeFunction(
      "LMF_LOCAL_MAP",
      +[](const lcm::ReceiveBuffer* b, const std::string&, std::vector<Bytes>* out) {
        const auto* p = static_cast<const std::uint8_t*>(b->data);
        out->emplace_back(p, p + b->data_size);
      },
      &captured);

  ASSERT_TRUE(robot0.publish("LMF_LOCAL_MAP", a_local_map(0, 0)));
  ASSERT_TRUE(server.publish("LMF_LOCAL_MAP_ACK", an_ack(0, 0)));
  ASSERT_TRUE(outsider.publish("LMF_LOCAL_MAP", a_local_map(0, 1)));        // unsigned
  ASSERT_TRUE(robot1_forger.publish("LMF_LOCAL_MAP", a_local_map(0, 2)));   // robot1 as robot 0
  ASSERT_TRUE(outsider.publish("LMF_LOCAL_MAP_ACK", an_ack(0, 9)));         // unsigned ack
  network.handle_pending();
  ASSERT_EQ(captured.size(), 3u);
  network.lcm().publish("LMF_LOCAL_MAP", captured[0].data(), static_cast<unsigned>(captured[0].size()));  // replay
  network.handle_pending();

  EXPECT_EQ(maps_at_server, std::vector<std::int64_t>{0});
  EXPECT_EQ(acks_at_robot0, std::vector<std::int64_t>{0});
  EXPECT_EQ(acks_at_outsider, (std::vector<std::int64_t>{0, 9}));  // no keys: reads both, trailer removed
  EXPECT_EQ(server.rejects().count(RejectReason::kAuthMissing), 1);
  EXPECT_EQ(server.rejects().count(RejectReason::kAuthUnknownSender), 0);
  EXPECT_EQ(server.rejects().count(RejectReason::kAuthNotAllowed), 1);
  EXPECT_EQ(server.rejects().count(RejectReason::kAuthReplayed), 1);
  EXPECT_EQ(server.rejects().count(RejectReason::kDecodeFailed), 0);
  EXPECT_EQ(robot0.rejects().count(RejectReason::kAuthMissing), 1);
  EXPECT_EQ(server.messages_verified(), 1);  // robot0's map; robot1's had a valid tag but was not allowed
  EXPECT_EQ(outsider.rejects().total(), 0);
  // The signed message on the wire starts with the unchanged LCM encoding.
  const Bytes plain = rt::encode_message(a_local_map(0, 0));
  EXPECT_TRUE(std::equal(plain.begin(), plain.end(), captured[0].begin()));
}

TEST(AuthOptions, KeysAndIdentityFlags) {
  TempDir dir;
  const auto file = dir.write("agent.keys", "robot3 " + auth::to_hex(kRobot0) + "\nserver " + auth::to_hex(kServer) + "\n");
  rt::CommonOptions options;
  EXPECT_FALSE(rt::auth_config(options, "robot3").has_value());
  boost::program_options::options_description description("Options");
  rt::add_common_options(description, options);
  const std::string keys = file.string();
  const char* argv[] = {"prog", "--keys", keys.c_str()};
  ASSERT_EQ(rt::parse_options(3, argv, description, "prog", "Test.").status, rt::ParseResult::Status::kOk);
  const auto config = rt::auth_config(options, "robot3");
  ASSERT_TRUE(config.has_value());
  EXPECT_EQ(config->identity, "robot3");
  EXPECT_EQ(config->keys->size(), 2u);
  EXPECT_EQ(error_of([&] { rt::auth_config(options, "robot4"); }),
            keys + ": no key for 'robot4', the principal this process signs as (see --identity)");
  options.identity = "server";
  EXPECT_EQ(rt::auth_config(options, "robot3")->identity, "server");
  options.keys_file.clear();
  EXPECT_EQ(error_of([&] { rt::auth_config(options, "robot3"); }), "--identity needs --keys");
}

}  // namespace
