#include "tools/tool_support.hpp"

#include <algorithm>
#include <cmath>
#include <exception>
#include <iostream>
#include <stdexcept>

#include "lmf/io/trajectory.hpp"

namespace po = boost::program_options;

namespace lmf::tools {

std::optional<int> parse_command_line(int argc, char** argv, const po::options_description& options,
                                      const std::string& tool, const std::function<void()>& check) {
  try {
    po::variables_map vm;
    po::store(po::parse_command_line(argc, argv, options), vm);
    if (vm.count("help") != 0u) {
      std::cout << options << "\n";
      return 0;
    }
    po::notify(vm);
    if (check) check();
  } catch (const po::error& e) {
    std::cerr << tool << ": " << e.what() << "\nTry " << tool << " --help\n";
    return 2;
  }
  return std::nullopt;
}

int run_reporting_errors(const std::string& tool, const std::function<int()>& body) {
  try {
    return body();
  } catch (const std::exception& e) {
    std::cerr << tool << ": " << e.what() << "\n";
    return 1;
  }
}

void check_scan_index(const std::string& flag, std::size_t index, std::size_t num_scans,
                      const std::string& log_file) {
  if (index < num_scans) return;
  throw std::out_of_range(flag + " " + std::to_string(index) + " is out of range: " + log_file + " has " +
                          std::to_string(num_scans) + " scans");
}

std::vector<StampedPose> read_reference_per_scan(const std::string& file, std::size_t num_scans) {
  std::vector<StampedPose> reference = io::read_trajectory(file);
  if (reference.size() != num_scans) {
    throw std::runtime_error(file + " has " + std::to_string(reference.size()) + " poses, the log has " +
                             std::to_string(num_scans) + " scans (one per scan expected)");
  }
  return reference;
}

bool is_drawn_return(const LaserScan& scan, std::size_t i) {
  const double no_return_m = scan.max_range_m > 0.0 ? scan.max_range_m - 0.1 : 1e9;
  const double r = scan.ranges_m[i];
  return std::isfinite(r) && r > 0.0 && r < no_return_m;
}

void add_segment_band(io::SvgDocument& svg, const Pose2& location, const Eigen::Matrix2d& P,
                      const std::vector<double>& along_m, double fill_opacity) {
  const Eigen::Vector2d d(std::cos(location.phi), std::sin(location.phi));
  const Eigen::Vector2d n(-d.y(), d.x());  // the segment's left: the side it is seen from
  std::vector<Eigen::Vector2d> left;
  std::vector<Eigen::Vector2d> right;
  for (const double x : along_m) {
    // Lateral error of the point at x along the segment: p_y + x p_phi.
    const double var = P(0, 0) + 2.0 * x * P(0, 1) + x * x * P(1, 1);
    const double w = 2.0 * std::sqrt(std::max(var, 0.0));
    const Eigen::Vector2d p = location.transform_point({x, 0.0});
    left.push_back(p + w * n);
    right.push_back(p - w * n);
  }
  io::SvgStyle band;
  band.stroke = "none";
  band.fill = "#d62728";
  band.fill_opacity = fill_opacity;
  svg.add_band(left, right, band);
}

void add_heading_line(io::SvgDocument& svg, const Pose2& pose, double length_m) {
  io::SvgStyle heading;
  heading.stroke = "black";
  heading.stroke_width_px = 2.0;
  svg.add_line({pose.x, pose.y}, pose.transform_point({length_m, 0.0}), heading);
}

}  // namespace lmf::tools
