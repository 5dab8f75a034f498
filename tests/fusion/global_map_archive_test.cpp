// GlobalMap archive: a map read back continues bit-identically to the original
// (queued local maps, pending sightings, frame history and all), and short,
// corrupt or unknown-version archives are rejected with ArchiveError.
#include "lmf/fusion/global_map_archive.hpp"

#include <cstring>
#include <random>
#include <sstream>
#include <string>
#include <vector>

#include <gtest/gtest.h>

#include "fusion/synthetic_maps.hpp"

namespace lmf::fusion {
namespace {

using synthetic::Wall;

std::string archive_bytes(const GlobalMap& map) {
  std::ostringstream out;
  write_archive(map, out);
  return out.str();
}

GlobalMap from_bytes(const std::string& bytes) {
  std::istringstream in(bytes);
  return read_archive(in);
}

// A report's bytes without its wall-clock times (they differ run to run).
std::string report_bytes(FusionReport r) {
  r.time = PhaseTimes{};
  std::string s;
  ArchiveWriter w(s);
  write_fusion_report(w, r);
  return s;
}

std::string reports_bytes(const std::vector<FusionReport>& reports) {
  std::string s;
  for (const FusionReport& r : reports) s += report_bytes(r);
  return s;
}

std::vector<Wall> subset(const std::vector<Wall>& walls, std::initializer_list<int> indices) {
  std::vector<Wall> out;
  for (const int i : indices) out.push_back(walls[static_cast<std::size_t>(i)]);
  return out;
}

Pose2 frame_after(const Pose2& x_WL0, const Pose2& step, int k) {
  Pose2 x = x_WL0;
  for (int i = 0; i < k; ++i) x = compose(x, step);
  return x;
}

// The robots of the scenario: true first frame and per-map motion.
struct Robot {
  int id;
  Pose2 x_WL0;
  Pose2 step;
};
const std::vector<Wall>& walls() {
  static const std::vector<Wall> w = synthetic::room(0.0, 0.0, 12.0, 8.0, 4);  // 16 walls
  return w;
}
const Robot kRobot0{0, Pose2(), Pose2(0.9, 0.2, 0.15)};
const Robot kRobot1{1, Pose2(-3.0, 2.0, -1.0), Pose2(0.8, 0.3, 0.2)};
const Robot kRobot3{3, Pose2(2.0, 1.0, 0.0), Pose2(0.5, 0.0, 0.1)};

// Noisy (consistent) local map `seq` of `robot` seeing `wall_indices`.
LocalMapSnapshot local_map(const Robot& robot, int seq, std::initializer_list<int> wall_indices, std::mt19937& rng) {
  return synthetic::make_snapshot(robot.id, seq, frame_after(robot.x_WL0, robot.step, seq), robot.step,
                                  subset(walls(), wall_indices), {}, &rng);
}

RobotSighting sighting(const Robot& observer, int observer_seq, const Robot& observed, int observed_seq) {
  RobotSighting s;
  s.utime = 1000 * observer_seq + observed.id;
  s.observer_id = observer.id;
  s.observed_id = observed.id;
  s.observer_seq = observer_seq;
  s.x_LA = Pose2(0.3, 0.05, 0.02);
  s.cov_LA = Eigen::Vector3d(1e-4, 1e-4, 1e-5).asDiagonal();
  s.observed_seq = observed_seq;
  s.x_LB = Pose2(0.2, -0.1, 0.03);
  s.cov_LB = Eigen::Vector3d(2e-4, 2e-4, 2e-5).asDiagonal();
  const Pose2 x_WA = compose(frame_after(observer.x_WL0, observer.step, observer_seq), s.x_LA);
  const Pose2 x_WB = compose(frame_after(observed.x_WL0, observed.step, observed_seq), s.x_LB);
  s.x_AB = between(x_WA, x_WB);
  s.cov_AB = Eigen::Vector3d(0.01, 0.01, 0.001).asDiagonal();
  return s;
}

// Before the archive: robot 0 maps (one local map out of order, so queued),
// robot 1 and robot 3 ship maps before anyone saw them (queued), robot 2 (not
// there yet) saw robot 3 (pending).
void first_half(GlobalMap& map, std::mt19937& rng) {
  map.fuse(local_map(kRobot0, 0, {0, 1, 2, 3, 15}, rng));
  map.fuse(local_map(kRobot0, 1, {1, 2, 3, 4, 5}, rng));
  map.fuse(local_map(kRobot0, 2, {4, 5, 6, 7}, rng));
  map.fuse(local_map(kRobot0, 3, {6, 7, 8, 9}, rng));
  EXPECT_TRUE(map.fuse(local_map(kRobot0, 5, {10, 11, 12}, rng)).empty());
  EXPECT_TRUE(map.fuse(local_map(kRobot1, 0, {0, 1, 14, 15}, rng)).empty());
  EXPECT_TRUE(map.fuse(local_map(kRobot1, 1, {0, 13, 14}, rng)).empty());
  EXPECT_TRUE(map.fuse(local_map(kRobot3, 0, {2, 3, 4}, rng)).empty());
  RobotSighting s = sighting(kRobot0, 0, kRobot3, 0);
  s.observer_id = 2;  // a robot that has not joined (it will at robot 0's origin): the sighting waits
  EXPECT_EQ(map.add_sighting(s).status, SightingStatus::kPending);
}

// After the archive: everything that was waiting gets resolved, plus more maps.
// Returns the bytes of every report and status, in order.
std::string second_half(GlobalMap& map, std::mt19937& rng) {
  std::string log;
  log += reports_bytes(map.fuse(local_map(kRobot0, 4, {8, 9, 10, 11}, rng)));  // unblocks 5
  const SightingResult joined1 = map.add_sighting(sighting(kRobot0, 5, kRobot1, 2));
  log += std::to_string(static_cast<int>(joined1.status)) + reports_bytes(joined1.fused);
  log += reports_bytes(map.fuse(local_map(kRobot1, 2, {12, 13, 14, 15}, rng)));
  log += reports_bytes(map.join_robot(2, Pose2(), Eigen::Matrix3d::Identity() * 1e-3));
  log += reports_bytes(map.fuse(local_map(kRobot3, 1, {4, 5, 6}, rng)));
  log += reports_bytes(map.fuse(local_map(kRobot0, 6, {12, 13, 14, 15, 0}, rng)));
  log += reports_bytes(map.fuse(local_map(kRobot1, 3, {0, 1, 2}, rng)));
  return log;
}

TEST(GlobalMapArchiveTest, RestoredMapContinuesBitIdentically) {
  GlobalMapConfig config;
  config.health = HealthCheck::kFullLdlt;
  config.frame_history_per_robot = 3;
  config.footprint_radius_m = 0.35;  // the scan poses' footprints are archived too
  config.crossing_margin_m = 0.15;
  config.crossing_max_angle_rad = 0.9;
  config.registration.window_m = 1.2;  // every registration field is archived
  config.registration.window_rad = 0.08;
  config.registration.resolution_m = 0.04;
  config.registration.min_score = 0.35;
  config.registration.ambiguity_ratio = 0.85;
  config.registration.min_constraint = 0.06;
  config.registration.own_recent_maps = 5;
  config.registration.confirm_pairings = false;
  GlobalMap original(config);
  std::mt19937 rng(7);
  first_half(original, rng);
  ASSERT_GT(original.queued_count(), 0);
  ASSERT_GT(original.counts().segments, 0);

  const std::string bytes = archive_bytes(original);
  GlobalMap restored = from_bytes(bytes);
  // Everything the archive holds came back: writing it again gives the same bytes.
  EXPECT_EQ(archive_bytes(restored), bytes);
  EXPECT_TRUE(same_config(restored.config(), original.config()));
  EXPECT_EQ(restored.state().capacity(), original.state().capacity());
  EXPECT_EQ(restored.queued_count(), original.queued_count());
  EXPECT_TRUE(restored.state().full_covariance() == original.state().full_covariance());

  // The same inputs into both: identical reports and identical maps, bit for bit.
  std::mt19937 rng_a = rng;
  std::mt19937 rng_b = rng;
  const std::string log_original = second_half(original, rng_a);
  const std::string log_restored = second_half(restored, rng_b);
  EXPECT_EQ(log_restored, log_original);
  EXPECT_EQ(restored.queued_count(), 0);
  EXPECT_TRUE(restored.is_joined(1));
  EXPECT_TRUE(restored.is_joined(3));
  EXPECT_EQ(archive_bytes(restored), archive_bytes(original));
  const std::vector<SegmentView> a = original.segments();
  const std::vector<SegmentView> b = restored.segments();
  ASSERT_EQ(a.size(), b.size());
  for (std::size_t i = 0; i < a.size(); ++i) {
    EXPECT_EQ(std::memcmp(&a[i].x_WS, &b[i].x_WS, sizeof(Pose2)), 0) << "segment " << i;
    EXPECT_TRUE(a[i].covariance == b[i].covariance);
  }
}

TEST(GlobalMapArchiveTest, EmptyMapRoundTrips) {
  GlobalMap map;
  GlobalMap restored = from_bytes(archive_bytes(map));
  EXPECT_EQ(restored.counts().segments, 0);
  EXPECT_EQ(archive_bytes(restored), archive_bytes(map));
}

TEST(GlobalMapArchiveTest, TruncatedArchivesAreRejected) {
  GlobalMap map;
  std::mt19937 rng(3);
  first_half(map, rng);
  const std::string bytes = archive_bytes(map);
  // Every prefix is rejected (a step keeps the test fast; both ends densely).
  for (std::size_t n = 0; n < bytes.size(); n += (n < 64 || n + 64 > bytes.size()) ? 1 : 97) {
    EXPECT_THROW(from_bytes(bytes.substr(0, n)), ArchiveError) << n << " of " << bytes.size() << " bytes";
  }
  try {
    from_bytes(bytes.substr(0, bytes.size() / 2));
    FAIL() << "a half archive was accepted";
  } catch (const ArchiveError& e) {
    EXPECT_NE(std::string(e.what()).find("truncated"), std::string::npos) << e.what();
  }
}

TEST(GlobalMapArchiveTest, CorruptedArchivesAreRejected) {
  GlobalMap map;
  std::mt19937 rng(4);
  first_half(map, rng);
  const std::string bytes = archive_bytes(map);
  // Any flipped bit, in the header, a count, a double or the checksum.
  for (std::size_t i = 0; i < bytes.size(); i += 53) {
    std::string bad = bytes;
    bad[i] = static_cast<char>(bad[i] ^ 0x10);
    EXPECT_THROW(from_bytes(bad), ArchiveError) << "byte " << i;
  }
  std::string tail = bytes;
  tail.back() = static_cast<char>(tail.back() ^ 1);
  EXPECT_THROW(from_bytes(tail), ArchiveError);
  // Extra bytes after the archive's own checksum are not part of it, but a
  // payload with bytes after the map is corrupt even with a good checksum.
  std::string payload;
  ArchiveWriter w(payload);
  write_global_map(w, map);
  w.u8(0);
  std::ostringstream framed;
  write_framed(framed, std::string_view("LMFGMAP\0", 8), kGlobalMapArchiveVersion, payload);
  EXPECT_THROW(from_bytes(framed.str()), ArchiveError);
}

TEST(GlobalMapArchiveTest, BrokenInvariantsAreRejectedEvenWithAGoodChecksum) {
  GlobalMap map;
  std::mt19937 rng(5);
  first_half(map, rng);
  std::string payload;
  ArchiveWriter w(payload);
  write_global_map(w, map);
  // The first entity's offset sits after the config (11 f64 + 2 u8 + i32 + 3 f64
  // + the registration's u8 + 6 f64 + i32 + u8 + place recognition's u8 +
  // 2 f64 + i32 = 193 bytes), next_id, n, capacity, count (32) and its id,
  // kind, pose, length, parent flag and parent (58 - 8 bytes): set it to 1.
  const std::size_t offset_at = 193 + 32 + 50;
  std::int64_t offset = 0;
  std::memcpy(&offset, payload.data() + offset_at, sizeof offset);
  ASSERT_EQ(offset, 0);
  offset = 1;
  std::memcpy(payload.data() + offset_at, &offset, sizeof offset);
  std::ostringstream framed;
  write_framed(framed, std::string_view("LMFGMAP\0", 8), kGlobalMapArchiveVersion, payload);
  try {
    from_bytes(framed.str());
    FAIL() << "a map with a bad entity offset was accepted";
  } catch (const ArchiveError& e) {
    EXPECT_NE(std::string(e.what()).find("offset"), std::string::npos) << e.what();
  }
}

TEST(GlobalMapArchiveTest, UnknownVersionAndForeignFilesAreRejected) {
  const std::string bytes = archive_bytes(GlobalMap());
  std::string future = bytes;
  const std::uint32_t version = kGlobalMapArchiveVersion + 1;
  std::memcpy(future.data() + 8, &version, sizeof version);
  try {
    from_bytes(future);
    FAIL() << "a future version was accepted";
  } catch (const ArchiveError& e) {
    EXPECT_NE(std::string(e.what()).find("unknown version"), std::string::npos) << e.what();
  }
  // An older archive is refused by name, never parsed with this build's layout.
  std::string older = bytes;
  const std::uint32_t previous = kGlobalMapArchiveVersion - 1;
  std::memcpy(older.data() + 8, &previous, sizeof previous);
  try {
    from_bytes(older);
    FAIL() << "an older version was accepted";
  } catch (const ArchiveError& e) {
    EXPECT_NE(std::string(e.what()).find("older version"), std::string::npos) << e.what();
  }
  EXPECT_THROW(from_bytes("not an archive at all, just some text that is long enough"), ArchiveError);
  EXPECT_THROW(from_bytes(""), ArchiveError);
}

TEST(GlobalMapArchiveTest, SameConfigComparesEveryField) {
  GlobalMapConfig a;
  GlobalMapConfig b;
  EXPECT_TRUE(same_config(a, b));
  b.gate_sigmas = std::nextafter(b.gate_sigmas, 10.0);
  EXPECT_FALSE(same_config(a, b));
  b = a;
  b.health = HealthCheck::kNone;
  EXPECT_FALSE(same_config(a, b));
  b = a;
  b.frame_history_per_robot = 1;
  EXPECT_FALSE(same_config(a, b));
  b = a;
  b.crossing_max_angle_rad = 1.0;
  EXPECT_FALSE(same_config(a, b));
  b = a;
  b.registration.enabled = false;
  EXPECT_FALSE(same_config(a, b));
  b = a;
  b.registration.min_constraint = 0.1;
  EXPECT_FALSE(same_config(a, b));
}

}  // namespace
}  // namespace lmf::fusion
