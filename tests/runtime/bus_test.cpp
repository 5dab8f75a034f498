// Channels, options, the Bus over memq:// and the event loop.
#include <atomic>
#include <chrono>
#include <stdexcept>
#include <string>
#include <thread>
#include <vector>

#include <boost/program_options.hpp>
#include <gtest/gtest.h>

#include "runtime/bus.hpp"
#include "runtime/channels.hpp"
#include "runtime/event_loop.hpp"
#include "runtime/event_loop_test_support.hpp"
#include "runtime/options.hpp"

namespace {

namespace rt = lmf::runtime;
using namespace std::chrono_literals;
using lmf::testing::no_signals;

TEST(Channels, DefaultPrefixAndNames) {
  const rt::Channels c;
  EXPECT_EQ(c.scan(3), "LMF_SCAN_3");
  EXPECT_EQ(c.scan_ack(), "LMF_SCAN_ACK");
  EXPECT_EQ(c.local_map(), "LMF_LOCAL_MAP");
  EXPECT_EQ(c.local_map_ack(), "LMF_LOCAL_MAP_ACK");
  EXPECT_EQ(c.corrected_frames(), "LMF_CORRECTED_FRAMES");
  EXPECT_EQ(c.sighting(), "LMF_SIGHTING");
  EXPECT_EQ(c.global_map(), "LMF_GLOBAL_MAP");
  EXPECT_EQ(c.agent_status(), "LMF_AGENT_STATUS");
  EXPECT_EQ(c.server_status(), "LMF_SERVER_STATUS");
  EXPECT_EQ(c.mission_end(), "LMF_MISSION_END");
  EXPECT_EQ(c.scan_robot("LMF_SCAN_12"), 12);
  EXPECT_FALSE(c.scan_robot("LMF_SCAN_ACK").has_value());
  EXPECT_FALSE(c.scan_robot("LMF_SCAN_").has_value());
  EXPECT_FALSE(c.scan_robot("X_SCAN_1").has_value());
  EXPECT_THROW(c.scan(-1), std::invalid_argument);
}

TEST(Channels, CustomPrefixIsValidated) {
  EXPECT_EQ(rt::Channels("TEST2_").sighting(), "TEST2_SIGHTING");
  EXPECT_EQ(rt::Channels("").scan(0), "SCAN_0");
  EXPECT_THROW(rt::Channels("lmf_"), std::invalid_argument);
  EXPECT_THROW(rt::Channels("LMF.*"), std::invalid_argument);
}

TEST(Options, ParsesCommonFlagsStrictly) {
  rt::CommonOptions options;
  boost::program_options::options_description description("Options");
  rt::add_common_options(description, options);
  const char* good[] = {"prog", "--lcm-url", "memq://", "--channel-prefix", "T_"};
  EXPECT_EQ(rt::parse_options(5, good, description, "prog", "Test.").status, rt::ParseResult::Status::kOk);
  EXPECT_EQ(options.lcm_url, "memq://");
  EXPECT_EQ(options.channel_prefix, "T_");

  const char* help[] = {"prog", "--help"};
  const auto h = rt::parse_options(2, help, description, "prog", "Test.");
  EXPECT_EQ(h.status, rt::ParseResult::Status::kHelp);
  EXPECT_NE(h.message.find("--lcm-url"), std::string::npos);
  EXPECT_NE(h.message.find("--channel-prefix"), std::string::npos);

  const char* unknown[] = {"prog", "--lcm-ulr", "memq://"};
  EXPECT_EQ(rt::parse_options(3, unknown, description, "prog", "").status, rt::ParseResult::Status::kError);
  const char* positional[] = {"prog", "extra"};
  EXPECT_EQ(rt::parse_options(2, positional, description, "prog", "").status, rt::ParseResult::Status::kError);
  const char* bad_prefix[] = {"prog", "--channel-prefix", "lower"};
  const auto b = rt::parse_options(3, bad_prefix, description, "prog", "");
  EXPECT_EQ(b.status, rt::ParseResult::Status::kError);
  EXPECT_NE(b.message.find("lower"), std::string::npos);
}

TEST(OptionsDeathTest, ErrorsExitNonZero) {
  rt::CommonOptions options;
  boost::program_options::options_description description("Options");
  rt::add_common_options(description, options);
  const char* unknown[] = {"prog", "--nope"};
  EXPECT_EXIT(rt::parse_options_or_exit(2, unknown, description, "prog", ""), ::testing::ExitedWithCode(2),
              "prog: error: .*nope");
  EXPECT_EXIT(rt::exit_with_error("prog", "config broken"), ::testing::ExitedWithCode(1), "prog: error: config broken");
}

TEST(Bus, DeliversTypedMessageOverMemq) {
  rt::Bus bus("memq://");
  ASSERT_TRUE(bus.good());
  const rt::Channels channels;
  std::vector<lmf::scan_ack_t> received;
  bus.subscribe_message<lmf::scan_ack_t>(channels.scan_ack(),
                                         [&](const std::string& channel, const lmf::scan_ack_t& msg) {
                                           EXPECT_EQ(channel, "LMF_SCAN_ACK");
                                           received.push_back(msg);
                                         });
  lmf::scan_ack_t ack{};
  ack.robot_id = 2;
  ack.seq = 17;
  ASSERT_TRUE(bus.publish(channels.scan_ack(), ack));
  ASSERT_TRUE(bus.publish(channels.local_map(), ack));  // nobody listens there
  EXPECT_TRUE(received.empty());  // nothing is dispatched before handle_pending()
  // memq drops a message nobody subscribed to at publish time: one to dispatch.
  EXPECT_EQ(bus.handle_pending(), 1);
  ASSERT_EQ(received.size(), 1u);
  EXPECT_EQ(received[0].seq, 17);
  EXPECT_EQ(bus.handle_pending(), 0);
}

TEST(Bus, RegexSubscriptionSeesEveryRobotsScans) {
  rt::Bus bus("memq://");
  const rt::Channels channels;
  std::vector<int> robots;
  bus.subscribe(channels.scan_any(), [&](const std::string& channel, const void*, std::size_t) {
    robots.push_back(channels.scan_robot(channel).value_or(-1));
  });
  const std::vector<std::uint8_t> payload{1, 2, 3};
  bus.publish_raw(channels.scan(0), payload);
  bus.publish_raw(channels.scan_ack(), payload);
  bus.publish_raw(channels.scan(11), payload);
  bus.handle_pending();
  EXPECT_EQ(robots, (std::vector<int>{0, 11}));
}

TEST(Bus, UndecodableMessageIsCountedNotDelivered) {
  rt::Bus bus("memq://");
  int delivered = 0;
  bus.subscribe_message<lmf::sighting_t>("S", [&](const std::string&, const lmf::sighting_t&) { ++delivered; });
  bus.publish_raw("S", {1, 2, 3, 4, 5, 6, 7, 8, 9});
  lmf::scan_ack_t wrong_type{};
  bus.publish("S", wrong_type);
  bus.handle_pending();
  EXPECT_EQ(delivered, 0);
  EXPECT_EQ(bus.rejects().count(rt::RejectReason::kDecodeFailed), 2);
}

TEST(Bus, ThrowingHandlerIsCaughtCountedAndDropped) {
  rt::Bus bus("memq://");
  int after = 0;
  bus.subscribe("X", [](const std::string&, const void*, std::size_t) { throw std::runtime_error("handler bug"); });
  bus.subscribe("X", [&](const std::string&, const void*, std::size_t) { ++after; });
  bus.subscribe("Y", [](const std::string&, const void*, std::size_t) { throw 42; });
  bus.publish_raw("X", {0});
  bus.publish_raw("X", {0});
  bus.publish_raw("Y", {0});
  EXPECT_NO_THROW(bus.handle_pending());
  EXPECT_EQ(bus.handler_errors(), 3);
  EXPECT_EQ(after, 2);  // the other subscriber of the same message still ran
}

TEST(Bus, UnsubscribeStopsDelivery) {
  rt::Bus bus("memq://");
  int n = 0;
  const int id = bus.subscribe("X", [&](const std::string&, const void*, std::size_t) { ++n; });
  bus.publish_raw("X", {0});
  bus.handle_pending();
  bus.unsubscribe(id);
  bus.publish_raw("X", {0});
  bus.handle_pending();
  EXPECT_EQ(n, 1);
}

TEST(Bus, SimulatedLossDropsAndDuplicatesDeterministically) {
  // What a listener receives of 2000 publishes through a lossy endpoint.
  const auto heard = [](const rt::SimulatedLoss& loss, std::int64_t* dropped, std::int64_t* duplicated) {
    rt::Bus network("memq://");
    rt::Bus sender(network, std::nullopt);
    sender.simulate_loss(loss);
    std::vector<std::uint8_t> received;
    network.subscribe("X", [&](const std::string&, const void* data, std::size_t) {
      received.push_back(*static_cast<const std::uint8_t*>(data));
    });
    for (int k = 0; k < 2000; ++k) {
      EXPECT_TRUE(sender.publish_raw("X", {static_cast<std::uint8_t>(k % 251)}));  // the sender cannot tell
      network.handle_pending();
    }
    *dropped = sender.publishes_dropped();
    *duplicated = sender.publishes_duplicated();
    return received;
  };
  std::int64_t dropped = 0, duplicated = 0, dropped_again = 0, duplicated_again = 0;
  const auto first = heard({0.2, 0.1, 42}, &dropped, &duplicated);
  EXPECT_EQ(heard({0.2, 0.1, 42}, &dropped_again, &duplicated_again), first) << "the same seed, the same losses";
  EXPECT_EQ(static_cast<std::int64_t>(first.size()), 2000 - dropped + duplicated);
  EXPECT_NEAR(static_cast<double>(dropped) / 2000.0, 0.2, 0.04);
  EXPECT_NEAR(static_cast<double>(duplicated) / static_cast<double>(2000 - dropped), 0.1, 0.03);
  EXPECT_NE(heard({0.2, 0.1, 43}, &dropped_again, &duplicated_again), first);

  rt::Bus bus("memq://");
  EXPECT_THROW(bus.simulate_loss({1.0, 0.0, 1}), std::invalid_argument);
  EXPECT_THROW(bus.simulate_loss({0.0, -0.1, 1}), std::invalid_argument);
}

TEST(Bus, BadUrlIsNotGood) {
  rt::Bus bus("nosuchprovider://");
  EXPECT_FALSE(bus.good());
  EXPECT_FALSE(bus.publish_raw("X", {0}));
  EXPECT_EQ(bus.publish_failures(), 1);
  EXPECT_LT(bus.handle_pending(), 0);
}

TEST(EventLoop, WatchesMemqDescriptorAndDeliversFromTimers) {
  rt::Bus bus("memq://");
  rt::EventLoop loop(bus, no_signals());
  EXPECT_TRUE(loop.watching_descriptor());  // LCM 1.3.1 memq exposes a notify pipe
  int received = 0;
  bus.subscribe("PING", [&](const std::string&, const void*, std::size_t) {
    if (++received == 5) loop.stop();
  });
  int sent = 0;
  loop.every(2ms, [&] {
    if (sent < 5) bus.publish_raw("PING", {static_cast<std::uint8_t>(sent++)});
  });
  const auto start = std::chrono::steady_clock::now();
  loop.run_for(2s);
  EXPECT_EQ(received, 5);
  EXPECT_LT(std::chrono::steady_clock::now() - start, 1s);  // stopped by stop(), not the deadline
}

TEST(EventLoop, MessageQueuedBeforeRunIsDelivered) {
  rt::Bus bus("memq://");
  int received = 0;
  bus.subscribe("EARLY", [&](const std::string&, const void*, std::size_t) { ++received; });
  bus.publish_raw("EARLY", {1});
  rt::EventLoop loop(bus, no_signals());
  loop.after(200ms, [&] { loop.stop(); });
  loop.run();
  EXPECT_EQ(received, 1);
}

TEST(EventLoop, TimersRunAndStopEndsRun) {
  rt::Bus bus("memq://");
  rt::EventLoop loop(bus, no_signals());
  int fast = 0;
  int slow = 0;
  loop.every(5ms, [&] { ++fast; });
  loop.every(20ms, [&] {
    if (++slow == 3) loop.stop();
  });
  const auto start = std::chrono::steady_clock::now();
  loop.run();
  const auto elapsed = std::chrono::steady_clock::now() - start;
  EXPECT_EQ(slow, 3);
  EXPECT_GE(fast, 8);  // ~12 expected in 60 ms; loose for a loaded machine
  EXPECT_GE(elapsed, 55ms);
  EXPECT_LT(elapsed, 2s);
  // A stopped loop runs again.
  loop.after(10ms, [&] { loop.stop(); });
  const int before = fast;
  loop.run();
  EXPECT_GE(fast, before);
}

TEST(EventLoop, CancelAndOneShot) {
  rt::Bus bus("memq://");
  rt::EventLoop loop(bus, no_signals());
  int cancelled = 0;
  int once = 0;
  const int id = loop.every(1ms, [&] { ++cancelled; });
  loop.cancel(id);
  loop.after(5ms, [&] { ++once; });
  loop.run_for(50ms);
  EXPECT_EQ(cancelled, 0);
  EXPECT_EQ(once, 1);
  EXPECT_THROW(loop.every(0ms, [] {}), std::invalid_argument);
}

TEST(EventLoop, PollDispatchesWithoutBlocking) {
  rt::Bus bus("memq://");
  rt::EventLoop loop(bus, no_signals());
  int received = 0;
  bus.subscribe("P", [&](const std::string&, const void*, std::size_t) { ++received; });
  bus.publish_raw("P", {1});
  bus.publish_raw("P", {2});
  loop.poll();
  EXPECT_EQ(received, 2);
  const auto start = std::chrono::steady_clock::now();
  loop.poll();
  EXPECT_LT(std::chrono::steady_clock::now() - start, 100ms);
}

TEST(EventLoop, PostFromAnotherThread) {
  rt::Bus bus("memq://");
  rt::EventLoop loop(bus, no_signals());
  std::atomic<bool> ran{false};
  std::thread worker([&] { loop.post([&] { ran = true; loop.stop(); }); });
  loop.run_for(2s);
  worker.join();
  EXPECT_TRUE(ran);
}

TEST(EventLoop, SigtermStopsTheLoop) {
  rt::Bus bus("memq://");
  rt::EventLoop loop(bus);  // signals handled
  loop.after(10ms, [] { std::raise(SIGTERM); });
  loop.run_for(5s);
  ASSERT_TRUE(loop.stopped_by_signal().has_value());
  EXPECT_EQ(*loop.stopped_by_signal(), SIGTERM);
}

TEST(EventLoop, ManyMessagesDoNotStarveTimers) {
  rt::Bus bus("memq://");
  rt::EventLoopOptions options = no_signals();
  options.max_messages_per_wakeup = 10;
  rt::EventLoop loop(bus, options);
  int received = 0;
  bus.subscribe("M", [&](const std::string&, const void*, std::size_t) { ++received; });
  for (int i = 0; i < 100; ++i) bus.publish_raw("M", {0});
  loop.after(100ms, [&] { loop.stop(); });
  loop.run();
  EXPECT_EQ(received, 100);
}

}  // namespace
