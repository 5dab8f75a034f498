// Pieces shared by the command-line tools of tools/: the command-line and error
// conventions of the tools (usage errors exit 2, runtime errors exit 1, both
// prefixed with the tool's name), checks of their inputs (a scan index into a
// CARMEN log, a reference with one pose per scan) and the SVG marks that the
// drawing tools have in common.
#pragma once

#include <cstddef>
#include <functional>
#include <optional>
#include <string>
#include <vector>

#include <boost/program_options.hpp>
#include <Eigen/Core>

#include "lmf/geometry/pose2.hpp"
#include "lmf/geometry/stamped_pose.hpp"
#include "lmf/io/svg.hpp"
#include "lmf/scan/laser_scan.hpp"

namespace lmf::tools {

// --- Command line and errors ---

// Parses the command line into the variables bound by `options`, then runs
// `check` (if any), which throws boost::program_options::error for invalid
// values. Returns the exit code to stop with: 0 after printing the help for
// --help/-h, 2 after printing "<tool>: <error>\nTry <tool> --help" to stderr;
// nullopt when the tool should go on.
std::optional<int> parse_command_line(int argc, char** argv,
                                      const boost::program_options::options_description& options,
                                      const std::string& tool, const std::function<void()>& check = {});

// Runs `body` and returns its exit code; an exception escaping it is printed to
// stderr as "<tool>: <what>" and exits with 1.
int run_reporting_errors(const std::string& tool, const std::function<int()>& body);

// --- Inputs ---

// Throws std::out_of_range ("<flag> <index> is out of range: <log_file> has N
// scans") unless `index` is one of the `num_scans` scans of the log.
void check_scan_index(const std::string& flag, std::size_t index, std::size_t num_scans,
                      const std::string& log_file);

// Reads a reference trajectory (io::read_trajectory) that must hold one pose per
// scan of a log with `num_scans` scans; throws std::runtime_error when it does not.
std::vector<StampedPose> read_reference_per_scan(const std::string& file, std::size_t num_scans);

// --- SVG ---

// True when beam i of `scan` is a return worth drawing: finite, positive and
// short of the no-return range (max_range_m - 0.1 m, when the scan has one).
bool is_drawn_return(const LaserScan& scan, std::size_t i);

// Adds the red 2-sigma lateral band of a segment: the segment lies along the x
// axis of `location` (its midpoint), `P` is the covariance of its (lateral,
// angular) perturbation, and the band's edges are sampled at `along_m` (metres
// along the segment from the midpoint, in order).
void add_segment_band(io::SvgDocument& svg, const Pose2& location, const Eigen::Matrix2d& P,
                      const std::vector<double>& along_m, double fill_opacity);

// Adds the robot's heading: a black line from `pose` along its x axis.
void add_heading_line(io::SvgDocument& svg, const Pose2& pose, double length_m);

}  // namespace lmf::tools
