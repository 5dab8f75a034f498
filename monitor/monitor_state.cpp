#include "monitor/monitor_state.hpp"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <limits>
#include <sstream>

#include <Eigen/Core>

#include "lmf/io/svg.hpp"
#include "lmf/io/svg_legend.hpp"

namespace lmf::monitor {
namespace {

using nlohmann::json;

// JSON has no NaN/inf: those become null so every line parses.
json number(double v) { return std::isfinite(v) ? json(v) : json(nullptr); }

json odometry_model_json(const runtime::OdometryModelReport& report) {
  const OdometryErrorModel& m = report.model;
  return {{"translation_scale", number(m.translation_scale)},
          {"rotation_scale", number(m.rotation_scale)},
          {"heading_bias_rad_per_m", number(m.heading_bias_rad_per_m)},
          {"x_step_m", number(m.x_step_m)},
          {"x_per_m", number(m.x_per_m)},
          {"y_step_m", number(m.y_step_m)},
          {"y_per_m", number(m.y_per_m)},
          {"phi_step_rad", number(m.phi_step_rad)},
          {"phi_per_m", number(m.phi_per_m)},
          {"phi_per_rad", number(m.phi_per_rad)},
          {"phi_turn_distance", number(m.phi_turn_distance)},
          {"increments_learned", report.increments_learned},
          {"increments_downweighted", report.increments_downweighted}};
}

std::string fixed(double v, int decimals) {
  if (!std::isfinite(v)) return "-";
  char buffer[64];
  std::snprintf(buffer, sizeof buffer, "%.*f", decimals, v);
  return buffer;
}

std::string pad_left(const std::string& s, std::size_t width) {
  return s.size() >= width ? s : std::string(width - s.size(), ' ') + s;
}

std::string pad_right(const std::string& s, std::size_t width) {
  return s.size() >= width ? s : s + std::string(width - s.size(), ' ');
}

// A round tick step giving about `target` ticks over `span`.
double nice_step(double span, int target) {
  if (!(span > 0.0)) return 1.0;
  const double raw = span / target;
  const double magnitude = std::pow(10.0, std::floor(std::log10(raw)));
  for (double m : {1.0, 2.0, 5.0, 10.0}) {
    if (m * magnitude >= raw) return m * magnitude;
  }
  return 10.0 * magnitude;
}

// The timing plot's lowest time (ms): faster updates are drawn there.
constexpr double kTimingFloorMs = 0.01;

const char* kPalette[] = {"#1f77b4", "#d62728", "#2ca02c", "#9467bd", "#ff7f0e", "#8c564b", "#e377c2", "#17becf"};

}  // namespace

RobotRow& MonitorState::robot(int robot_id) {
  RobotRow& row = robots_[robot_id];
  row.robot_id = robot_id;
  return row;
}

void MonitorState::count_message(const std::string& channel) {
  ++messages_;
  ++per_channel_[channel];
}

void MonitorState::on_rejected(const std::string& reason) { ++rejected_[reason]; }

void MonitorState::on_agent_status(const runtime::AgentStatus& status, std::int64_t receive_utime) {
  last_receive_utime_ = std::max(last_receive_utime_, receive_utime);
  RobotRow& row = robot(status.robot_id);
  row.have_status = true;
  row.joined = status.joined;
  row.scans = status.scans;
  row.local_map_segments = status.local_map_segments;
  row.scan_p50_ms = status.scan_time_p50_ms;
  row.scan_p99_ms = status.scan_time_p99_ms;
  row.scan_max_ms = status.scan_time_max_ms;
  row.maps_shipped = status.maps_shipped;
  row.maps_acknowledged = status.maps_acknowledged;
  row.covariance_ok = status.covariance_ok;
  row.mission_done = status.mission_done;
  row.global_pose = status.x_WR;
  row.odometry = status.odometry;
  row.rejects = 0;
  // Saturating: the counts come off the network (a forged INT64_MAX must not overflow).
  constexpr std::int64_t kMaxCount = std::numeric_limits<std::int64_t>::max();
  for (const auto& [reason, c] : status.rejects) {
    if (c > 0) row.rejects = row.rejects > kMaxCount - c ? kMaxCount : row.rejects + c;
  }
  row.status_utime = status.utime;
  if (status.window_scans > 0) {
    const auto acks = scan_ack_receipts_.find(status.robot_id);
    std::optional<std::int64_t> mission_utime;
    if (acks != scan_ack_receipts_.end() && !acks->second.empty()) mission_utime = acks->second.back().scan_utime;
    windows_[status.robot_id].push_back(
        {status.utime, mission_utime, status.scan_time_max_ms, status.scan_time_p99_ms, status.window_scans});
  }
}

void MonitorState::on_server_status(const runtime::ServerStatus& status, std::int64_t receive_utime) {
  last_receive_utime_ = std::max(last_receive_utime_, receive_utime);
  server_ = status;
}

void MonitorState::on_global_map(const runtime::GlobalMapSummary& map, std::int64_t receive_utime) {
  last_receive_utime_ = std::max(last_receive_utime_, receive_utime);
  runtime::GlobalMapSummary summary = map;
  // Drawn only where finite (convert refuses others; a caller might not use it).
  std::erase_if(summary.endpoints, [](const std::array<double, 4>& e) {
    return !std::all_of(e.begin(), e.end(), [](double v) { return std::isfinite(v); });
  });
  global_map_ = std::move(summary);
  ++global_map_version_;
}

void MonitorState::on_scan_ack(const runtime::ScanAck& ack, std::int64_t receive_utime) {
  last_receive_utime_ = std::max(last_receive_utime_, receive_utime);
  RobotRow& row = robot(ack.robot_id);
  ++row.scan_acks;
  row.last_scan_seq = std::max(row.last_scan_seq, ack.seq);
  scan_ack_receipts_[ack.robot_id].push_back({receive_utime, ack.utime});
}

void MonitorState::on_local_map_ack(const runtime::LocalMapAck& ack, std::int64_t receive_utime) {
  last_receive_utime_ = std::max(last_receive_utime_, receive_utime);
  ++robot(ack.robot_id).local_map_acks;
}

std::map<int, std::vector<TimingSample>> MonitorState::timing_series() const {
  // Each sample's time (us): mission time where the robot acknowledged scans,
  // else the status time; in double, as utimes come off the network.
  std::map<int, std::vector<std::pair<double, TimingSample>>> stamped;
  for (const auto& [id, w] : windows_) {
    const bool by_scan = std::any_of(w.begin(), w.end(), [](const StatusWindow& s) { return s.mission_utime.has_value(); });
    for (const StatusWindow& s : w) {
      if (by_scan && !s.mission_utime) continue;  // before its first ack: no scan to place it at
      const double t = static_cast<double>(by_scan ? *s.mission_utime : s.utime);
      stamped[id].push_back({t, {0.0, s.max_ms, s.p99_ms}});
    }
  }
  for (const auto& [id, r] : scan_ack_receipts_) {
    if (windows_.count(id)) continue;
    for (std::size_t i = 1; i < r.size(); ++i) {
      stamped[id].push_back({static_cast<double>(r[i].scan_utime),
                             {0.0, (static_cast<double>(r[i].receive_utime) - static_cast<double>(r[i - 1].receive_utime)) * 1e-3,
                              -1.0}});
    }
  }
  double t0 = std::numeric_limits<double>::infinity();
  for (const auto& [id, samples] : stamped) {
    for (const auto& [t, sample] : samples) t0 = std::min(t0, t);
  }
  std::map<int, std::vector<TimingSample>> out;
  for (auto& [id, samples] : stamped) {
    std::vector<TimingSample>& series = out[id];
    for (auto& [t, sample] : samples) {
      sample.time_s = (t - t0) * 1e-6;
      series.push_back(sample);
    }
    std::stable_sort(series.begin(), series.end(),
                     [](const TimingSample& a, const TimingSample& b) { return a.time_s < b.time_s; });
  }
  return out;
}

bool MonitorState::timing_in_mission_time() const {
  for (const auto& [id, w] : windows_) {
    if (std::none_of(w.begin(), w.end(), [](const StatusWindow& s) { return s.mission_utime.has_value(); })) return false;
  }
  return true;
}

json MonitorState::to_json(std::int64_t now_utime) const {
  json j;
  j["utime"] = now_utime;
  j["messages"] = messages_;
  json channels = json::object();
  for (const auto& [name, count] : per_channel_) channels[name] = count;
  j["channels"] = std::move(channels);
  json rejected = json::object();
  for (const auto& [name, count] : rejected_) rejected[name] = count;
  j["rejected"] = std::move(rejected);

  json robots = json::array();
  for (const auto& [id, r] : robots_) {
    robots.push_back({{"robot_id", id},
                      {"have_status", r.have_status},
                      {"joined", r.joined},
                      {"local_map_segments", r.local_map_segments},
                      {"scans", r.scans},
                      {"scan_p50_ms", number(r.scan_p50_ms)},
                      {"scan_p99_ms", number(r.scan_p99_ms)},
                      {"scan_max_ms", number(r.scan_max_ms)},
                      {"maps_shipped", r.maps_shipped},
                      {"maps_acknowledged", r.maps_acknowledged},
                      {"covariance_ok", r.covariance_ok},
                      {"mission_done", r.mission_done},
                      {"global_pose", {number(r.global_pose.x), number(r.global_pose.y), number(r.global_pose.phi)}},
                      {"rejects", r.rejects},
                      {"scan_acks", r.scan_acks},
                      {"last_scan_seq", r.last_scan_seq},
                      {"local_map_acks", r.local_map_acks},
                      {"odometry_model", odometry_model_json(r.odometry)}});
  }
  j["robots"] = std::move(robots);

  if (server_.has_value()) {
    json rejects = json::object();
    for (const auto& [name, count] : server_->rejects) rejects[name] = count;
    j["server"] = {{"utime", server_->utime},
                   {"robots_joined", server_->robots_joined},
                   {"segments", server_->segments},
                   {"submaps", server_->submaps},
                   {"graph_edges", server_->graph_edges},
                   {"fusions", server_->fusions},
                   {"last_fusion_ms", number(server_->last_fusion_ms)},
                   {"mean_fusion_ms", number(server_->mean_fusion_ms)},
                   {"queue_length", server_->queue_length},
                   {"covariance_ok", server_->covariance_ok},
                   {"min_eigenvalue", number(server_->min_eigenvalue)},
                   {"rejects", std::move(rejects)}};
  } else {
    j["server"] = nullptr;
  }
  if (global_map_) {
    j["global_map"] = {{"utime", global_map_->utime},
                       {"fusion_count", global_map_->fusion_count},
                       {"segments", global_map_->endpoints.size()},
                       {"submaps", global_map_->submaps},
                       {"graph_edges", global_map_->graph_edges}};
  } else {
    j["global_map"] = nullptr;
  }
  return j;
}

std::string MonitorState::table(std::int64_t now_utime) const {
  std::ostringstream out;
  std::int64_t rejected = 0;
  for (const auto& [name, count] : rejected_) rejected += count;
  out << "lmf monitor   messages " << messages_ << "   undecodable " << rejected << "   t "
      << fixed(static_cast<double>(now_utime) * 1e-6, 1) << " s\n\n";

  out << "ROBOT  JOINED  LM_SEGS     SCANS  P99_MS  MAX_MS  SHIPPED/ACKED  DONE  COV  REJ  GLOBAL POSE x y phi\n";
  if (robots_.empty()) out << "  (no robot heard yet)\n";
  for (const auto& [id, r] : robots_) {
    out << pad_left(std::to_string(id), 5) << "  ";
    if (!r.have_status) {
      out << "(no status; scan acks " << r.scan_acks << ", last scan " << r.last_scan_seq << ", map acks "
          << r.local_map_acks << ")\n";
      continue;
    }
    out << pad_right(r.joined ? "yes" : "no", 6) << "  " << pad_left(std::to_string(r.local_map_segments), 7) << "  "
        << pad_left(std::to_string(r.scans), 8) << "  " << pad_left(fixed(r.scan_p99_ms, 1), 6) << "  "
        << pad_left(fixed(r.scan_max_ms, 1), 6) << "  "
        << pad_left(std::to_string(r.maps_shipped) + "/" + std::to_string(r.maps_acknowledged), 13) << "  "
        << pad_right(r.mission_done ? "yes" : "no", 4) << "  " << pad_right(r.covariance_ok ? "ok" : "BAD", 3) << "  "
        << pad_left(std::to_string(r.rejects), 3) << "  " << pad_left(fixed(r.global_pose.x, 2), 8) << ' '
        << pad_left(fixed(r.global_pose.y, 2), 8) << ' ' << pad_left(fixed(r.global_pose.phi, 3), 6) << '\n';
  }
  for (const auto& [id, r] : robots_) {
    if (!r.have_status) continue;
    const OdometryErrorModel& m = r.odometry.model;
    out << "  robot " << id << " odometry: translation x" << fixed(m.translation_scale, 3) << ", rotation x"
        << fixed(m.rotation_scale, 3) << ", heading sigma " << fixed(m.phi_step_rad * 180.0 / 3.14159265358979, 2)
        << " deg/step + " << fixed(m.phi_per_m * 180.0 / 3.14159265358979, 2) << " deg/m (learned from "
        << r.odometry.increments_learned << " matches, " << r.odometry.increments_downweighted << " glitches)\n";
  }
  out << '\n';
  if (!server_.has_value()) {
    out << "SERVER  (no status heard yet)\n";
  } else {
    out << "SERVER  joined " << server_->robots_joined << "  segments " << server_->segments << "  submaps "
        << server_->submaps << "  graph edges " << server_->graph_edges << "  fusions " << server_->fusions << '\n'
        << "        fusion last " << fixed(server_->last_fusion_ms, 2) << " ms  mean " << fixed(server_->mean_fusion_ms, 2)
        << " ms  queue " << server_->queue_length << "  PSD " << (server_->covariance_ok ? "ok" : "FAILED")
        << " (min pivot " << server_->min_eigenvalue << ")\n"
        << "        rejects:";
    if (server_->rejects.empty()) out << " none";
    for (const auto& [name, count] : server_->rejects) out << ' ' << name << '=' << count;
    out << '\n';
  }
  if (global_map_) {
    out << "MAP     " << global_map_->endpoints.size() << " segments, " << global_map_->submaps << " submaps, "
        << global_map_->graph_edges << " graph edges after " << global_map_->fusion_count << " fusions\n";
  }
  return out.str();
}

void MonitorState::write_map_svg(const std::filesystem::path& file) const {
  io::SvgDocument svg(20.0, 20.0);
  svg.set_title("lmf global map");
  svg.begin_group("segments", "segments");
  io::SvgStyle wall;
  wall.stroke = "black";
  wall.stroke_width_px = 2.0;
  if (global_map_) {
    for (const auto& e : global_map_->endpoints) {
      svg.add_line(Eigen::Vector2d(e[0], e[1]), Eigen::Vector2d(e[2], e[3]), wall);
    }
  }
  svg.end_group();
  svg.begin_group("robots", "robots");
  std::size_t colour = 0;
  for (const auto& [id, r] : robots_) {
    if (!r.have_status || !r.joined) continue;
    io::SvgStyle dot;
    dot.stroke = "none";
    dot.fill = kPalette[colour++ % std::size(kPalette)];
    const Eigen::Vector2d p(r.global_pose.x, r.global_pose.y);
    if (!p.allFinite()) continue;  // a hostile or broken agent_status_t: SvgDocument refuses it
    svg.add_dot(p, 4.0, dot);
    io::SvgTextStyle label;
    label.color = dot.fill;
    svg.add_text(p + Eigen::Vector2d(0.3, 0.3), "robot " + std::to_string(id), label);
  }
  svg.end_group();
  // global_map_t carries the segments only (the graph is counted, not sent):
  // the server's own map.svg draws the environment graph with --map-graph.
  io::SvgStyle robot_dot;
  robot_dot.stroke = "none";
  robot_dot.fill = "#555";
  io::add_legend(svg,
                 {{io::SvgLegendEntry::Mark::kLine, wall, "wall segment"},
                  {io::SvgLegendEntry::Mark::kDot, robot_dot, "robot (global pose)"}},
                 io::legend_right_of_bounds(svg));
  svg.add_scale_bar();
  svg.write(file);
}

void MonitorState::write_timing_svg(const std::filesystem::path& file) const {
  const auto series = timing_series();
  // y: log10 of the time in ms, from 0.01 ms (a faster update is drawn there) to
  // the decade above the largest time or the bound.
  const auto y_of = [](double ms) { return std::log10(std::max(ms, kTimingFloorMs)); };
  double t_max = 1.0;
  double v_max = kRealTimeBoundMs;
  for (const auto& [id, samples] : series) {
    for (const TimingSample& s : samples) {
      if (std::isfinite(s.time_s)) t_max = std::max(t_max, s.time_s);
      if (std::isfinite(s.value_ms)) v_max = std::max(v_max, s.value_ms);
    }
  }
  const double y_lo = y_of(kTimingFloorMs);
  const double y_hi = std::ceil(y_of(v_max) + 1e-9);
  const double y_span = y_hi - y_lo;
  // x: seconds, y: decades, scaled to a ~900 x 400 px plot.
  io::SvgDocument svg(1.0, 40.0);
  svg.set_scale(900.0 / t_max, 400.0 / y_span);
  svg.set_title("Elapsed time between consecutive updates (paper Fig. 8)");
  const auto at = [&](double t, double y) { return Eigen::Vector2d(t, y); };

  io::SvgStyle axis;
  axis.stroke = "#444";
  io::SvgStyle grid;
  grid.stroke = "#ddd";
  io::SvgStyle minor = grid;
  minor.stroke = "#f0f0f0";
  io::SvgTextStyle tick;
  tick.size_px = 10.0;
  tick.anchor = "middle";
  svg.begin_group("axes", "axes");
  svg.add_line(at(0, y_lo), at(t_max, y_lo), axis);
  svg.add_line(at(0, y_lo), at(0, y_hi), axis);
  const double t_step = nice_step(t_max, 8);
  for (double t = 0.0; t <= t_max + 1e-9; t += t_step) {
    svg.add_line(at(t, y_lo), at(t, y_hi), grid);
    svg.add_text(at(t, y_lo - 0.05 * y_span), fixed(t, t_step < 1.0 ? 1 : 0), tick);
  }
  io::SvgTextStyle ytick = tick;
  ytick.anchor = "end";
  for (double decade = y_lo; decade <= y_hi + 1e-9; decade += 1.0) {
    svg.add_line(at(0, decade), at(t_max, decade), grid);
    const double ms = std::pow(10.0, decade);
    svg.add_text(at(-0.01 * t_max, decade - 0.02 * y_span), ms < 1.0 ? fixed(ms, static_cast<int>(-decade)) : fixed(ms, 0),
                 ytick);
    for (double m : {2.0, 5.0}) {
      if (decade + std::log10(m) < y_hi) svg.add_line(at(0, decade + std::log10(m)), at(t_max, decade + std::log10(m)), minor);
    }
  }
  io::SvgTextStyle label;
  label.size_px = 12.0;
  label.anchor = "middle";
  svg.add_text(at(0.5 * t_max, y_lo - 0.1 * y_span),
               timing_in_mission_time() ? "mission time (s, log time of the scans)" : "time (s, status messages)", label);
  label.anchor = "start";
  svg.add_text(at(-0.07 * t_max, y_hi + 0.04 * y_span), "update time (ms, log scale)", label);
  svg.end_group();

  io::SvgStyle bound;
  bound.stroke = "red";
  bound.stroke_width_px = 1.5;
  bound.dash_px = "8 4";
  svg.begin_group("200 ms bound", "bound");
  svg.add_line(at(0, y_of(kRealTimeBoundMs)), at(t_max, y_of(kRealTimeBoundMs)), bound);
  io::SvgTextStyle bound_label;
  bound_label.color = "red";
  bound_label.anchor = "start";
  svg.add_text(at(0.01 * t_max, y_of(kRealTimeBoundMs) + 0.02 * y_span), "200 ms (5 Hz laser)", bound_label);
  svg.end_group();

  std::vector<io::SvgLegendEntry> legend;
  std::size_t colour = 0;
  for (const auto& [id, samples] : series) {
    const std::string c = kPalette[colour++ % std::size(kPalette)];
    svg.begin_group("robot " + std::to_string(id), "robot" + std::to_string(id));
    std::vector<Eigen::Vector2d> line;
    std::vector<Eigen::Vector2d> p99;
    for (const TimingSample& s : samples) {
      if (!std::isfinite(s.time_s)) continue;
      if (std::isfinite(s.value_ms)) line.push_back(at(s.time_s, y_of(s.value_ms)));
      if (s.p99_ms >= 0.0 && std::isfinite(s.p99_ms)) p99.push_back(at(s.time_s, y_of(s.p99_ms)));
    }
    io::SvgStyle style;
    style.stroke = c;
    if (line.size() >= 2) svg.add_polyline(line, style);
    if (line.size() == 1) {
      io::SvgStyle dot;
      dot.stroke = "none";
      dot.fill = c;
      svg.add_dot(line.front(), 2.0, dot);
    }
    const bool from_status = !samples.empty() && samples.front().p99_ms >= 0.0;
    legend.push_back({io::SvgLegendEntry::Mark::kLine, style,
                      "robot " + std::to_string(id) + (from_status ? ": max per status window" : ": time between scan acks")});
    if (p99.size() >= 2) {
      style.dash_px = "2 2";
      style.stroke_opacity = 0.6;
      svg.add_polyline(p99, style);
      legend.push_back({io::SvgLegendEntry::Mark::kLine, style, "robot " + std::to_string(id) + ": p99 per window"});
    }
    svg.end_group();
  }
  legend.push_back({io::SvgLegendEntry::Mark::kLine, bound, "real-time bound"});
  // Right of the plot, level with its top.
  const double legend_x = 1.03 * t_max;
  io::add_legend(svg, legend, at(legend_x, y_hi));
  const double legend_width = io::legend_size_px(legend).x() / svg.pixels_per_unit_x();
  svg.set_bounds(Eigen::Vector2d(-0.08 * t_max, y_lo - 0.12 * y_span),
                 Eigen::Vector2d(legend_x + legend_width + 0.01 * t_max, y_hi + 0.08 * y_span));
  svg.write(file);
}

}  // namespace lmf::monitor
