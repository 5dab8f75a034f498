// The public bags in ../shared/bags (their README): each is read or refused as
// the README says, with the counts and types it gives.
#include <gtest/gtest.h>

#include <map>

#include "lmf/bag/bag_file.hpp"
#include "lmf/bag/bag_scans.hpp"
#include "lmf/bag/ros_messages.hpp"
#include "test_support.hpp"

namespace lmf::bag {
namespace {

std::map<std::string, std::pair<std::string, std::size_t>> topics(const BagSummary& s) {
  std::map<std::string, std::pair<std::string, std::size_t>> out;
  for (const auto& t : s.topics) out[t.name] = {t.type, t.count};
  return out;
}

TEST(SharedBags, Ros1LaserScanBagsAreReadWithTheirCounts) {
  LMF_REQUIRE_BAGS(dir);
  const BagSummary demo = summarize_bag(dir / "ros1-scan-matcher-demo.bag");
  EXPECT_EQ(demo.format, BagFormat::ros1);
  EXPECT_EQ(demo.compression, "none");
  EXPECT_FALSE(demo.cut_short) << *demo.cut_short;
  EXPECT_EQ(topics(demo), (std::map<std::string, std::pair<std::string, std::size_t>>{
                              {"/scan", {"sensor_msgs/LaserScan", 360}}}));
  const BagSummary right = summarize_bag(dir / "ros1-scan-topic-without-slash.bag");
  EXPECT_EQ(topics(right).at("right_scan"), std::make_pair(std::string("sensor_msgs/LaserScan"), std::size_t{243}));
}

TEST(SharedBags, TheFirstScanOfTheDemoBagDecodesToAConsistentScan) {
  LMF_REQUIRE_BAGS(dir);
  std::optional<RosLaserScan> first;
  for_each_bag_message(dir / "ros1-scan-matcher-demo.bag", {"/scan"}, [&](const BagMessage& m) {
    if (!first) first = decode_laser_scan(m.data, m.encoding);
  });
  ASSERT_TRUE(first);
  ASSERT_GT(first->ranges.size(), 2u);
  EXPECT_FALSE(first->header.frame_id.empty());
  // The beams span angle_min .. angle_max in angle_increment steps.
  EXPECT_NEAR(first->angle_min + first->angle_increment * static_cast<float>(first->ranges.size() - 1),
              first->angle_max, std::abs(first->angle_increment));
  EXPECT_GT(first->range_max, first->range_min);
}

TEST(SharedBags, CompressedChunksAreReadBz2AndLz4) {
  LMF_REQUIRE_BAGS(dir);
  const BagSummary odom = summarize_bag(dir / "ros1-odometry-bz2.bag");
  EXPECT_EQ(odom.compression, "bz2");
  EXPECT_FALSE(odom.cut_short);
  EXPECT_EQ(topics(odom).at("/jackal_velocity_controller/odom"),
            std::make_pair(std::string("nav_msgs/Odometry"), std::size_t{3060}));
  EXPECT_EQ(topics(odom).at("/imu/data").second, 3061u);
  std::size_t decoded = 0;
  for_each_bag_message(dir / "ros1-odometry-bz2.bag", {"/jackal_velocity_controller/odom"}, [&](const BagMessage& m) {
    const RosOdometry o = decode_odometry(m.data, m.encoding);
    EXPECT_TRUE(o.pose.translation.allFinite());
    ++decoded;
  });
  EXPECT_EQ(decoded, 3060u);

  const BagSummary tf2 = summarize_bag(dir / "ros1-tf2-lz4.bag");
  EXPECT_EQ(tf2.compression, "lz4");
  EXPECT_EQ(topics(tf2).at("/tf"), std::make_pair(std::string("tf2_msgs/TFMessage"), std::size_t{517}));
  EXPECT_EQ(topics(tf2).at("/tf_static").second, 1u);
  for (const char* name : {"ros1-turtlesim-tf-lz4.bag", "ros1-turtlesim-tf-bz2.bag"}) {
    const BagSummary s = summarize_bag(dir / name);
    EXPECT_EQ(topics(s).at("/tf").first, "tf/tfMessage") << name;
    EXPECT_EQ(topics(s).at("/tf_static").first, "tf2_msgs/TFMessage") << name;
    std::size_t transforms = 0;
    for_each_bag_message(dir / name, {"/tf"}, [&](const BagMessage& m) {
      transforms += decode_tf_message(m.data, m.encoding).size();
    });
    EXPECT_GT(transforms, 0u) << name;
  }
}

TEST(SharedBags, UnsortedChunksComeOutInTimeOrder) {
  LMF_REQUIRE_BAGS(dir);
  std::vector<std::int64_t> times;
  for_each_bag_message(dir / "ros1-unsorted-chunks.bag", {}, [&](const BagMessage& m) {
    times.push_back(m.log_time_ns);
  });
  ASSERT_EQ(times.size(), 3u);
  EXPECT_TRUE(std::is_sorted(times.begin(), times.end()));
}

TEST(SharedBags, AnEmptyBagIsReadAsEmptyAndHasNoScansToMap) {
  LMF_REQUIRE_BAGS(dir);
  const BagSummary s = summarize_bag(dir / "ros1-no-messages.bag");
  EXPECT_EQ(s.messages, 0u);
  EXPECT_TRUE(s.topics.empty());
  EXPECT_THROW(read_bag_scans(dir / "ros1-no-messages.bag"), std::invalid_argument);
}

TEST(SharedBags, ThePre2010FormatIsRefusedByName) {
  LMF_REQUIRE_BAGS(dir);
  try {
    summarize_bag(dir / "rosrecord-v1.2-unsupported.bag");
    FAIL() << "read";
  } catch (const BagFormatError& e) {
    EXPECT_NE(std::string(e.what()).find("rosrecord-v1.2-unsupported.bag"), std::string::npos);
    EXPECT_NE(std::string(e.what()).find("#ROSRECORD V1.2"), std::string::npos);
  }
}

TEST(SharedBags, ScansWithoutOdometryAskForNoOdometry) {
  LMF_REQUIRE_BAGS(dir);
  try {
    read_bag_scans(dir / "ros1-scan-matcher-demo.bag");
    FAIL() << "read";
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find("--no-odometry"), std::string::npos);
  }
}

}  // namespace
}  // namespace lmf::bag

