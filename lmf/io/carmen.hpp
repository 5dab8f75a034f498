// CARMEN log files (plain or gzip): reading FLASER, ROBOTLASER1, ODOM and PARAM
// lines, and writing FLASER logs (the simulator's output).
//
// Line formats (whitespace separated; trailing `timestamp host logger_timestamp`):
//   FLASER n r1..rn x y theta odom_x odom_y odom_theta ts host lts
//   ROBOTLASER1 type start_angle fov resolution max_range accuracy remission_mode
//               n r1..rn m rem1..remm laser_x laser_y laser_theta robot_x robot_y
//               robot_theta tv rv forward_safety side_safety turn_axis ts host lts
//   ODOM x y theta tv rv accel ts host lts
//   PARAM name value ts host lts
// FLASER beams span 180° from -90°, step from beam_increment_for_180deg().
// Scans carry the `odom_*` (FLASER) / `robot_*` (ROBOTLASER1) pose as LaserScan::odometry,
// composed with the laser's mounting where the log's laser poses show a rigid
// one (laser_mounting.hpp; lmf's robot frame is the laser's).
#pragma once

#include <cstdint>
#include <filesystem>
#include <map>
#include <optional>
#include <stdexcept>
#include <string>
#include <vector>

#include "lmf/geometry/pose2.hpp"
#include "lmf/io/laser_mounting.hpp"
#include "lmf/io/no_return_reading.hpp"
#include "lmf/scan/laser_scan.hpp"

namespace lmf::io {

// A malformed line: what() names the file, the line number and what was wrong.
class CarmenParseError : public std::runtime_error {
 public:
  CarmenParseError(const std::filesystem::path& file, std::size_t line, const std::string& what);
  const std::filesystem::path& file() const { return file_; }
  std::size_t line() const { return line_; }

 private:
  std::filesystem::path file_;
  std::size_t line_;
};

struct OdometryRecord {
  int64_t utime = 0;
  Pose2 pose;  // x_OR
};

struct CarmenLog {
  std::vector<LaserScan> scans;                  // FLASER and ROBOTLASER1, in file order
  std::vector<Pose2> laser_poses;                // each scan's laser pose field, as written
  LaserMounting laser_mounting;                  // found by read_carmen_log (apply_laser_mounting)
  // The FLASER scans' no-return reading, found from their readings by
  // read_carmen_log (no_return_reading.hpp); where it lies below
  // flaser_max_range_m it is their max_range_m.
  NoReturnReading flaser_no_return;
  std::size_t no_return_readings = 0;            // NaN or infinite ranges, read as "no return"
  std::optional<std::string> cut_short;          // the last line was cut mid-line: why it did not parse
  std::vector<OdometryRecord> odometry;          // ODOM lines
  std::map<std::string, std::string> params;     // PARAM name -> value (last wins)
  std::map<std::string, std::size_t> skipped;    // other line types -> count (comments excluded)
};

struct CarmenReadOptions {
  // Readings at or above max_range_m - margin are "no return"; FLASER has no max
  // range field, so it comes from here (80 m covers the datasets' sensors), or
  // from the log's own no-return reading where it shows one below this
  // (CarmenLog::flaser_no_return).
  double flaser_max_range_m = 81.0;
  // Compose each scan's robot pose with the laser's mounting (apply_laser_mounting).
  bool use_laser_mounting = true;
};

// Reads a whole log (plain or gzip; any line length). `#` comments and blank
// lines are ignored; FLASER needs 2..4096 beams, and their no-return reading
// is found from the log (apply_flaser_no_return). A NaN or infinite range is a
// beam with no return (no_return_readings), not an error. A last line without
// its newline that does not parse was cut by a killed logger: the log is read
// up to it (cut_short says why). Throws CarmenParseError on any other
// malformed line (negative or missing ranges, wrong counts, unparsable or
// non-finite numbers elsewhere) and std::runtime_error when the file cannot be
// opened or decompressed.
CarmenLog read_carmen_log(const std::filesystem::path& file, const CarmenReadOptions& options = {});

// Estimates the laser's mounting from the scans' robot and laser poses
// (estimate_laser_mounting) into log.laser_mounting and, where it is rigid,
// moves every scan's odometry pose to the laser's: x_OR ⊕ x_RS.
void apply_laser_mounting(CarmenLog& log);

// Finds the FLASER scans' no-return reading (find_no_return_reading) into
// log.flaser_no_return and, where it lies below options.flaser_max_range_m,
// makes it their max_range_m.
void apply_flaser_no_return(CarmenLog& log, const CarmenReadOptions& options);

// Parses one line (no trailing newline) into `log`; `file`/`line_number` only feed error messages.
void parse_carmen_line(const std::string& text, const std::filesystem::path& file, std::size_t line_number,
                       const CarmenReadOptions& options, CarmenLog& log);

struct CarmenWriteOptions {
  std::string host = "lmf-sim";
  std::vector<std::string> header_comments;  // written as `# ...` lines first
  bool gzip = false;                         // also implied by a `.gz` file name
};

// One FLASER line (no newline) for a scan: ranges with 3 decimals (mm), the
// odometry pose with 6 decimals as both the laser and the odometry pose, and the
// time stamp in seconds with 6 decimals (exact microseconds) as both time stamps.
// Throws std::invalid_argument for a scan FLASER cannot express (not 180° from
// -90°, beam count outside 2..4096, negative or non-finite ranges/pose) or a host
// that is not one word.
std::string carmen_flaser_line(const LaserScan& scan, const std::string& host);

// Writes scans as FLASER lines (pose fields: the scan's odometry pose for both
// the laser and the odometry pose). Scans must have 180° geometry as above.
// Throws std::invalid_argument for scans it cannot express, std::runtime_error on I/O errors.
void write_carmen_log(const std::filesystem::path& file, const std::vector<LaserScan>& scans,
                      const CarmenWriteOptions& options = {});

}  // namespace lmf::io
