// A two-role LCM peer for the multi-process test (netns_test.cpp): "echo"
// answers the first scan_ack_t on SCAN_ACK with a local_map_ack_t on
// LOCAL_MAP_ACK and exits 0; "ping" publishes scan_ack_t every 20 ms until the
// answer arrives (exit 0) or --timeout-ms passes (exit 1). Uses the runtime
// exactly as a process would: common options, Bus, EventLoop, conversions.
#include <chrono>
#include <iostream>
#include <string>

#include <boost/program_options.hpp>

#include "runtime/bus.hpp"
#include "runtime/channels.hpp"
#include "runtime/convert.hpp"
#include "runtime/event_loop.hpp"
#include "runtime/options.hpp"

namespace rt = lmf::runtime;

int main(int argc, char** argv) {
  rt::CommonOptions common;
  std::string role;
  int timeout_ms = 5000;
  boost::program_options::options_description description("Options");
  rt::add_common_options(description, common);
  description.add_options()
      ("role", boost::program_options::value<std::string>(&role)->required(), "echo or ping")
      ("timeout-ms", boost::program_options::value<int>(&timeout_ms)->default_value(timeout_ms), "give up after this");
  rt::parse_options_or_exit(argc, argv, description, "lmf_runtime_peer", "LCM ping/echo peer for runtime tests.");
  if (role != "echo" && role != "ping") rt::exit_with_error("lmf_runtime_peer", "--role must be echo or ping", 2);

  rt::Bus bus(common.lcm_url);
  if (!bus.good()) rt::exit_with_error("lmf_runtime_peer", "LCM not good for URL '" + common.lcm_url + "'");
  const rt::Channels channels(common.channel_prefix);
  rt::EventLoop loop(bus);
  int exit_code = 1;
  std::int64_t seq = 0;  // pings sent; outlives the handlers that use it

  if (role == "echo") {
    bus.subscribe(channels.scan_ack(), [&](const std::string&, const void* data, std::size_t size) {
      auto ack = rt::decode<rt::ScanAck>(data, size);
      if (!ack) return;
      const rt::LocalMapAck answer{ack.value().utime, ack.value().robot_id, ack.value().seq,
                                   rt::LocalMapAck::Status::kFused};
      // Answer a few times: UDP may drop one, and the ping stops at the first.
      for (int i = 0; i < 3; ++i) bus.publish(channels.local_map_ack(), rt::to_message(answer));
      std::cout << "echo: answered seq " << ack.value().seq << std::endl;
      exit_code = 0;
      loop.stop();
    });
  } else {
    bus.subscribe(channels.local_map_ack(), [&](const std::string&, const void* data, std::size_t size) {
      auto answer = rt::decode<rt::LocalMapAck>(data, size);
      if (!answer || answer.value().robot_id != 7) return;
      std::cout << "ping: answer for seq " << answer.value().seq << " after " << seq << " pings" << std::endl;
      exit_code = 0;
      loop.stop();
    });
    loop.every(std::chrono::milliseconds(20), [&] {
      rt::ScanAck ack;
      ack.utime = 1000 + seq;
      ack.robot_id = 7;
      ack.seq = seq;
      bus.publish(channels.scan_ack(), rt::to_message(ack).value());
      ++seq;
    });
  }
  loop.after(std::chrono::milliseconds(timeout_ms), [&] {
    std::cerr << role << ": timed out after " << timeout_ms << " ms" << std::endl;
    loop.stop();
  });
  loop.run();
  return exit_code;
}
