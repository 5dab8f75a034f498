// read_bag_scans against bags written by write_scan_bag (ROS 1 through
// librosbag-storage, and MCAP): the scans, their odometry and the laser's mounting come
// back as they went in, from /odom or from /tf, compressed or not.
#include <gtest/gtest.h>

#include <cmath>
#include <filesystem>
#include <fstream>

#include "lmf/bag/bag_file.hpp"
#include "lmf/bag/bag_scans.hpp"
#include "lmf/bag/ros1_bag_writer.hpp"
#include "lmf/bag/scan_bag_export.hpp"
#include "lmf/bag/wire_encoder.hpp"
#include "lmf/io/carmen.hpp"
#include "test_support.hpp"

namespace lmf::bag {
namespace {

class TempDir {
 public:
  TempDir() : path_(std::filesystem::temp_directory_path() / ("lmf-bag-test-" + std::to_string(::getpid()) + "-" +
                                                              std::to_string(counter_++))) {
    std::filesystem::create_directories(path_);
  }
  ~TempDir() { std::filesystem::remove_all(path_); }
  const std::filesystem::path& path() const { return path_; }

 private:
  static inline int counter_ = 0;
  std::filesystem::path path_;
};

std::vector<LaserScan> synthetic_scans(int n) {
  std::vector<LaserScan> scans;
  for (int k = 0; k < n; ++k) {
    LaserScan s;
    s.utime = 1'000'000 + 250'000 * k;
    s.odometry = Pose2(0.1 * k, 0.02 * k * k, wrap_angle(0.3 * k));
    s.angle_min_rad = -M_PI / 2;
    s.angle_increment_rad = M_PI / 180;
    s.max_range_m = 30.0;
    for (int i = 0; i < 181; ++i) s.ranges_m.push_back(1.0 + 0.01 * i + k);
    scans.push_back(at_message_precision(s));
  }
  return scans;
}

// The odometry bit for bit where the laser sits at the base's origin; through a
// mounting, composed there and back, to `odometry_tolerance`.
void expect_same_scans(const std::vector<LaserScan>& read, const std::vector<LaserScan>& written,
                       double odometry_tolerance = 0.0) {
  ASSERT_EQ(read.size(), written.size());
  for (std::size_t k = 0; k < read.size(); ++k) {
    const LaserScan expected = at_message_precision(written[k]);
    EXPECT_EQ(read[k].utime, expected.utime) << k;
    EXPECT_EQ(read[k].ranges_m, expected.ranges_m) << k;
    EXPECT_EQ(read[k].angle_min_rad, expected.angle_min_rad) << k;
    EXPECT_EQ(read[k].angle_increment_rad, expected.angle_increment_rad) << k;
    EXPECT_EQ(read[k].max_range_m, expected.max_range_m) << k;
    if (odometry_tolerance == 0.0) {
      EXPECT_EQ(read[k].odometry.x, expected.odometry.x) << k;
      EXPECT_EQ(read[k].odometry.y, expected.odometry.y) << k;
      EXPECT_EQ(read[k].odometry.phi, expected.odometry.phi) << k;
    } else {
      EXPECT_TRUE(is_near(read[k].odometry, expected.odometry, odometry_tolerance, odometry_tolerance))
          << k << ": " << read[k].odometry.x << " " << read[k].odometry.y << " " << read[k].odometry.phi;
    }
  }
}

TEST(BagScans, ScansAndOdometryComeBackFromOdomAndFromTf) {
  TempDir dir;
  const auto scans = synthetic_scans(12);
  const std::vector<std::pair<BagFormat, std::string>> kinds = {
      {BagFormat::ros1, "none"}, {BagFormat::ros1, "bz2"}, {BagFormat::ros1, "lz4"},
      {BagFormat::mcap, "none"}, {BagFormat::mcap, "zstd"}};
  for (const bool as_tf : {false, true}) {
    for (const auto& [format, compression] : kinds) {
      const auto file = dir.path() / (format == BagFormat::mcap ? "scans.mcap" : "scans.bag");
      ScanBagExportOptions options;
      options.format = format;
      options.compression = compression;
      options.odometry_as_tf = as_tf;
      write_scan_bag(file, scans, std::nullopt, options);
      SCOPED_TRACE(std::string(to_string(format)) + " " + compression + (as_tf ? " tf" : " odom"));
      EXPECT_EQ(summarize_bag(file).format, format);
      expect_same_scans(read_bag_scans(file).scans, scans);
    }
  }
}

TEST(BagScans, TheLaserMountingFromTfStaticGivesTheLasersOdometry) {
  TempDir dir;
  const auto scans = synthetic_scans(5);
  const Pose2 x_BL(0.25, -0.05, 0.1);
  write_scan_bag(dir.path() / "mounted.bag", scans, x_BL);
  const BagScans read = read_bag_scans(dir.path() / "mounted.bag");
  expect_same_scans(read.scans, scans, 1e-12);
  // Given instead of read: the same.
  BagScanOptions given;
  given.laser_mounting = x_BL;
  expect_same_scans(read_bag_scans(dir.path() / "mounted.bag", given).scans, scans, 1e-12);
  // Ignoring it (the identity given) leaves the base's poses, which differ.
  given.laser_mounting = Pose2{};
  EXPECT_FALSE(is_near(read_bag_scans(dir.path() / "mounted.bag", given).scans[1].odometry, scans[1].odometry, 0.01,
                       0.01));
}

// A bag written message by message: odometry at t = 1 and 2 s, one scan at 1.25 s.
std::filesystem::path handmade_bag(const std::filesystem::path& dir, const RosLaserScan& scan,
                                   const std::optional<RosTransform>& mount) {
  const auto file = dir / "handmade.bag";
  Ros1BagWriter bag(file, Ros1BagWriter::Compression::none);
  if (mount) bag.write("/tf_static", "tf2_msgs/TFMessage", 1, encode_tf_message({*mount}, MessageEncoding::ros1));
  for (int k = 0; k < 2; ++k) {
    RosOdometry o;
    o.header = {(k + 1) * 1'000'000'000LL, "odom"};
    o.child_frame_id = "base";
    o.pose.translation = {k * 1.0, 0.0, 0.0};
    o.pose.rotation = Eigen::Quaterniond(Eigen::AngleAxisd(k * 0.4, Eigen::Vector3d::UnitZ()));
    bag.write("/odom", "nav_msgs/Odometry", o.header.stamp_ns + 1, encode_odometry(o, MessageEncoding::ros1));
  }
  bag.write("/scan", "sensor_msgs/LaserScan", 1'250'000'001, encode_laser_scan(scan, MessageEncoding::ros1));
  bag.close();
  return file;
}

RosLaserScan three_beams() {
  RosLaserScan s;
  s.header = {1'250'000'000, "laser"};
  s.angle_min = 0.5f;
  s.angle_increment = -0.5f;  // clockwise
  s.angle_max = -0.5f;
  s.range_min = 0.1f;
  s.range_max = 10.0f;
  s.ranges = {1.0f, std::nanf(""), 3.0f};
  return s;
}

TEST(BagScans, OdometryIsInterpolatedAtTheScansStampAndClockwiseScansAreReversed) {
  TempDir dir;
  const BagScans read = read_bag_scans(handmade_bag(dir.path(), three_beams(), std::nullopt));
  ASSERT_EQ(read.scans.size(), 1u);
  const LaserScan& s = read.scans[0];
  EXPECT_EQ(s.utime, 1'250'000);
  EXPECT_TRUE(is_near(s.odometry, Pose2(0.25, 0.0, 0.1), 1e-12, 1e-12)) << s.odometry.x << " " << s.odometry.y << " " << s.odometry.phi;
  EXPECT_NEAR(s.angle_min_rad, -0.5, 1e-7);
  EXPECT_NEAR(s.angle_increment_rad, 0.5, 1e-7);
  EXPECT_EQ(s.ranges_m, (std::vector<double>{3.0, 10.0, 1.0}));  // NaN: no return
  EXPECT_EQ(read.no_return_readings, 1u);
}

TEST(BagScans, ALaserMountedUpsideDownIsMirrored) {
  TempDir dir;
  RosTransform mount;
  mount.header = {0, "base"};
  mount.child_frame_id = "laser";
  mount.transform.rotation = Eigen::Quaterniond(Eigen::AngleAxisd(M_PI, Eigen::Vector3d::UnitX()));
  const BagScans read = read_bag_scans(handmade_bag(dir.path(), three_beams(), mount));
  ASSERT_EQ(read.scans.size(), 1u);
  // The clockwise beam at +0.5 rad (range 1) is, seen from above, at -0.5 rad.
  const LaserScan& s = read.scans[0];
  EXPECT_NEAR(s.angle_min_rad, -0.5, 1e-7);
  EXPECT_EQ(s.ranges_m, (std::vector<double>{1.0, 10.0, 3.0}));
}

TEST(BagScans, AScanOutsideTheOdometrysSpanIsDroppedAndCounted) {
  TempDir dir;
  RosLaserScan late = three_beams();
  late.header.stamp_ns = 3'000'000'000;
  const BagScans read = read_bag_scans(handmade_bag(dir.path(), late, std::nullopt));
  EXPECT_TRUE(read.scans.empty());
  EXPECT_EQ(read.scans_outside_odometry, 1u);
}

TEST(BagScans, ATopicThatIsNotThereIsNamedWithWhatThereIs) {
  TempDir dir;
  const auto file = handmade_bag(dir.path(), three_beams(), std::nullopt);
  BagScanOptions options;
  options.scan_topic = "/front_scan";
  try {
    read_bag_scans(file, options);
    FAIL() << "read";
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find("/front_scan"), std::string::npos);
    EXPECT_NE(std::string(e.what()).find("/scan (sensor_msgs/LaserScan)"), std::string::npos);
  }
}

TEST(BagScans, ADatasetComesBackScanForScanFromRos1AndMcap) {
  LMF_REQUIRE_DATASETS(datasets);
  TempDir dir;
  const io::CarmenLog log = io::read_carmen_log(datasets / "orebro-realodo.log.gz");
  write_scan_bag(dir.path() / "orebro.bag", log.scans, log.laser_mounting.x_RS, {BagFormat::ros1, "lz4", false});
  expect_same_scans(read_bag_scans(dir.path() / "orebro.bag").scans, log.scans);
  write_scan_bag(dir.path() / "orebro.mcap", log.scans, log.laser_mounting.x_RS, {BagFormat::mcap, "zstd", false});
  expect_same_scans(read_bag_scans(dir.path() / "orebro.mcap").scans, log.scans);
}

}  // namespace
}  // namespace lmf::bag

namespace lmf::bag {
namespace {

TEST(BagScans, ARos1BagCutShortByAKilledRecorderIsReadUpToTheCut) {
  TempDir dir;
  const auto file = dir.path() / "whole.bag";
  write_scan_bag(file, synthetic_scans(2000), std::nullopt, {BagFormat::ros1, "none", false});  // ~4 chunks
  std::vector<char> bytes;
  {
    std::ifstream in(file, std::ios::binary);
    bytes.assign(std::istreambuf_iterator<char>(in), {});
  }
  // As a killed recorder leaves it: the header's index_pos still 0, a chunk cut in the middle.
  const std::string index_pos = "index_pos=";
  const auto field = std::search(bytes.begin(), bytes.end(), index_pos.begin(), index_pos.end());
  ASSERT_NE(field, bytes.end());
  std::fill_n(field + static_cast<std::ptrdiff_t>(index_pos.size()), 8, '\0');
  bytes.resize(bytes.size() / 2);
  const auto cut = dir.path() / "cut.bag";
  std::ofstream(cut, std::ios::binary).write(bytes.data(), static_cast<std::streamsize>(bytes.size()));
  const BagSummary summary = summarize_bag(cut);
  ASSERT_TRUE(summary.cut_short);
  EXPECT_NE(summary.cut_short->find("no index"), std::string::npos) << *summary.cut_short;
  const BagScans read = read_bag_scans(cut);
  EXPECT_GT(read.scans.size(), 0u);
  EXPECT_LT(read.scans.size(), 2000u);
  bool noted = false;
  for (const auto& note : read.notes) noted = noted || note.starts_with("CUT SHORT");
  EXPECT_TRUE(noted);
}

}  // namespace
}  // namespace lmf::bag

namespace lmf::bag {
namespace {

TEST(BagScans, SeveralRobotsInOneBagAreReadByNamespace) {
  TempDir dir;
  std::vector<LaserScan> other = synthetic_scans(8);
  for (auto& scan : other) {
    scan.odometry = compose(Pose2(5.0, -1.0, 0.5), scan.odometry);
    for (double& r : scan.ranges_m) r += 0.5;
  }
  const Pose2 mount(0.2, 0.0, 0.0);
  for (const bool as_tf : {false, true}) {
    for (const BagFormat format : {BagFormat::ros1, BagFormat::mcap}) {
      const auto file = dir.path() / (format == BagFormat::mcap ? "robots.mcap" : "robots.bag");
      write_scan_bag(file, {{"/robot1", synthetic_scans(10), std::nullopt}, {"/robot2", other, mount}},
                     {format, "none", as_tf});
      SCOPED_TRACE(std::string(to_string(format)) + (as_tf ? " tf" : " odom"));
      EXPECT_THROW(read_bag_scans(file), std::invalid_argument);  // two LaserScan topics: which robot?
      BagScanOptions first;
      first.robot_namespace = "/robot1";
      expect_same_scans(read_bag_scans(file, first).scans, synthetic_scans(10));
      BagScanOptions second;
      second.robot_namespace = "robot2";
      expect_same_scans(read_bag_scans(file, second).scans, other, 1e-12);
    }
  }
}

}  // namespace
}  // namespace lmf::bag

#include <iostream>
#include <random>

#include "lmf/bag/planar_pose.hpp"

namespace lmf::bag {
namespace {

TEST(PlanarPose, EveryHeadingWrittenAsAQuaternionReadsBackBitForBit) {
  std::mt19937_64 rng(7);
  std::uniform_real_distribution<double> heading(-M_PI, M_PI);
  std::uniform_real_distribution<double> position(-1e3, 1e3);
  int exact_without_search = 0;
  const int n = 100'000;
  for (int k = 0; k < n; ++k) {
    const Pose2 x(position(rng), position(rng), heading(rng));
    const RosPose3 p = ros_pose(x);
    ASSERT_NEAR(p.rotation.norm(), 1.0, 1e-15);
    const Pose2 read = planar_pose(p);
    ASSERT_EQ(read.x, x.x);
    ASSERT_EQ(read.y, x.y);
    ASSERT_EQ(read.phi, x.phi) << k;
    const double half = x.phi / 2.0;
    exact_without_search += planar_pose(RosPose3{p.translation, Eigen::Quaterniond(std::cos(half), 0, 0, std::sin(half))}).phi == x.phi;
  }
  // The search is not idle: the exact quaternion alone misses some headings.
  EXPECT_LT(exact_without_search, n);
  std::cout << "headings read back exactly from the exact quaternion, without the search: " << exact_without_search
            << " of " << n << "\n";
  for (const double phi : {0.0, M_PI, -M_PI / 2, M_PI / 2, 1e-300}) EXPECT_EQ(planar_pose(ros_pose(Pose2(0, 0, phi))).phi, phi);
}

}  // namespace
}  // namespace lmf::bag
