// lmf-scan-svg: draws one scan of a CARMEN log, the segments extracted from it
// and the robot, in the robot (= sensor) frame, as an SVG file.
#include <algorithm>
#include <cmath>
#include <iostream>
#include <sstream>
#include <string>
#include <vector>

#include <boost/program_options.hpp>

#include "lmf/io/carmen.hpp"
#include "lmf/io/svg.hpp"
#include "lmf/scan/extraction_config_json.hpp"
#include "lmf/scan/segment_extraction.hpp"
#include "tools/tool_support.hpp"

namespace po = boost::program_options;

namespace {

// The drawing, in the sensor frame (metres, x forward, y left).
lmf::io::SvgDocument draw(const lmf::LaserScan& scan, const std::vector<lmf::ExtractedSegment>& segments,
                          std::size_t index, double pixels_per_metre) {
  lmf::io::SvgDocument svg(pixels_per_metre);
  svg.set_title("scan " + std::to_string(index) + ": " + std::to_string(segments.size()) + " segments");

  std::vector<bool> used(scan.ranges_m.size(), false);
  for (const auto& e : segments) {
    for (std::size_t i = e.first_beam; i <= e.last_beam; ++i) used[i] = true;
  }
  svg.begin_group("points", "points");
  for (std::size_t i = 0; i < scan.ranges_m.size(); ++i) {
    if (!lmf::tools::is_drawn_return(scan, i)) continue;
    lmf::io::SvgStyle dot;
    dot.stroke = "none";
    dot.fill = used[i] ? "#1f77b4" : "#999999";
    svg.add_dot(scan.beam_point(i), used[i] ? 1.5 : 1.2, dot);
  }
  svg.end_group();

  svg.begin_group("segments", "segments");
  for (const auto& e : segments) {
    const lmf::ObservedSegment& s = e.segment;
    const Eigen::Vector2d d(std::cos(s.location.phi), std::sin(s.location.phi));
    const Eigen::Vector2d n(-d.y(), d.x());  // towards the sensor
    std::vector<double> along_m;
    for (int k = 0; k <= 8; ++k) along_m.push_back(-0.5 * s.length_m + s.length_m * k / 8.0);
    lmf::tools::add_segment_band(svg, s.location, s.covariance, along_m, 0.25);
    lmf::io::SvgStyle line;
    line.stroke = "#d62728";
    line.stroke_width_px = 2.5;
    svg.add_line(s.first_point, s.last_point, line);
    // Direction: an arrow head at the midpoint; side: a tick towards the sensor (left, +y).
    const Eigen::Vector2d mid(s.location.x, s.location.y);
    const double head = std::min(0.15, 0.25 * s.length_m);
    lmf::io::SvgStyle mark;
    mark.stroke = "#d62728";
    mark.stroke_width_px = 1.5;
    svg.add_line(mid, mid - head * d + 0.5 * head * n, mark);
    svg.add_line(mid, mid - head * d - 0.5 * head * n, mark);
    lmf::io::SvgStyle tick = mark;
    tick.stroke = "#2ca02c";
    svg.add_line(mid, mid + 0.2 * n, tick);
    lmf::io::SvgTextStyle label;
    label.size_px = 9.0;
    label.color = "#555555";
    std::ostringstream text;
    text.precision(2);
    text << std::fixed << s.length_m << " m, " << s.num_points << " pts";
    svg.add_text(mid - 0.25 * n, text.str(), label);
  }
  svg.end_group();

  svg.begin_group("robot", "robot");
  lmf::io::SvgStyle body;
  body.stroke = "black";
  body.fill = "#ffdd57";
  body.stroke_width_px = 1.5;
  svg.add_circle(Eigen::Vector2d::Zero(), 0.22, body);
  lmf::tools::add_heading_line(svg, lmf::Pose2{}, 0.35);
  svg.end_group();
  svg.add_scale_bar();
  return svg;
}

struct Options {
  std::string log_file;
  std::string config_file;
  std::string out_file;
  std::size_t index = 0;
  double pixels_per_metre = 40.0;
};

int run(const Options& o) {
  const lmf::ExtractionConfig config =
      o.config_file.empty() ? lmf::ExtractionConfig{} : lmf::load_extraction_config(o.config_file);
  const lmf::io::CarmenLog log = lmf::io::read_carmen_log(o.log_file);
  lmf::tools::check_scan_index("--index", o.index, log.scans.size(), o.log_file);
  const lmf::LaserScan& scan = log.scans[o.index];
  const auto segments = lmf::extract_segments_with_support(scan, config);
  draw(scan, segments, o.index, o.pixels_per_metre).write(o.out_file);
  std::cout << "scan " << o.index << ": " << segments.size() << " segments -> " << o.out_file << "\n";
  return 0;
}

}  // namespace

int main(int argc, char** argv) {
  Options o;
  po::options_description options(
      "lmf-scan-svg: draw scan K of a CARMEN log with its extracted segments (red, with a 2-sigma lateral\n"
      "band, an arrow head giving the direction and a green tick on the sensor side) and the robot\n"
      "(yellow, heading +x), in the robot frame.\nOptions");
  options.add_options()("help,h", "print this help")(
      "log", po::value(&o.log_file)->required(), "CARMEN log (plain or .gz)")(
      "index", po::value(&o.index)->required(), "scan index K (0-based, FLASER/ROBOTLASER1 lines in file order)")(
      "config", po::value(&o.config_file),
      "JSON object with ExtractionConfig fields (e.g. {\"split_distance_m\": 0.08}); defaults otherwise")(
      "out", po::value(&o.out_file)->required(), "output SVG file")(
      "scale", po::value(&o.pixels_per_metre)->default_value(40.0), "pixels per metre");
  if (const auto exit_code = lmf::tools::parse_command_line(argc, argv, options, "lmf-scan-svg")) return *exit_code;
  return lmf::tools::run_reporting_errors("lmf-scan-svg", [&] { return run(o); });
}
