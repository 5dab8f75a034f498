#include "lmf/io/carmen.hpp"

#include <charconv>
#include <cmath>
#include <cstdio>
#include <numbers>
#include <optional>
#include <string_view>
#include <system_error>

#include "lmf/io/text_file.hpp"

namespace lmf::io {
namespace {

constexpr std::size_t kMaxBeams = 4096;

std::string error_text(const std::filesystem::path& file, std::size_t line, const std::string& what) {
  return file.string() + ":" + std::to_string(line) + ": " + what;
}

// Parses the fields of one line, naming the line in every error.
class LineParser {
 public:
  LineParser(const std::filesystem::path& file, std::size_t line, std::string_view type)
      : file_(file), line_(line), type_(type) {}

  [[noreturn]] void fail(const std::string& what) const {
    throw CarmenParseError(file_, line_, std::string(type_) + ": " + what);
  }

  // Any double, NaN and infinities included (callers decide what is allowed).
  double raw_number(std::string_view field, const std::string& name) const {
    const std::optional<double> v = parse_double(field);
    if (!v) fail(name + " is not a number: '" + std::string(field) + "'");
    return *v;
  }

  double finite(std::string_view field, const std::string& name) const {
    const double v = raw_number(field, name);
    if (std::isnan(v)) fail(name + " is NaN");
    if (std::isinf(v)) fail(name + " is infinite");
    return v;
  }

  // A range reading. NaN and ±infinity are what lasers and their drivers
  // write for a beam with no return: read as `no_return` (the scan's maximum
  // range, which means "no return") and counted, never an error.
  double range(std::string_view field, std::size_t index, double no_return, std::size_t& no_returns) const {
    const double v = raw_number(field, "range " + std::to_string(index));
    if (!std::isfinite(v)) {
      ++no_returns;
      return no_return;
    }
    if (v < 0.0) fail("negative range " + std::string(field) + " (range " + std::to_string(index) + ")");
    return v;
  }

  std::size_t count(std::string_view field, const std::string& name, std::size_t min, std::size_t max) const {
    long long v = 0;
    const auto [ptr, ec] = std::from_chars(field.data(), field.data() + field.size(), v);
    if (ec != std::errc() || ptr != field.data() + field.size()) {
      fail(name + " is not an integer: '" + std::string(field) + "'");
    }
    if (v < static_cast<long long>(min) || v > static_cast<long long>(max)) {
      fail(name + " " + std::to_string(v) + " outside " + std::to_string(min) + ".." + std::to_string(max));
    }
    return static_cast<std::size_t>(v);
  }

  Pose2 pose(const std::vector<std::string_view>& f, std::size_t first, const std::string& name) const {
    const double x = finite(f[first], name + " x");
    const double y = finite(f[first + 1], name + " y");
    const double theta = finite(f[first + 2], name + " theta");
    return {x, y, wrap_angle(theta)};
  }

  // Seconds -> microseconds, rounded.
  int64_t utime(std::string_view field) const {
    const double t = finite(field, "timestamp");
    if (std::abs(t) > 9.0e12) fail("timestamp " + std::string(field) + " s does not fit in microseconds");
    return static_cast<int64_t>(std::llround(t * 1e6));
  }

