#include "lmf/fusion/map_export.hpp"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <fstream>
#include <map>
#include <stdexcept>

#include "lmf/io/svg_legend.hpp"

namespace lmf::fusion {
namespace {

nlohmann::json pose_json(const Pose2& p) { return nlohmann::json::array({p.x, p.y, p.phi}); }

nlohmann::json point_json(const Eigen::Vector2d& p) { return nlohmann::json::array({p.x(), p.y()}); }

template <typename Matrix>
nlohmann::json matrix_json(const Matrix& M) {
  nlohmann::json rows = nlohmann::json::array();
  for (Eigen::Index i = 0; i < M.rows(); ++i) {
    nlohmann::json row = nlohmann::json::array();
    for (Eigen::Index j = 0; j < M.cols(); ++j) row.push_back(M(i, j));
    rows.push_back(row);
  }
  return rows;
}

const char* kind_name(GraphEdge::Kind kind) { return kind == GraphEdge::Kind::kConsecutive ? "consecutive" : "paired"; }

const std::vector<std::string>& palette() {
  static const std::vector<std::string> colors{"#1f77b4", "#ff7f0e", "#2ca02c", "#d62728",
                                               "#9467bd", "#8c564b", "#e377c2", "#17becf"};
  return colors;
}

std::string robot_color(int robot_id) {
  const auto& p = palette();
  return p[static_cast<std::size_t>(std::abs(robot_id)) % p.size()];
}

// A small triangle pointing along the frame's x axis (size in metres).
std::vector<Eigen::Vector2d> frame_marker(const Pose2& x, double size) {
  return {x.transform_point({size, 0.0}), x.transform_point({-0.5 * size, 0.5 * size}),
          x.transform_point({-0.5 * size, -0.5 * size})};
}

}  // namespace

nlohmann::json map_to_json(const GlobalMap& map) {
  nlohmann::json doc;
  doc["format"] = "lmf-map";
  doc["version"] = 1;

  const MapCounts c = map.counts();
  doc["counts"] = {{"segments", c.segments},
                   {"submaps", c.submaps},
                   {"robots", c.robots_joined},
                   {"graph_edges", c.graph_edges},
                   {"queued_local_maps", c.queued_local_maps},
                   {"state_dimension", c.state_dimension}};

  nlohmann::json segments = nlohmann::json::array();
  for (const SegmentView& s : map.segments()) {
    segments.push_back({{"id", s.id},
                        {"submap", s.submap},
                        {"start", point_json(s.start_W)},
                        {"end", point_json(s.end_W)},
                        {"pose", pose_json(s.x_WS)},
                        {"length_m", s.length_m},
                        {"covariance", matrix_json(s.covariance)}});
  }
  doc["segments"] = segments;

  nlohmann::json submaps = nlohmann::json::array();
  nlohmann::json nodes = nlohmann::json::array();
  for (const SubmapView& f : map.submaps()) {
    submaps.push_back({{"id", f.frame},
                       {"robot", f.robot_id},
                       {"seq", f.seq},
                       {"pose", pose_json(f.x_WF)},
                       {"covariance", matrix_json(f.covariance)},
                       {"segments", f.segments}});
    nodes.push_back(f.frame);
  }
  doc["submaps"] = submaps;

  nlohmann::json robots = nlohmann::json::array();
  for (const CorrectedFrame& r : map.corrected_frames()) {
    robots.push_back({{"id", r.robot_id},
                      {"seq", r.map_seq},  // the local map that begins at "frame"
                      {"frame", pose_json(r.x_WL)},
                      {"covariance", matrix_json(r.covariance)}});
  }
  doc["robots"] = robots;

  nlohmann::json edges = nlohmann::json::array();
  for (const GraphEdge& e : map.graph_edges()) edges.push_back({{"a", e.a}, {"b", e.b}, {"kind", kind_name(e.kind)}});
  doc["graph"] = {{"nodes", nodes}, {"edges", edges}};
  return doc;
}

void write_map_json(const GlobalMap& map, const std::filesystem::path& file) {
  std::ofstream out(file);
  if (!out) throw std::runtime_error("write_map_json: cannot open " + file.string());
  out << map_to_json(map).dump(2) << '\n';
  if (!out) throw std::runtime_error("write_map_json: cannot write " + file.string());
}

io::SvgDocument map_to_svg(const GlobalMap& map, const std::vector<MapTrajectory>& trajectories,
                           const MapSvgOptions& options) {
  io::SvgDocument doc(options.pixels_per_metre);
  doc.set_title(options.title);
  const std::vector<SegmentView> segments = map.segments();
  const std::vector<SubmapView> submaps = map.submaps();

  if (!trajectories.empty()) {
    doc.begin_group("trajectories", "trajectories");
    for (std::size_t t = 0; t < trajectories.size(); ++t) {
      const MapTrajectory& tr = trajectories[t];
      std::vector<Eigen::Vector2d> points;
      points.reserve(tr.poses.size());
      for (const Pose2& p : tr.poses) points.emplace_back(p.x, p.y);
      io::SvgStyle style;
      style.stroke = tr.color.empty() ? palette()[t % palette().size()] : tr.color;
      style.stroke_width_px = 1.2;
      style.stroke_opacity = 0.8;
      style.css_class = "trajectory";
      doc.begin_group(tr.label.empty() ? "trajectory " + std::to_string(t) : tr.label);
      doc.add_polyline(points, style);
      doc.end_group();
    }
    doc.end_group();
  }

  if (options.sigma_bands) {
    // Lateral error at distance s from the midpoint: δy + s δφ, so its
    // variance is C00 + 2 s C01 + s² C11 (the band widens with the angle error).
    doc.begin_group(std::to_string(options.band_sigmas) + "-sigma bands", "bands");
    io::SvgStyle style;
    style.stroke = "none";
    style.fill = "#1f77b4";
    style.fill_opacity = 0.2;
    constexpr int kSamples = 9;
    for (const SegmentView& s : segments) {
      std::vector<Eigen::Vector2d> left;
      std::vector<Eigen::Vector2d> right;
      for (int i = 0; i < kSamples; ++i) {
        const double along = s.length_m * (static_cast<double>(i) / (kSamples - 1) - 0.5);
        const double var =
            s.covariance(0, 0) + 2.0 * along * s.covariance(0, 1) + along * along * s.covariance(1, 1);
        const double w = options.band_sigmas * std::sqrt(std::max(0.0, var));
        left.push_back(s.x_WS.transform_point({along, w}));
        right.push_back(s.x_WS.transform_point({along, -w}));
      }
      doc.add_band(left, right, style);
    }
    doc.end_group();
  }

  // The environment graph under the walls and faint: hundreds of edges of a
  // mission otherwise hide the map they describe.
  if (options.graph && !submaps.empty()) {
    std::map<EntityId, Eigen::Vector2d> node;
    for (const SubmapView& f : submaps) node[f.frame] = Eigen::Vector2d(f.x_WF.x, f.x_WF.y);
    doc.begin_group("environment graph", "graph");
    for (const GraphEdge& e : map.graph_edges()) {
      io::SvgStyle style;
      style.stroke = e.kind == GraphEdge::Kind::kConsecutive ? "#2ca02c" : "#d62728";
      style.stroke_width_px = 1.0;
      style.stroke_opacity = e.kind == GraphEdge::Kind::kConsecutive ? 0.6 : 0.3;
      style.dash_px = e.kind == GraphEdge::Kind::kConsecutive ? "" : "4 3";
      style.css_class = std::string("edge-") + kind_name(e.kind);
      doc.add_line(node.at(e.a), node.at(e.b), style);
    }
    io::SvgStyle dot;
    dot.stroke = "none";
    dot.fill = "#d62728";
    dot.fill_opacity = 0.6;
    for (const auto& [id, p] : node) doc.add_dot(p, 3.0, dot);
    doc.end_group();
  }

  doc.begin_group("segments", "segments");
  {
    io::SvgStyle style;
    style.stroke = "black";
    style.stroke_width_px = 2.0;
    style.css_class = "segment";
    for (const SegmentView& s : segments) doc.add_line(s.start_W, s.end_W, style);
  }
  doc.end_group();

  if (options.frames) {
    doc.begin_group("submap frames", "submaps");
    for (const SubmapView& f : submaps) {
      io::SvgStyle style;
      style.stroke = robot_color(f.robot_id);
      style.fill = "none";
      doc.add_polygon(frame_marker(f.x_WF, 0.3), style);
    }
    doc.end_group();
    doc.begin_group("robot frames", "robots");
    for (const CorrectedFrame& r : map.corrected_frames()) {
      io::SvgStyle style;
      style.stroke = "black";
      style.fill = robot_color(r.robot_id);
      doc.add_polygon(frame_marker(r.x_WL, 0.5), style);
      io::SvgTextStyle text;
      text.size_px = 11.0;
      doc.add_text({r.x_WL.x, r.x_WL.y}, " R" + std::to_string(r.robot_id), text);
    }
    doc.end_group();
  }
  // The legend, right of the map: one row per layer drawn.
  std::vector<io::SvgLegendEntry> legend;
  io::SvgStyle wall;
  wall.stroke_width_px = 2.0;
  legend.push_back({io::SvgLegendEntry::Mark::kLine, wall, "wall segment"});
  if (options.sigma_bands) {
    io::SvgStyle band;
    band.stroke = "none";
    band.fill = "#1f77b4";
    band.fill_opacity = 0.2;
    char label[64];
    std::snprintf(label, sizeof label, "%g-sigma lateral band", options.band_sigmas);
    legend.push_back({io::SvgLegendEntry::Mark::kPatch, band, label});
  }
  for (std::size_t t = 0; t < trajectories.size(); ++t) {
    io::SvgStyle style;
    style.stroke = trajectories[t].color.empty() ? palette()[t % palette().size()] : trajectories[t].color;
    style.stroke_width_px = 1.2;
    legend.push_back({io::SvgLegendEntry::Mark::kLine, style,
                      trajectories[t].label.empty() ? "trajectory " + std::to_string(t) : trajectories[t].label});
  }
  if (options.graph && !submaps.empty()) {
    io::SvgStyle consecutive;
    consecutive.stroke = "#2ca02c";
    consecutive.stroke_opacity = 0.6;
    io::SvgStyle paired = consecutive;
    paired.stroke = "#d62728";
    paired.dash_px = "4 3";
    io::SvgStyle node;
    node.stroke = "none";
    node.fill = "#d62728";
    node.fill_opacity = 0.6;
    legend.push_back({io::SvgLegendEntry::Mark::kDot, node, "graph node (submap)"});
    legend.push_back({io::SvgLegendEntry::Mark::kLine, consecutive, "graph edge: consecutive"});
    legend.push_back({io::SvgLegendEntry::Mark::kLine, paired, "graph edge: paired"});
  }
  if (options.frames) {
    io::SvgStyle submap;
    submap.stroke = "#555";
    io::SvgStyle robot;
    robot.fill = "#555";
    legend.push_back({io::SvgLegendEntry::Mark::kPatch, submap, "submap frame"});
    legend.push_back({io::SvgLegendEntry::Mark::kPatch, robot, "robot frame (R<id>)"});
  }
  io::add_legend(doc, legend, io::legend_right_of_bounds(doc));
  doc.add_scale_bar();
  return doc;
}

void write_map_svg(const GlobalMap& map, const std::filesystem::path& file,
                   const std::vector<MapTrajectory>& trajectories, const MapSvgOptions& options) {
  map_to_svg(map, trajectories, options).write(file);
}

}  // namespace lmf::fusion
