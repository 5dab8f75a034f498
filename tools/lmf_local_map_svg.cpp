// lmf-local-map-svg: runs one robot's local map over the first scans of a CARMEN
// log and draws the map: segments with their 2-sigma lateral bands, the robot
// path with its final 2-sigma position ellipse, the last scan's points and,
// optionally, the reference path aligned at the first scan (L = its pose).
#include <algorithm>
#include <cmath>
#include <iostream>
#include <numbers>
#include <optional>
#include <sstream>
#include <string>
#include <vector>

#include <boost/program_options.hpp>
#include <Eigen/Eigenvalues>

#include "lmf/io/carmen.hpp"
#include "lmf/io/svg.hpp"
#include "lmf/local_map/local_map.hpp"
#include "lmf/local_map/local_map_config_json.hpp"
#include "tools/tool_support.hpp"

namespace po = boost::program_options;

namespace {

struct Options {
  std::string log_file;
  std::string config_file;
  std::string reference_file;
  std::string out_file;
  std::size_t first = 0;
  std::size_t scans = 0;  // 0: to the end of the log
  double pixels_per_metre = 30.0;
  bool no_constraints = false;
};

void draw_segments(const lmf::LocalMap& lm, lmf::io::SvgDocument& svg) {
  svg.begin_group("segments (2-sigma lateral bands)", "segments");
  for (const lmf::spmap::EntityId id : lm.segment_ids()) {
    const lmf::spmap::Entity& s = lm.map().entity(id);
    const Eigen::MatrixXd P = lm.map().block(id, id);
    const Eigen::Vector2d d(std::cos(s.location.phi), std::sin(s.location.phi));
    const Eigen::Vector2d n(-d.y(), d.x());  // the side the robot saw it from
    std::vector<double> along_m;
    for (int k = 0; k <= 8; ++k) along_m.push_back(s.length_m * (k / 8.0 - 0.5));
    lmf::tools::add_segment_band(svg, s.location, P.topLeftCorner<2, 2>(), along_m, 0.3);
    lmf::io::SvgStyle line;
    line.stroke = "#d62728";
    line.stroke_width_px = 2.0;
    svg.add_line(s.location.transform_point({-0.5 * s.length_m, 0.0}),
                 s.location.transform_point({0.5 * s.length_m, 0.0}), line);
    lmf::io::SvgStyle tick = line;
    tick.stroke = "#2ca02c";
    tick.stroke_width_px = 1.0;
    const Eigen::Vector2d mid(s.location.x, s.location.y);
    svg.add_line(mid, mid + 0.15 * n, tick);
  }
  svg.end_group();
}

void draw_path(const std::vector<Eigen::Vector2d>& path, const std::string& title, const std::string& color,
               const std::string& dash, lmf::io::SvgDocument& svg) {
  svg.begin_group(title);
  lmf::io::SvgStyle style;
  style.stroke = color;
  style.stroke_width_px = 1.5;
  style.dash_px = dash;
  svg.add_polyline(path, style);
  svg.end_group();
}

int run(const Options& o) {
  lmf::LocalMapConfig config = o.config_file.empty() ? lmf::LocalMapConfig{}
                                                     : lmf::load_local_map_config(o.config_file);
  if (o.no_constraints) config.constraints_enabled = false;
  const lmf::io::CarmenLog log = lmf::io::read_carmen_log(o.log_file);
  lmf::tools::check_scan_index("--first", o.first, log.scans.size(), o.log_file);
  const std::vector<lmf::StampedPose> reference =
      o.reference_file.empty() ? std::vector<lmf::StampedPose>{}
                               : lmf::tools::read_reference_per_scan(o.reference_file, log.scans.size());
  const std::size_t end = o.scans == 0 ? log.scans.size() : std::min(log.scans.size(), o.first + o.scans);

  lmf::LocalMap lm(config);
  int unhealthy = 0;
  for (std::size_t k = o.first; k < end; ++k) {
    const lmf::ScanReport r = lm.process_scan(log.scans[k]);
    if (!r.covariance_health.ok()) ++unhealthy;
  }
  lm.take_skipped_scan();  // the map ends at the last scan, drawn there

  lmf::io::SvgDocument svg(o.pixels_per_metre);
  std::ostringstream title;
  title << o.log_file << ": local map after scans " << o.first << ".." << end - 1 << " ("
        << lm.num_segments() << " segments, " << lm.span_m() << " m)";
  svg.set_title(title.str());

  // The last scan's points, placed at the final robot estimate.
  const lmf::LaserScan& last = log.scans[end - 1];
  svg.begin_group("last scan", "scan");
  lmf::io::SvgStyle dot;
  dot.stroke = "none";
  dot.fill = "#7f7f7f";
  const lmf::Pose2 x_LR = lm.x_LR();
  for (std::size_t i = 0; i < last.ranges_m.size(); ++i) {
    if (!lmf::tools::is_drawn_return(last, i)) continue;
    svg.add_dot(x_LR.transform_point(last.beam_point(i)), 1.0, dot);
  }
  svg.end_group();

  draw_segments(lm, svg);

  if (!reference.empty()) {
    std::vector<Eigen::Vector2d> path;
    for (std::size_t k = o.first; k < end; ++k) {
      const lmf::Pose2 x = lmf::between(reference[o.first].pose, reference[k].pose);
      path.emplace_back(x.x, x.y);
    }
    draw_path(path, "reference path (aligned at the first scan)", "#2ca02c", "5 3", svg);
  }
  std::vector<Eigen::Vector2d> path;
  for (const lmf::ScanPose& p : lm.snapshot().scan_poses) path.emplace_back(p.x_LR.x, p.x_LR.y);
  draw_path(path, "robot path (filtered)", "#1f77b4", "", svg);

  svg.begin_group("robot (2-sigma position ellipse)", "robot");
  const Eigen::Matrix2d P_xy = lm.robot_covariance().topLeftCorner<2, 2>();
  const Eigen::SelfAdjointEigenSolver<Eigen::Matrix2d> eig(P_xy);
  const Eigen::Vector2d axes = eig.eigenvalues().cwiseMax(0.0).cwiseSqrt() * 2.0;
  const Eigen::Vector2d major = eig.eigenvectors().col(1);
  lmf::io::SvgStyle ellipse;
  ellipse.stroke = "#1f77b4";
  ellipse.fill = "#1f77b4";
  ellipse.fill_opacity = 0.2;
  svg.add_ellipse({x_LR.x, x_LR.y}, std::max(axes(1), 1e-3), std::max(axes(0), 1e-3),
                  std::atan2(major.y(), major.x()), ellipse);
  lmf::tools::add_heading_line(svg, x_LR, 0.4);
  svg.end_group();
  svg.add_scale_bar();
  svg.write(o.out_file);

  std::cout << "scans " << o.first << ".." << end - 1 << ": " << lm.num_segments() << " segments, robot at ("
            << x_LR.x << ", " << x_LR.y << ", " << x_LR.phi << ") in L, span " << lm.span_m() << " m";
  if (!reference.empty()) {
    const lmf::Pose2 truth = lmf::between(reference[o.first].pose, reference[end - 1].pose);
    std::cout << ", error vs reference " << std::hypot(x_LR.x - truth.x, x_LR.y - truth.y) << " m / "
              << std::abs(lmf::wrap_angle(x_LR.phi - truth.phi)) * 180.0 / std::numbers::pi << " deg";
  }
  std::cout << ", scans with covariance warnings: " << unhealthy << " -> " << o.out_file << "\n";
  return 0;
}

}  // namespace