 private:
  const std::filesystem::path& file_;
  std::size_t line_;
  std::string_view type_;
};

// FLASER n r1..rn x y theta odom_x odom_y odom_theta ts host lts
LaserScan parse_flaser(const std::vector<std::string_view>& f, const LineParser& p,
                       const CarmenReadOptions& options, Pose2& laser_pose, std::size_t& no_returns) {
  if (f.size() < 2) p.fail("missing the beam count");
  // A 180° scan needs two beams to define its step (beam_increment_for_180deg).
  const std::size_t n = p.count(f[1], "beam count", 2, kMaxBeams);
  const std::size_t trailing = 9;  // 2 poses, ts, host, lts
  if (f.size() != 2 + n + trailing) {
    if (f.size() < 2 + trailing) p.fail("expected " + std::to_string(n) + " ranges, line has only " +
                                        std::to_string(f.size()) + " fields");
    p.fail("expected " + std::to_string(n) + " ranges, found " + std::to_string(f.size() - 2 - trailing));
  }
  LaserScan scan;
  scan.ranges_m.reserve(n);
  for (std::size_t i = 0; i < n; ++i) {
    scan.ranges_m.push_back(p.range(f[2 + i], i, options.flaser_max_range_m, no_returns));
  }
  const std::size_t k = 2 + n;
  laser_pose = p.pose(f, k, "laser pose");
  scan.odometry = p.pose(f, k + 3, "odometry pose");
  scan.utime = p.utime(f[k + 6]);
  p.finite(f[k + 8], "logger timestamp");
  scan.angle_min_rad = -std::numbers::pi / 2.0;
  scan.angle_increment_rad = beam_increment_for_180deg(n);
  scan.max_range_m = options.flaser_max_range_m;
  return scan;
}

// ROBOTLASER1 type start_angle fov resolution max_range accuracy remission_mode
//             n r1..rn m rem1..remm laser_x laser_y laser_theta robot_x robot_y
//             robot_theta tv rv forward_safety side_safety turn_axis ts host lts
LaserScan parse_robotlaser1(const std::vector<std::string_view>& f, const LineParser& p, Pose2& laser_pose,
                            std::size_t& no_returns) {
  if (f.size() < 10) p.fail("line too short (" + std::to_string(f.size()) + " fields)");
  p.finite(f[1], "laser type");
  const double start_angle = p.finite(f[2], "start angle");
  p.finite(f[3], "field of view");
  const double resolution = p.finite(f[4], "angular resolution");
  const double max_range = p.finite(f[5], "max range");
  p.finite(f[6], "accuracy");
  p.finite(f[7], "remission mode");
  if (!(resolution > 0.0)) p.fail("angular resolution must be positive, got " + std::string(f[4]));
  if (!(max_range > 0.0)) p.fail("max range must be positive, got " + std::string(f[5]));
  const std::size_t n = p.count(f[8], "beam count", 1, kMaxBeams);
  if (f.size() < 10 + n) p.fail("expected " + std::to_string(n) + " ranges, line too short");
  const std::size_t m = p.count(f[9 + n], "remission count", 0, kMaxBeams);
  const std::size_t trailing = 14;  // 2 poses, tv rv fs ss ta, ts host lts
  if (f.size() != 10 + n + m + trailing) {
    p.fail("expected " + std::to_string(n + m + 24) + " fields for " + std::to_string(n) + " ranges and " +
           std::to_string(m) + " remissions, found " + std::to_string(f.size()));
  }
  LaserScan scan;
  scan.ranges_m.reserve(n);
  for (std::size_t i = 0; i < n; ++i) scan.ranges_m.push_back(p.range(f[9 + i], i, max_range, no_returns));
  for (std::size_t i = 0; i < m; ++i) p.finite(f[10 + n + i], "remission " + std::to_string(i));
  const std::size_t k = 10 + n + m;
  laser_pose = p.pose(f, k, "laser pose");
  scan.odometry = p.pose(f, k + 3, "robot pose");
  for (std::size_t i = 6; i < 11; ++i) p.finite(f[k + i], "velocity/safety field");
  scan.utime = p.utime(f[k + 11]);
  p.finite(f[k + 13], "logger timestamp");
  scan.angle_min_rad = start_angle;
  scan.angle_increment_rad = resolution;
  scan.max_range_m = max_range;
  return scan;
}

// ODOM x y theta tv rv accel ts host lts
OdometryRecord parse_odom(const std::vector<std::string_view>& f, const LineParser& p) {
  if (f.size() != 10) p.fail("expected 9 fields, found " + std::to_string(f.size() - 1));
  OdometryRecord r;
  r.pose = p.pose(f, 1, "pose");
  p.finite(f[4], "tv");
  p.finite(f[5], "rv");
  p.finite(f[6], "accel");
  r.utime = p.utime(f[7]);
  p.finite(f[9], "logger timestamp");
  return r;
}

}  // namespace

CarmenParseError::CarmenParseError(const std::filesystem::path& file, std::size_t line, const std::string& what)
    : std::runtime_error(error_text(file, line, what)), file_(file), line_(line) {}

void parse_carmen_line(const std::string& text, const std::filesystem::path& file, std::size_t line_number,
                       const CarmenReadOptions& options, CarmenLog& log) {
  const std::vector<std::string_view> f = split_fields(text);
  if (f.empty() || f[0].front() == '#') return;
  const std::string_view type = f[0];
  const LineParser p(file, line_number, type);
  Pose2 laser_pose;
  if (type == "FLASER") {
    log.scans.push_back(parse_flaser(f, p, options, laser_pose, log.no_return_readings));
    log.laser_poses.push_back(laser_pose);
  } else if (type == "ROBOTLASER1") {
    log.scans.push_back(parse_robotlaser1(f, p, laser_pose, log.no_return_readings));
    log.laser_poses.push_back(laser_pose);
  } else if (type == "ODOM") {
    log.odometry.push_back(parse_odom(f, p));
  } else if (type == "PARAM") {
    // The public logs write `PARAM name value host ts`, CARMEN's docs `PARAM name
    // value ts host lts`: only name and value are used.
    if (f.size() < 3) p.fail("expected a name and a value");
    log.params[std::string(f[1])] = std::string(f[2]);
  } else {
    ++log.skipped[std::string(type)];
  }
}

void apply_laser_mounting(CarmenLog& log) {
  std::vector<Pose2> robot_poses;
  robot_poses.reserve(log.scans.size());
  for (const LaserScan& scan : log.scans) robot_poses.push_back(scan.odometry);
  log.laser_mounting = estimate_laser_mounting(robot_poses, log.laser_poses);
  if (!log.laser_mounting.x_RS) return;
  for (LaserScan& scan : log.scans) scan.odometry = compose(scan.odometry, *log.laser_mounting.x_RS);
}

void apply_flaser_no_return(CarmenLog& log, const CarmenReadOptions& options) {
  // FLASER scans are those read with the options' range (a ROBOTLASER1 line
  // states its own).
  const auto from_flaser = [&](const LaserScan& scan) { return scan.max_range_m == options.flaser_max_range_m; };
  log.flaser_no_return = find_no_return_reading(log.scans, from_flaser);
  const std::optional<double> ceiling = log.flaser_no_return.range_m;
  if (!ceiling || *ceiling >= options.flaser_max_range_m) return;
  for (LaserScan& scan : log.scans) {
    if (from_flaser(scan)) scan.max_range_m = *ceiling;
  }
}

CarmenLog read_carmen_log(const std::filesystem::path& file, const CarmenReadOptions& options) {
  if (!(options.flaser_max_range_m > 0.0)) {
    throw std::invalid_argument("read_carmen_log: flaser_max_range_m must be positive");
  }
  CarmenLog log;
  // A last line without its newline that does not parse was cut while the
  // logger wrote it (the logger was killed): the log is read up to it and the
  // cut is reported. Any other bad line is an error.
  for_each_line(file, [&](const std::string& text, std::size_t line_number, bool terminated) {
    if (terminated) {
      parse_carmen_line(text, file, line_number, options, log);
      return;
    }
    const std::size_t no_returns_before = log.no_return_readings;
    try {
      parse_carmen_line(text, file, line_number, options, log);
    } catch (const CarmenParseError& e) {
      log.no_return_readings = no_returns_before;  // the cut line adds nothing
      log.cut_short = std::string(e.what()) + " (the last line, without its newline: the log was cut there; read up to it)";
    }
  });
  apply_flaser_no_return(log, options);
  if (options.use_laser_mounting) apply_laser_mounting(log);
  return log;
}

std::string carmen_flaser_line(const LaserScan& scan, const std::string& host) {
  const std::size_t n = scan.ranges_m.size();
  if (n < 2 || n > kMaxBeams) {
    throw std::invalid_argument("carmen_flaser_line: FLASER needs 2.." + std::to_string(kMaxBeams) +
                                " beams, scan has " + std::to_string(n));
  }
  if (std::abs(scan.angle_min_rad + std::numbers::pi / 2.0) > 1e-9 ||
      std::abs(scan.angle_increment_rad - beam_increment_for_180deg(n)) > 1e-12) {
    throw std::invalid_argument("carmen_flaser_line: FLASER scans span 180 degrees from -90 degrees; scan has "
                                "angle_min " + std::to_string(scan.angle_min_rad) + " rad, increment " +
                                std::to_string(scan.angle_increment_rad) + " rad");
  }
  if (host.empty() || host.find_first_of(" \t\r\n") != std::string::npos) {
    throw std::invalid_argument("carmen_flaser_line: host must be one non-empty word, got '" + host + "'");
  }
  const Pose2& o = scan.odometry;
  if (!std::isfinite(o.x) || !std::isfinite(o.y) || !std::isfinite(o.phi)) {
    throw std::invalid_argument("carmen_flaser_line: non-finite odometry pose");
  }
  std::string out = "FLASER " + std::to_string(n);
  out.reserve(out.size() + n * 8 + 128);
  // %.3f / %.6f of a double take up to 317 characters (1e308 has 309 digits):
  // room for three, so a huge value is written whole, never cut short.
  char buf[1024];
  for (std::size_t i = 0; i < n; ++i) {
    const double r = scan.ranges_m[i];
    if (!std::isfinite(r) || r < 0.0) {
      throw std::invalid_argument("carmen_flaser_line: range " + std::to_string(i) + " is " + std::to_string(r));
    }
    std::snprintf(buf, sizeof buf, " %.3f", r);  // millimetres: the sensors' resolution
    out += buf;
  }
  std::snprintf(buf, sizeof buf, " %.6f %.6f %.6f", o.x, o.y, o.phi);
  out += buf;
  out += buf;  // the laser pose and the odometry pose are the same
  const std::string ts = seconds_text(scan.utime);
  out += ' ' + ts + ' ' + host + ' ' + ts;
  return out;
}

void write_carmen_log(const std::filesystem::path& file, const std::vector<LaserScan>& scans,
                      const CarmenWriteOptions& options) {
  // Format everything first so a bad scan leaves no half-written file.
  std::string text;
  for (const std::string& comment : options.header_comments) {
    if (comment.find_first_of("\r\n") != std::string::npos) {
      throw std::invalid_argument("write_carmen_log: a header comment spans several lines");
    }
    text += "# " + comment + "\n";
  }
  for (std::size_t i = 0; i < scans.size(); ++i) {
    try {
      text += carmen_flaser_line(scans[i], options.host);
    } catch (const std::invalid_argument& e) {
      throw std::invalid_argument("write_carmen_log: scan " + std::to_string(i) + ": " + e.what());
    }
    text += '\n';
  }
  write_text_file(file, text, options.gzip);
}

}  // namespace lmf::io
