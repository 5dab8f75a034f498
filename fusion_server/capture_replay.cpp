#include "fusion_server/capture_replay.hpp"

#include <algorithm>
#include <chrono>
#include <cstdio>
#include <stdexcept>
#include <string>
#include <thread>

#include <lcm/lcm-cpp.hpp>

namespace lmf::server {
namespace {

// Runs the loop's ready handlers (worker outcomes) until `done`.
template <class Done>
void poll_until(runtime::EventLoop& loop, Done done) {
  while (!done()) {
    loop.poll();
    std::this_thread::sleep_for(std::chrono::microseconds(200));
  }
  loop.poll();
}

}  // namespace

CaptureReplayStats replay_capture(const std::filesystem::path& capture, runtime::Bus& bus, runtime::EventLoop& loop,
                                  const ServerNode& node, const runtime::Channels& channels) {
  if (bus.url().rfind("memq://", 0) != 0) {
    throw std::invalid_argument("replay_capture: the bus must be memq:// (got '" + bus.url() + "')");
  }
  lcm::LogFile log(capture.string(), "r");
  if (!log.good()) throw std::runtime_error(capture.string() + ": cannot open as an lcm-logger capture");
  const std::string local_map = channels.local_map();
  const std::string sighting = channels.sighting();
  CaptureReplayStats stats;
  std::int64_t read_up_to = 0;  // end of the last event read
  while (const lcm::LogEvent* event = log.readNextEvent()) {
    ++stats.events;
    if (log.getFilePtr() != nullptr) read_up_to = std::ftell(log.getFilePtr());
    const bool is_map = event->channel == local_map;
    if (!is_map && event->channel != sighting) continue;
    // Room in the worker queue first: a live server would defer this message
    // and fuse a later resend; a capture may not hold one.
    poll_until(loop, [&] { return node.queue_length() < node.options().queue_capacity; });
    // The captured bytes as they were sent (with their trailer if signed):
    // straight to LCM, not re-signed by this Bus; its subscribers verify them.
    if (bus.lcm().publish(event->channel, event->data, static_cast<unsigned int>(event->datalen)) != 0) {
      throw std::runtime_error(capture.string() + ": event " + std::to_string(event->eventnum) +
                               " could not be republished on " + bus.url());
    }
    bus.handle_pending();
    ++(is_map ? stats.local_maps : stats.sightings);
  }
  // LCM stops at the first event it cannot read (a capture cut short by a
  // crash ends in half an event): say how much was left.
  std::error_code error;
  const auto size = static_cast<std::int64_t>(std::filesystem::file_size(capture, error));
  if (!error) stats.unread_bytes = std::max<std::int64_t>(0, size - read_up_to);
  if (stats.events == 0 && !error && size > 0) {
    throw std::runtime_error(capture.string() + ": no lcm-logger event could be read (not a capture?)");
  }
  poll_until(loop, [&] { return !node.worker_busy() && node.queue_length() == 0; });
  return stats;
}

}  // namespace lmf::server
