// What the CARMEN targets check on every parsed log (lmf/io/carmen.hpp):
// errors name the file and the line; accepted scans are usable (finite,
// non-negative ranges, a positive beam step and max range, a finite pose with
// the angle wrapped); FLASER-shaped scans write back to a line that parses to
// the same scan (ranges in mm, poses in µm/µrad).
#pragma once

#include <cmath>
#include <cstddef>
#include <filesystem>
#include <numbers>
#include <string>

#include "fuzz_support.hpp"
#include "lmf/io/carmen.hpp"

namespace lmf::fuzz {

inline void check_parse_error(const io::CarmenParseError& e, const std::filesystem::path& file, std::size_t line) {
  const std::string prefix = file.string() + ":" + std::to_string(line) + ": ";
  if (e.file() != file || e.line() != line || std::string(e.what()).rfind(prefix, 0) != 0) {
    fail("CARMEN error does not name " + prefix + " : '" + e.what() + "'");
  }
}

inline bool near(double a, double b, double tolerance) { return std::abs(a - b) <= tolerance * (1.0 + std::abs(a)); }

inline void check_scan(const LaserScan& scan, const std::string& where) {
  const std::size_t n = scan.ranges_m.size();
  if (n < 1 || n > 4096) fail(where + ": " + std::to_string(n) + " beams accepted");
  for (const double r : scan.ranges_m) {
    if (!std::isfinite(r) || r < 0.0) fail(where + ": range " + std::to_string(r) + " accepted");
  }
  if (!std::isfinite(scan.angle_min_rad) || !(scan.angle_increment_rad > 0.0) ||
      !std::isfinite(scan.angle_increment_rad) || !(scan.max_range_m > 0.0) || !std::isfinite(scan.max_range_m)) {
    fail(where + ": bad beam geometry accepted");
  }
  const Pose2& o = scan.odometry;
  if (!std::isfinite(o.x) || !std::isfinite(o.y) || !(std::abs(o.phi) <= std::numbers::pi)) {
    fail(where + ": odometry pose not finite or not wrapped");
  }
  const bool flaser_shaped = n >= 2 && scan.angle_min_rad == -std::numbers::pi / 2.0 &&
                             scan.angle_increment_rad == beam_increment_for_180deg(n);
  if (!flaser_shaped) return;
  const std::string line = io::carmen_flaser_line(scan, "fuzz");
  io::CarmenLog back;
  try {
    io::parse_carmen_line(line, "written", 1, {}, back);
  } catch (const io::CarmenParseError& e) {
    fail(where + ": the written FLASER line does not parse: " + e.what());
  }
  if (back.scans.size() != 1 || back.scans[0].ranges_m.size() != n) fail(where + ": the written FLASER line changed shape");
  const LaserScan& b = back.scans[0];
  for (std::size_t i = 0; i < n; ++i) {
    if (!near(scan.ranges_m[i], b.ranges_m[i], 1e-3)) {
      fail(where + ": range " + std::to_string(i) + " written as " + std::to_string(b.ranges_m[i]) + " (was " +
           std::to_string(scan.ranges_m[i]) + ")");
    }
  }
  if (!near(o.x, b.odometry.x, 1e-5) || !near(o.y, b.odometry.y, 1e-5) ||
      std::abs(wrap_angle(o.phi - b.odometry.phi)) > 1e-5) {
    fail(where + ": the odometry pose did not survive writing");
  }
}

inline void check_log(const io::CarmenLog& log, const std::string& where) {
  for (std::size_t i = 0; i < log.scans.size(); ++i) check_scan(log.scans[i], where + " scan " + std::to_string(i));
  for (const io::OdometryRecord& r : log.odometry) {
    if (!std::isfinite(r.pose.x) || !std::isfinite(r.pose.y) || !(std::abs(r.pose.phi) <= std::numbers::pi)) {
      fail(where + ": ODOM pose not finite or not wrapped");
    }
  }
}

}  // namespace lmf::fuzz
