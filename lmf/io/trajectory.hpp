// Trajectory files: one pose per line, `t x y theta` or `index t x y theta`
// (the datasets' .gt reference files), t in seconds, x y in metres, theta in
// radians; `#` comments and blank lines allowed; plain or gzip.
#pragma once

#include <cstdint>
#include <filesystem>
#include <stdexcept>
#include <string>
#include <vector>

#include "lmf/geometry/pose2.hpp"
#include "lmf/geometry/stamped_pose.hpp"

namespace lmf::io {

// A malformed trajectory line: what() is "file:line: what was wrong".
class TrajectoryParseError : public std::runtime_error {
 public:
  TrajectoryParseError(const std::filesystem::path& file, std::size_t line, const std::string& what);
  const std::filesystem::path& file() const { return file_; }
  std::size_t line() const { return line_; }

 private:
  std::filesystem::path file_;
  std::size_t line_;
};

// Reads a trajectory in file order. The column count (4 or 5) is taken from the
// first data line and must be the same on every line; an index column must hold
// non-negative integers. Angles are wrapped to (-pi, pi]. Throws
// TrajectoryParseError for a bad line (non-numeric, NaN/inf, wrong column count)
// and std::runtime_error when the file cannot be read.
std::vector<StampedPose> read_trajectory(const std::filesystem::path& file);

// Writes `t x y theta` lines: t in seconds with exactly 6 decimals (the
// microseconds), x y theta with 6 decimals; `header_comments` first as `# ...`.
// Gzip when the name ends in ".gz". Throws std::invalid_argument for a non-finite
// pose or a multi-line comment, std::runtime_error on I/O errors.
void write_trajectory(const std::filesystem::path& file, const std::vector<StampedPose>& poses,
                      const std::vector<std::string>& header_comments = {});

}  // namespace lmf::io
