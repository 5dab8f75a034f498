// The resend wait follows the measured round trip, backs off and stays bounded.
#include "runtime/retransmission_timeout.hpp"

#include <stdexcept>

#include <gtest/gtest.h>

namespace {

using namespace std::chrono_literals;
using lmf::runtime::RetransmissionConfig;
using lmf::runtime::RetransmissionTimeout;

RetransmissionTimeout make(std::chrono::milliseconds min, std::chrono::milliseconds max) {
  RetransmissionConfig config;
  config.min = min;
  config.max = max;
  return RetransmissionTimeout(config);
}

TEST(RetransmissionTimeout, BeforeTheFirstAnswerStartsAtTheInitialWaitAndBacksOff) {
  const RetransmissionTimeout rto = make(10ms, 2000ms);
  EXPECT_EQ(rto.timeout(1), 200ms);
  EXPECT_EQ(rto.timeout(2), 400ms);
  EXPECT_EQ(rto.timeout(4), 1600ms);
  EXPECT_EQ(rto.timeout(5), 2000ms);
  EXPECT_FALSE(rto.smoothed_round_trip().has_value());
}

TEST(RetransmissionTimeout, TheInitialWaitStaysWithinBounds) {
  EXPECT_EQ(make(500ms, 2000ms).timeout(1), 500ms);
  EXPECT_EQ(make(10ms, 100ms).timeout(1), 100ms);
}

TEST(RetransmissionTimeout, FollowsTheRoundTrip) {
  RetransmissionTimeout rto = make(1ms, 2000ms);
  rto.on_round_trip(20ms);  // SRTT 20, RTTVAR 10: 60 ms
  EXPECT_EQ(rto.timeout(1), 60ms);
  for (int i = 0; i < 100; ++i) rto.on_round_trip(20ms);  // RTTVAR decays: towards SRTT
  using Ms = std::chrono::duration<double, std::milli>;
  EXPECT_NEAR(Ms(rto.timeout(1)).count(), 20.0, 0.1);
  EXPECT_EQ(*rto.smoothed_round_trip(), 20ms);
}

TEST(RetransmissionTimeout, AJitteryPeerGetsMoreMargin) {
  RetransmissionTimeout steady = make(1ms, 2000ms), jittery = make(1ms, 2000ms);
  for (int i = 0; i < 50; ++i) {
    steady.on_round_trip(20ms);
    jittery.on_round_trip(i % 2 == 0 ? 5ms : 35ms);  // the same mean
  }
  EXPECT_GT(jittery.timeout(1), steady.timeout(1) + 40ms);
}

TEST(RetransmissionTimeout, BacksOffAndStaysWithinBounds) {
  RetransmissionTimeout rto = make(10ms, 500ms);
  rto.on_round_trip(1ms);  // 1 + 4 * 0.5 = 3 ms: the floor
  EXPECT_EQ(rto.timeout(1), 10ms);
  EXPECT_EQ(rto.timeout(2), 20ms);
  EXPECT_EQ(rto.timeout(3), 40ms);
  EXPECT_EQ(rto.timeout(7), 500ms);  // 640 ms capped
  EXPECT_EQ(rto.timeout(1000), 500ms);
  rto.on_round_trip(5s);  // a stalled peer: capped too
  EXPECT_EQ(rto.timeout(1), 500ms);
}

TEST(RetransmissionTimeout, IgnoresNegativeSamples) {
  RetransmissionTimeout rto = make(10ms, 500ms);
  rto.on_round_trip(-5ms);
  EXPECT_FALSE(rto.smoothed_round_trip().has_value());
}

TEST(RetransmissionTimeout, RejectsABadConfig) {
  EXPECT_THROW(make(0ms, 100ms), std::invalid_argument);
  EXPECT_THROW(make(200ms, 100ms), std::invalid_argument);
  RetransmissionConfig no_initial;
  no_initial.initial = 0ms;
  EXPECT_THROW(RetransmissionTimeout{no_initial}, std::invalid_argument);
  EXPECT_NO_THROW(make(100ms, 100ms));
}

}  // namespace
