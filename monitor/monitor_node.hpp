// lmf-monitor's node: subscribes to the status, map and acknowledgement
// channels, keeps a MonitorState, and prints it every refresh as a table
// (redrawn in place on a terminal) or as one JSON line. Optionally writes the
// global map and the timing plot (paper Fig. 8) as SVG files on each refresh
// where they changed.
//
// The same node reads an lcm-logger file (replay_log): events are handled in
// file order with their logged timestamps as receive times, refreshes happen
// every refresh period of LOG time, and a last refresh is printed at the end.
//
// Threading: the loop's thread only. Nothing thrown while handling a message
// escapes into LCM (decode failures are counted in the state by reason).
#pragma once

#include <chrono>
#include <cstdint>
#include <filesystem>
#include <optional>
#include <ostream>
#include <string>
#include <vector>

#include "monitor/monitor_state.hpp"
#include "runtime/auth.hpp"
#include "runtime/bus.hpp"
#include "runtime/channels.hpp"
#include "runtime/event_loop.hpp"
#include "runtime/rejection.hpp"

namespace lmf::monitor {

struct MonitorOptions {
  bool json = false;              // JSON lines instead of the table
  bool redraw_in_place = false;   // clear the terminal before each table (set by main on a tty)
  std::chrono::milliseconds refresh{1000};
  std::optional<std::filesystem::path> map_svg;     // written when a new global_map_t arrived
  std::optional<std::filesystem::path> timing_svg;  // written on each refresh with new timing data
  void validate() const;          // throws std::invalid_argument
};

class MonitorNode {
 public:
  // Live: subscribes on `bus` and refreshes on `loop`'s timer. Output goes to `out`.
  MonitorNode(runtime::Bus& bus, runtime::EventLoop& loop, runtime::Channels channels, MonitorOptions options,
              std::ostream& out);
  // Offline (replay_log): no bus, no loop.
  MonitorNode(runtime::Channels channels, MonitorOptions options, std::ostream& out);
  ~MonitorNode();
  MonitorNode(const MonitorNode&) = delete;
  MonitorNode& operator=(const MonitorNode&) = delete;

  // One message as received on `channel` at receive_utime (us). Channels the
  // monitor does not show are counted only.
  void handle(const std::string& channel, const void* data, std::size_t size, std::int64_t receive_utime);

  // Prints the table or a JSON line for time `now_utime` and writes the SVGs
  // that changed. Returns false if writing an SVG failed (logged to stderr).
  bool refresh(std::int64_t now_utime);

  // Reads every event of an lcm-logger file through handle(), refreshing every
  // refresh period of log time (JSON mode) and once at the end (both modes).
  // With `keys` (a capture of a system running with --keys, and the keys of
  // every sender in it, as the monitor's keys file holds them), each event must
  // carry a valid signature of a sender allowed to send it, fresh for that
  // sender (events on channels outside the system's prefix, never shown, are
  // only counted): the others are counted (log_rejections()), reported on stderr with
  // their file and event number, and skipped. Without keys a signed capture's
  // trailers are stripped unchecked. Returns the number of events read; throws
  // std::runtime_error if the file cannot be opened.
  std::int64_t replay_log(const std::filesystem::path& file,
                          const std::optional<runtime::auth::Config>& keys = std::nullopt);
  const runtime::RejectCounter& log_rejections() const { return log_rejections_; }

  const MonitorState& state() const { return state_; }

 private:
  template <class Core, class OnMessage>
  void decode_into(const void* data, std::size_t size, OnMessage on_message);

  runtime::Bus* bus_ = nullptr;
  runtime::EventLoop* loop_ = nullptr;
  runtime::Channels channels_;
  MonitorOptions options_;
  std::ostream& out_;
  MonitorState state_;
  std::int64_t written_map_version_ = 0;
  std::size_t written_timing_samples_ = 0;
  std::vector<int> subscriptions_;
  std::optional<int> timer_;
  runtime::RejectCounter log_rejections_;
};

}  // namespace lmf::monitor
