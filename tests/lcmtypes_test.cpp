// The generated message types encode and decode losslessly.
#include <vector>

#include <gtest/gtest.h>

#include "lmf/local_map_t.hpp"
#include "lmf/sighting_t.hpp"

namespace {

TEST(LcmTypes, LocalMapRoundTrips) {
  lmf::local_map_t msg{};  // value-initialised: every count (num_scan_poses, ...) starts at 0
  msg.utime = 123456789;
  msg.robot_id = 2;
  msg.seq = 7;
  msg.first_scan_utime = 100;
  msg.num_scans = 21;
  msg.robot.x = 1.5;
  msg.robot.y = -0.5;
  msg.robot.phi = 0.25;
  msg.num_segments = 1;
  msg.segments.resize(1);
  msg.segments[0].location.x = 3.0;
  msg.segments[0].length = 2.0f;
  const int n = 3 + 2 * msg.num_segments;
  msg.num_covariance = n * (n + 1) / 2;
  msg.covariance.assign(static_cast<size_t>(msg.num_covariance), 0.01);

  std::vector<unsigned char> buffer(static_cast<size_t>(msg.getEncodedSize()));
  ASSERT_EQ(msg.encode(buffer.data(), 0, static_cast<int>(buffer.size())), static_cast<int>(buffer.size()));
  lmf::local_map_t decoded;
  ASSERT_EQ(decoded.decode(buffer.data(), 0, static_cast<int>(buffer.size())), static_cast<int>(buffer.size()));
  EXPECT_EQ(decoded.robot_id, 2);
  EXPECT_EQ(decoded.seq, 7);
  EXPECT_DOUBLE_EQ(decoded.robot.phi, 0.25);
  ASSERT_EQ(decoded.segments.size(), 1u);
  EXPECT_DOUBLE_EQ(decoded.segments[0].location.x, 3.0);
  EXPECT_EQ(decoded.covariance.size(), 15u);
}

TEST(LcmTypes, TruncatedBufferFailsToDecode) {
  lmf::sighting_t msg{};
  msg.observer_id = 1;
  msg.observed_id = 2;
  std::vector<unsigned char> buffer(static_cast<size_t>(msg.getEncodedSize()));
  msg.encode(buffer.data(), 0, static_cast<int>(buffer.size()));
  lmf::sighting_t decoded;
  EXPECT_LT(decoded.decode(buffer.data(), 0, static_cast<int>(buffer.size()) - 4), 0);
}

}  // namespace
