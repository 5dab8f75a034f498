// What lmf-monitor knows of the system, built only from messages (docs/design.md §1:
// "a monitor shows the whole system as a refreshing text view or JSON lines,
// live or from an lcm-logger capture, and draws the map"). No LCM I/O here:
// MonitorNode feeds it decoded messages with their receive time (wall clock
// live, the event timestamp from a log), so the same code serves both.
//
// Renders: a text table (robots, then server), one JSON object with the same
// fields (NaN or infinite numbers become null, so every line parses), the
// global map as SVG, and the paper's Fig. 8 as SVG: per robot, the time taken
// by the updates over the mission with the 200 ms real-time bound of a 5 Hz
// laser marked. Its source, per robot: the agent_status_t windows (largest and
// p99 per-scan time of each window) when the robot sent any, else the time
// between consecutive scan_ack_t receptions. Its x axis is mission time, the
// log time of the scans: a window is placed at the scan the robot acknowledged
// last before its status (scan_ack_t carries the scan's utime), an ack gap at
// its scan; a robot that acknowledged no scan is placed by its status times.
// The y axis is logarithmic (0.01 ms .. above the bound), so sub-millisecond
// per-scan times are as readable as the 200 ms bound.
//
// Not thread-safe (the monitor has one thread).
#pragma once

#include <array>
#include <cstdint>
#include <filesystem>
#include <map>
#include <optional>
#include <string>
#include <utility>
#include <vector>

#include <nlohmann/json.hpp>

#include "lmf/geometry/pose2.hpp"
#include "runtime/messages.hpp"

namespace lmf::monitor {

// The real-time bound of a 5 Hz laser (paper §IV: "less than 200 ms").
inline constexpr double kRealTimeBoundMs = 200.0;

struct RobotRow {
  int robot_id = 0;
  bool have_status = false;
  bool joined = false;
  std::int64_t scans = 0;
  int local_map_segments = 0;
  double scan_p50_ms = 0.0;
  double scan_p99_ms = 0.0;
  double scan_max_ms = 0.0;
  std::int64_t maps_shipped = 0;
  std::int64_t maps_acknowledged = 0;
  bool covariance_ok = true;
  bool mission_done = false;
  Pose2 global_pose;
  std::int64_t rejects = 0;
  std::int64_t status_utime = 0;
  std::int64_t scan_acks = 0;        // scan_ack_t seen
  std::int64_t last_scan_seq = -1;   // from scan_ack_t
  std::int64_t local_map_acks = 0;   // local_map_ack_t seen for this robot
  runtime::OdometryModelReport odometry;  // from the last status: the agent's learned odometry model
};

// One point of the timing plot.
struct TimingSample {
  double time_s = 0.0;    // since the first sample of any robot: mission (log) time, see the header
  double value_ms = 0.0;  // largest per-scan time of a window, or gap between acks
  double p99_ms = -1.0;   // < 0 when unknown (scan_ack source)
};

class MonitorState {
 public:
  // receive_utime: when the message arrived (us); used for the scan-ack gaps.
  // The values as runtime/convert decoded them; extreme ones (times near the
  // int64 limits, huge counts) are survived, not trusted.
  void on_agent_status(const runtime::AgentStatus& status, std::int64_t receive_utime);
  void on_server_status(const runtime::ServerStatus& status, std::int64_t receive_utime);
  void on_global_map(const runtime::GlobalMapSummary& map, std::int64_t receive_utime);
  void on_scan_ack(const runtime::ScanAck& ack, std::int64_t receive_utime);
  void on_local_map_ack(const runtime::LocalMapAck& ack, std::int64_t receive_utime);
  // A message on `channel` that did not decode (named by reason).
  void on_rejected(const std::string& reason);
  void count_message(const std::string& channel);

  const std::map<int, RobotRow>& robots() const { return robots_; }
  // The last server status heard, if any.
  const std::optional<runtime::ServerStatus>& server() const { return server_; }
  bool have_global_map() const { return global_map_.has_value(); }
  // Bumped by every global_map_t (lets the node write the SVG only when it changed).
  std::int64_t global_map_version() const { return global_map_version_; }
  std::int64_t messages() const { return messages_; }
  std::int64_t last_receive_utime() const { return last_receive_utime_; }

  // Per robot, time-ordered samples for the timing plot (see header).
  std::map<int, std::vector<TimingSample>> timing_series() const;
  // True when every robot of timing_series() is placed in mission time (each acknowledged a scan).
  bool timing_in_mission_time() const;

  // One object: {"utime", "messages", "rejected", "robots": [...], "server": {...} | null,
  // "global_map": {...} | null}.
  nlohmann::json to_json(std::int64_t now_utime) const;
  // The text view (fixed-width table), ending with a newline.
  std::string table(std::int64_t now_utime) const;

  // Throw std::runtime_error when the file cannot be written; write_map_svg
  // draws an empty map before any global_map_t.
  void write_map_svg(const std::filesystem::path& file) const;
  void write_timing_svg(const std::filesystem::path& file) const;

 private:
  struct StatusWindow {
    std::int64_t utime = 0;
    std::optional<std::int64_t> mission_utime;  // the robot's last acknowledged scan then
    double max_ms = 0.0;
    double p99_ms = 0.0;
    int window_scans = 0;
  };
  RobotRow& robot(int robot_id);

  std::map<int, RobotRow> robots_;
  std::optional<runtime::ServerStatus> server_;
  std::optional<runtime::GlobalMapSummary> global_map_;
  std::int64_t global_map_version_ = 0;
  std::map<int, std::vector<StatusWindow>> windows_;            // per robot, from agent_status_t
  struct AckReceipt {
    std::int64_t receive_utime = 0;
    std::int64_t scan_utime = 0;  // the acknowledged scan's (log) time
  };
  std::map<int, std::vector<AckReceipt>> scan_ack_receipts_;  // per robot
  std::map<std::string, std::int64_t> rejected_;
  std::map<std::string, std::int64_t> per_channel_;
  std::int64_t messages_ = 0;
  std::int64_t last_receive_utime_ = 0;
};

}  // namespace lmf::monitor