namespace lmf::bag {
namespace {

TEST(SharedBags, Ros2McapZstdOdometryAndTfAreReadAndDecoded) {
  LMF_REQUIRE_BAGS(dir);
  const auto file = dir / "ros2-nav2-odometry-tf-zstd.mcap";
  const BagSummary s = summarize_bag(file);
  EXPECT_EQ(s.format, BagFormat::mcap);
  EXPECT_EQ(s.compression, "zstd");
  EXPECT_FALSE(s.cut_short);
  EXPECT_EQ(topics(s).at("/odom"), std::make_pair(std::string("nav_msgs/msg/Odometry"), std::size_t{2639}));
  EXPECT_EQ(topics(s).at("/tf"), std::make_pair(std::string("tf2_msgs/msg/TFMessage"), std::size_t{5422}));
  EXPECT_EQ(topics(s).at("/tf_static").second, 1u);
  EXPECT_EQ(topics(s).at("/amcl_pose").second, 135u);
  std::size_t odometry = 0, transforms = 0;
  std::int64_t last = 0;
  for_each_bag_message(file, {"/odom", "/tf"}, [&](const BagMessage& m) {
    EXPECT_GE(m.log_time_ns, last);
    last = m.log_time_ns;
    EXPECT_EQ(m.encoding, MessageEncoding::cdr);
    if (m.topic == "/odom") {
      const RosOdometry o = decode_odometry(m.data, m.encoding);
      EXPECT_EQ(o.header.frame_id, "odom");
      EXPECT_TRUE(o.pose.translation.allFinite());
      EXPECT_NEAR(o.pose.rotation.norm(), 1.0, 1e-6);
      ++odometry;
    } else {
      transforms += decode_tf_message(m.data, m.encoding).size();
    }
  });
  EXPECT_EQ(odometry, 2639u);
  EXPECT_GE(transforms, 5422u);
}

TEST(SharedBags, McapWrittenByAnotherLibraryDecodesItsScanAndOdometry) {
  LMF_REQUIRE_BAGS(dir);
  const auto file = dir / "ros2-every-type-synthetic.mcap";
  const BagSummary s = summarize_bag(file);
  EXPECT_EQ(s.topics.size(), 94u);
  EXPECT_EQ(s.messages, 188u);
  EXPECT_EQ(topics(s).at("/test/sensor_msgs/laser_scan"),
            std::make_pair(std::string("sensor_msgs/msg/LaserScan"), std::size_t{2}));
  std::size_t scans = 0, odometry = 0;
  for_each_bag_message(file, {"/test/sensor_msgs/laser_scan", "/test/nav_msgs/odometry"}, [&](const BagMessage& m) {
    if (is_laser_scan_type(m.type)) {
      decode_laser_scan(m.data, m.encoding);  // random content: it must decode to the end, whatever it says
      ++scans;
    } else {
      decode_odometry(m.data, m.encoding);
      ++odometry;
    }
  });
  EXPECT_EQ(scans, 2u);
  EXPECT_EQ(odometry, 2u);
}

TEST(SharedBags, McapWithoutScansAndOtherEncodingsAreSummarised) {
  LMF_REQUIRE_BAGS(dir);
  const BagSummary talker = summarize_bag(dir / "ros2-talker-zstd.mcap");
  EXPECT_EQ(topics(talker).at("/topic"), std::make_pair(std::string("std_msgs/msg/String"), std::size_t{10}));
  EXPECT_EQ(topics(talker).at("/rosout").second, 10u);
  const BagSummary cdr = summarize_bag(dir / "ros2-cdr-test.mcap");
  EXPECT_EQ(cdr.compression, "none");
  EXPECT_EQ(cdr.messages, 7u);
  EXPECT_THROW(read_bag_scans(dir / "ros2-talker-zstd.mcap"), std::invalid_argument);
}

TEST(SharedBags, Ros2Sqlite3FolderIsReadWithItsScans) {
  LMF_REQUIRE_BAGS(dir);
  const auto folder = dir / "ros2-laser-imu-sqlite3";
  const BagSummary s = summarize_bag(folder);
  EXPECT_EQ(s.format, BagFormat::sqlite3);
  EXPECT_EQ(topics(s).at("/scan"), std::make_pair(std::string("sensor_msgs/msg/LaserScan"), std::size_t{147}));
  EXPECT_EQ(topics(s).at("/imu_data").second, 590u);
  std::optional<RosLaserScan> first;
  std::size_t scans = 0;
  for_each_bag_message(folder, {"/scan"}, [&](const BagMessage& m) {
    if (!first) first = decode_laser_scan(m.data, m.encoding);
    ++scans;
  });
  EXPECT_EQ(scans, 147u);
  ASSERT_TRUE(first);
  EXPECT_EQ(first->header.frame_id, "laser_frame");
  // A 360° scan: the beams cover the full turn.
  EXPECT_NEAR(std::abs(first->angle_increment) * static_cast<float>(first->ranges.size()), 2 * M_PI, 0.05);
  const BagSummary talker = summarize_bag(dir / "ros2-talker-sqlite3");
  EXPECT_EQ(topics(talker).at("/topic").second, 10u);
}

}  // namespace
}  // namespace lmf::bag