int main(int argc, char** argv) {
  Options o;
  po::options_description options(
      "lmf-local-map-svg: run one robot's local map (docs/design.md §4, shipping disabled) over scans of a CARMEN\n"
      "log and draw it in the local frame L (the robot's pose at the first scan): segments in red with\n"
      "their 2-sigma lateral bands (green tick: the side they were seen from), the filtered robot path\n"
      "in blue with the final 2-sigma position ellipse, the last scan's points in grey and, with --gt,\n"
      "the reference path aligned at the first scan (dashed green).\nOptions");
  options.add_options()("help,h", "print this help")(
      "log", po::value(&o.log_file)->required(), "CARMEN log (plain or .gz)")(
      "scans", po::value(&o.scans)->default_value(0), "number of scans to run (0: to the end of the log)")(
      "first", po::value(&o.first)->default_value(0), "index of the first scan (0-based)")(
      "config", po::value(&o.config_file), "JSON LocalMapConfig (see local_map_config_json.hpp); defaults otherwise")(
      "no-constraints", po::bool_switch(&o.no_constraints), "disable the perfect angular constraints (step 9)")(
      "gt", po::value(&o.reference_file), "reference trajectory, one `index t x y theta` line per scan (.gt)")(
      "out", po::value(&o.out_file)->required(), "output SVG file")(
      "scale", po::value(&o.pixels_per_metre)->default_value(30.0), "pixels per metre");
  const auto check = [&] {
    if (!(o.pixels_per_metre > 0.0)) throw po::error("--scale must be > 0");
  };
  if (const auto exit_code = lmf::tools::parse_command_line(argc, argv, options, "lmf-local-map-svg", check)) {
    return *exit_code;
  }
  return lmf::tools::run_reporting_errors("lmf-local-map-svg", [&] { return run(o); });
}
