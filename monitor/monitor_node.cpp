#include "monitor/monitor_node.hpp"

#include <exception>
#include <iostream>
#include <stdexcept>

#include <lcm/lcm-cpp.hpp>

#include "runtime/auth.hpp"
#include "runtime/convert.hpp"

namespace lmf::monitor {
namespace {

std::int64_t wall_utime() {
  return std::chrono::duration_cast<std::chrono::microseconds>(
             std::chrono::system_clock::now().time_since_epoch())
      .count();
}

std::size_t sample_count(const std::map<int, std::vector<TimingSample>>& series) {
  std::size_t n = 0;
  for (const auto& [id, samples] : series) n += samples.size();
  return n;
}

}  // namespace

void MonitorOptions::validate() const {
  if (refresh.count() <= 0) throw std::invalid_argument("--refresh-ms must be > 0");
}

MonitorNode::MonitorNode(runtime::Bus& bus, runtime::EventLoop& loop, runtime::Channels channels,
                         MonitorOptions options, std::ostream& out)
    : bus_(&bus), loop_(&loop), channels_(std::move(channels)), options_(std::move(options)), out_(out) {
  options_.validate();
  // Everything of the system, so the message counts are complete; decoding
  // happens only for the channels shown.
  subscriptions_.push_back(bus_->subscribe(
      channels_.all(), [this](const std::string& channel, const void* data, std::size_t size) {
        handle(channel, data, size, wall_utime());
      }));
  timer_ = loop_->every(options_.refresh, [this] { refresh(wall_utime()); });
}

MonitorNode::MonitorNode(runtime::Channels channels, MonitorOptions options, std::ostream& out)
    : channels_(std::move(channels)), options_(std::move(options)), out_(out) {
  options_.validate();
}

MonitorNode::~MonitorNode() {
  if (loop_ && timer_) loop_->cancel(*timer_);
  if (bus_) {
    for (int id : subscriptions_) bus_->unsubscribe(id);
  }
}

template <class Core, class OnMessage>
void MonitorNode::decode_into(const void* data, std::size_t size, OnMessage on_message) {
  auto value = runtime::decode<Core>(data, size);
  if (!value) {
    state_.on_rejected(std::string(runtime::reason_name(value.rejection().reason)));
    return;
  }
  on_message(value.value());
}

void MonitorNode::handle(const std::string& channel, const void* data, std::size_t size,
                         std::int64_t receive_utime) {
  try {
    state_.count_message(channel);
    if (channel == channels_.agent_status()) {
      decode_into<runtime::AgentStatus>(data, size, [&](const auto& m) { state_.on_agent_status(m, receive_utime); });
    } else if (channel == channels_.server_status()) {
      decode_into<runtime::ServerStatus>(data, size, [&](const auto& m) { state_.on_server_status(m, receive_utime); });
    } else if (channel == channels_.global_map()) {
      decode_into<runtime::GlobalMapSummary>(data, size, [&](const auto& m) { state_.on_global_map(m, receive_utime); });
    } else if (channel == channels_.scan_ack()) {
      decode_into<runtime::ScanAck>(data, size, [&](const auto& m) { state_.on_scan_ack(m, receive_utime); });
    } else if (channel == channels_.local_map_ack()) {
      decode_into<runtime::LocalMapAck>(data, size, [&](const auto& m) { state_.on_local_map_ack(m, receive_utime); });
    }
  } catch (const std::exception& e) {
    // Only a bug of ours gets here; the monitor keeps going.
    state_.on_rejected(std::string(runtime::reason_name(runtime::RejectReason::kHandlerError)));
    std::cerr << "lmf-monitor: " << channel << ": " << e.what() << '\n';
  }
}

bool MonitorNode::refresh(std::int64_t now_utime) {
  if (options_.json) {
    out_ << state_.to_json(now_utime).dump() << '\n';
  } else {
    if (options_.redraw_in_place) out_ << "\x1b[H\x1b[2J";  // cursor home, clear screen
    out_ << state_.table(now_utime);
    if (!options_.redraw_in_place) out_ << '\n';
  }
  out_.flush();
  bool ok = true;
  try {
    if (options_.map_svg && state_.global_map_version() != written_map_version_) {
      state_.write_map_svg(*options_.map_svg);
      written_map_version_ = state_.global_map_version();
    }
    if (options_.timing_svg) {
      const std::size_t samples = sample_count(state_.timing_series());
      if (samples != written_timing_samples_ || samples == 0) {
        state_.write_timing_svg(*options_.timing_svg);
        written_timing_samples_ = samples;
      }
    }
  } catch (const std::exception& e) {
    std::cerr << "lmf-monitor: " << e.what() << '\n';
    ok = false;
  }
  return ok;
}

std::int64_t MonitorNode::replay_log(const std::filesystem::path& file,
                                     const std::optional<runtime::auth::Config>& keys) {
  lcm::LogFile log(file.string(), "r");
  if (!log.good()) throw std::runtime_error(file.string() + ": cannot open as an lcm-logger file");
  std::optional<runtime::auth::Verifier> verifier;
  if (keys) {
    keys->validate();
    verifier.emplace(keys->keys, keys->replay_window);
  }
  const std::int64_t period_us = std::chrono::duration_cast<std::chrono::microseconds>(options_.refresh).count();
  std::int64_t events = 0;
  std::optional<std::int64_t> next_refresh;
  std::int64_t last_time = 0;
  while (const lcm::LogEvent* event = log.readNextEvent()) {
    ++events;
    last_time = event->timestamp;
    if (!next_refresh) next_refresh = event->timestamp + period_us;
    // Refresh points passed before this event (JSON lines only: a table per
    // period of a log would just scroll by).
    if (options_.json && event->timestamp >= *next_refresh) {
      refresh(*next_refresh);
      // A long silence in the log gives one line, not one per period.
      const std::int64_t skipped = (event->timestamp - *next_refresh) / period_us;
      *next_refresh += (skipped + 1) * period_us;
    }
    const auto* bytes = static_cast<const std::uint8_t*>(event->data);
    const auto length = static_cast<std::size_t>(event->datalen);
    const bool system_channel = event->channel.rfind(channels_.prefix(), 0) == 0;
    if (!verifier || !system_channel) {
      // A capture of a system running with --keys holds signed messages: their
      // LCM part, unchecked (the capture file is trusted as a whole). Other
      // channels (LCM's own self test) are never shown, only counted.
      handle(event->channel, event->data, runtime::auth::unverified_payload_size(bytes, length), event->timestamp);
      continue;
    }
    const auto payload = verifier->verify(event->channel, {bytes, length});
    if (!payload) {
      log_rejections_.record(payload.rejection(), file.string() + " event " + std::to_string(event->eventnum) +
                                                      " on " + event->channel);
      continue;
    }
    handle(event->channel, payload.value().data(), payload.value().size(), event->timestamp);
  }
  refresh(last_time);
  return events;
}

}  // namespace lmf::monitor
