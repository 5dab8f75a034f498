// lmf-scan-svg: draws one scan of a CARMEN log, the segments extracted from it
// and the robot, in the robot (= sensor) frame, as an SVG file.
#include <cmath>
#include <cstdio>
#include <exception>
#include <iostream>
#include <sstream>
#include <string>
#include <vector>

#include <boost/program_options.hpp>

#include "lmf/io/carmen.hpp"
#include "lmf/io/svg.hpp"
#include "lmf/scan/extraction_config_json.hpp"
#include "lmf/scan/segment_extraction.hpp"

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
  const double no_return_m = scan.max_range_m > 0.0 ? scan.max_range_m - 0.1 : 1e9;
  for (std::size_t i = 0; i < scan.ranges_m.size(); ++i) {
    const double r = scan.ranges_m[i];
    if (!std::isfinite(r) || r <= 0.0 || r >= no_return_m) continue;
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
    // 2-sigma lateral band: Var(lateral at x) = P00 + 2 x P01 + x² P11.
    std::vector<Eigen::Vector2d> left;
    std::vector<Eigen::Vector2d> right;
    for (int k = 0; k <= 8; ++k) {
      const double x = -0.5 * s.length_m + s.length_m * k / 8.0;
      const double var = s.covariance(0, 0) + 2.0 * x * s.covariance(0, 1) + x * x * s.covariance(1, 1);
      const double w = 2.0 * std::sqrt(std::max(var, 0.0));
      const Eigen::Vector2d p = s.location.transform_point({x, 0.0});
      left.push_back(p + w * n);
      right.push_back(p - w * n);
    }
    lmf::io::SvgStyle band;
    band.stroke = "none";
    band.fill = "#d62728";
    band.fill_opacity = 0.25;
    svg.add_band(left, right, band);
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
  lmf::io::SvgStyle heading;
  heading.stroke = "black";
  heading.stroke_width_px = 2.0;
  svg.add_line(Eigen::Vector2d::Zero(), Eigen::Vector2d(0.35, 0.0), heading);
  svg.end_group();
  svg.add_scale_bar();
  return svg;
}

}  // namespace

int main(int argc, char** argv) {
  std::string log_file;
  std::string config_file;
  std::string out_file;
  std::size_t index = 0;
  double pixels_per_metre = 40.0;
  po::options_description options(
      "lmf-scan-svg: draw scan K of a CARMEN log with its extracted segments (red, with a 2-sigma lateral\n"
      "band, an arrow head giving the direction and a green tick on the sensor side) and the robot\n"
      "(yellow, heading +x), in the robot frame.\nOptions");
  options.add_options()("help,h", "print this help")(
      "log", po::value(&log_file)->required(), "CARMEN log (plain or .gz)")(
      "index", po::value(&index)->required(), "scan index K (0-based, FLASER/ROBOTLASER1 lines in file order)")(
      "config", po::value(&config_file),
      "JSON object with ExtractionConfig fields (e.g. {\"split_distance_m\": 0.08}); defaults otherwise")(
      "out", po::value(&out_file)->required(), "output SVG file")(
      "scale", po::value(&pixels_per_metre)->default_value(40.0), "pixels per metre");
  try {
    po::variables_map vm;
    po::store(po::parse_command_line(argc, argv, options), vm);
    if (vm.count("help") != 0u) {
      std::cout << options << "\n";
      return 0;
    }
    po::notify(vm);
  } catch (const po::error& e) {
    std::cerr << "lmf-scan-svg: " << e.what() << "\nTry lmf-scan-svg --help\n";
    return 2;
  }
  try {
    const lmf::ExtractionConfig config = config_file.empty() ? lmf::ExtractionConfig{} : lmf::load_extraction_config(config_file);
    const lmf::io::CarmenLog log = lmf::io::read_carmen_log(log_file);
    if (index >= log.scans.size()) {
      std::cerr << "lmf-scan-svg: --index " << index << " is out of range: " << log_file << " has "
                << log.scans.size() << " scans\n";
      return 1;
    }
    const lmf::LaserScan& scan = log.scans[index];
    const auto segments = lmf::extract_segments_with_support(scan, config);
    draw(scan, segments, index, pixels_per_metre).write(out_file);
    std::cout << "scan " << index << ": " << segments.size() << " segments -> " << out_file << "\n";
  } catch (const std::exception& e) {
    std::cerr << "lmf-scan-svg: " << e.what() << "\n";
    return 1;
  }
  return 0;
}
