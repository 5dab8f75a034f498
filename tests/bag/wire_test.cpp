#include <gtest/gtest.h>

#include "lmf/bag/ros_messages.hpp"
#include "lmf/bag/wire_decoder.hpp"
#include "lmf/bag/wire_encoder.hpp"

namespace lmf::bag {
namespace {

RosLaserScan example_scan() {
  RosLaserScan s;
  s.header = {1'282'836'371'070'000'123, "laser"};
  s.angle_min = -2.0f;
  s.angle_max = 2.0f;
  s.angle_increment = 0.5f;
  s.range_min = 0.1f;
  s.range_max = 30.0f;
  s.ranges = {1.0f, 2.5f, 3.25f, 4.0f, 5.0f, 6.0f, 7.0f, 8.0f, 9.0f};
  return s;
}

class WireEncodings : public ::testing::TestWithParam<MessageEncoding> {};

TEST_P(WireEncodings, ALaserScanDecodesToWhatWasEncoded) {
  const RosLaserScan s = example_scan();
  const RosLaserScan d = decode_laser_scan(encode_laser_scan(s, GetParam()), GetParam());
  EXPECT_EQ(d.header.stamp_ns, s.header.stamp_ns);
  EXPECT_EQ(d.header.frame_id, "laser");
  EXPECT_EQ(d.angle_min, s.angle_min);
  EXPECT_EQ(d.angle_increment, s.angle_increment);
  EXPECT_EQ(d.range_max, s.range_max);
  EXPECT_EQ(d.ranges, s.ranges);
}

TEST_P(WireEncodings, OdometryAndTransformsDecodeToWhatWasEncoded) {
  RosOdometry o;
  o.header = {5'000'000'001, "odom"};
  o.child_frame_id = "base_link";
  o.pose.translation = {1.5, -2.25, 0.0};
  o.pose.rotation = Eigen::Quaterniond(Eigen::AngleAxisd(0.7, Eigen::Vector3d::UnitZ()));
  const RosOdometry od = decode_odometry(encode_odometry(o, GetParam()), GetParam());
  EXPECT_EQ(od.child_frame_id, "base_link");
  EXPECT_EQ(od.pose.translation, o.pose.translation);
  EXPECT_TRUE(od.pose.rotation.isApprox(o.pose.rotation, 1e-15));

  RosTransform t;
  t.header = {7, "base_link"};
  t.child_frame_id = "laser";
  t.transform.translation = {0.2, 0.0, 0.3};
  const auto ts = decode_tf_message(encode_tf_message({t, t}, GetParam()), GetParam());
  ASSERT_EQ(ts.size(), 2u);
  EXPECT_EQ(ts[1].header.frame_id, "base_link");
  EXPECT_EQ(ts[1].child_frame_id, "laser");
  EXPECT_EQ(ts[1].transform.translation, t.transform.translation);
}

TEST_P(WireEncodings, EveryTruncationIsRefusedWithItsOffsetNeverReadPast) {
  const auto bytes = encode_laser_scan(example_scan(), GetParam());
  for (std::size_t n = 0; n < bytes.size(); ++n) {
    const std::vector<std::uint8_t> cut(bytes.begin(), bytes.begin() + static_cast<std::ptrdiff_t>(n));
    try {
      decode_laser_scan(cut, GetParam());
      ADD_FAILURE() << "a message cut to " << n << " of " << bytes.size() << " bytes decoded";
    } catch (const WireDecodeError& e) {
      EXPECT_LE(e.offset(), n);
      EXPECT_NE(std::string(e.what()).find("byte "), std::string::npos);
    }
  }
}

INSTANTIATE_TEST_SUITE_P(Both, WireEncodings, ::testing::Values(MessageEncoding::ros1, MessageEncoding::cdr),
                         [](const auto& info) { return std::string(to_string(info.param)); });

TEST(WireDecoder, CdrAlignsEachPrimitiveToItsSizeFromTheEndOfTheHeader) {
  // After the little-endian header: the string "a" (uint32 length 2, 'a', NUL:
  // 6 bytes), 2 padding bytes, then a float64 at offset 8 from the header's end.
  std::vector<std::uint8_t> bytes = {0x00, 0x01, 0x00, 0x00, 2, 0, 0, 0, 'a', 0, 0xEE, 0xEE};
  const double value = 3.5;
  const auto* p = reinterpret_cast<const std::uint8_t*>(&value);
  bytes.insert(bytes.end(), p, p + 8);
  WireDecoder d(bytes, MessageEncoding::cdr);
  EXPECT_EQ(d.string("s"), "a");
  EXPECT_EQ(d.f64("d"), 3.5);
}

TEST(WireDecoder, BigEndianCdrIsRead) {
  const std::vector<std::uint8_t> bytes = {0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x01, 0x02};
  WireDecoder d(bytes, MessageEncoding::cdr);
  EXPECT_EQ(d.u32("v"), 0x0102u);
}

TEST(WireDecoder, ASequenceLongerThanTheMessageIsRefusedBeforeAnyAllocation) {
  const std::vector<std::uint8_t> bytes = {0xFF, 0xFF, 0xFF, 0x7F, 0, 0, 0, 0};
  WireDecoder d(bytes, MessageEncoding::ros1);
  EXPECT_THROW(d.f32_sequence("ranges"), WireDecodeError);
}

TEST(WireDecoder, AnUnknownCdrEncapsulationIsRefused) {
  const std::vector<std::uint8_t> bytes = {0x00, 0x07, 0x00, 0x00, 0, 0, 0, 0};
  EXPECT_THROW(WireDecoder(bytes, MessageEncoding::cdr), WireDecodeError);
}

}  // namespace
}  // namespace lmf::bag
