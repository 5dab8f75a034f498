#include "lmf/io/trajectory.hpp"

#include <charconv>
#include <cmath>
#include <cstdio>
#include <optional>
#include <string_view>
#include <system_error>

#include "lmf/io/text_file.hpp"

namespace lmf::io {

TrajectoryParseError::TrajectoryParseError(const std::filesystem::path& file, std::size_t line,
                                           const std::string& what)
    : std::runtime_error(file.string() + ":" + std::to_string(line) + ": " + what), file_(file), line_(line) {}

std::vector<StampedPose> read_trajectory(const std::filesystem::path& file) {
  std::vector<StampedPose> poses;
  std::size_t columns = 0;  // fixed by the first data line
  std::size_t first_data_line = 0;
  for_each_line(file, [&](const std::string& text, std::size_t line) {
    const std::vector<std::string_view> f = split_fields(text);
    if (f.empty() || f[0].front() == '#') return;
    const auto fail = [&](const std::string& what) { throw TrajectoryParseError(file, line, what); };
    if (f.size() != 4 && f.size() != 5) {
      fail("expected 4 columns (t x y theta) or 5 (index t x y theta), found " + std::to_string(f.size()));
    }
    if (columns == 0) {
      columns = f.size();
      first_data_line = line;
    } else if (f.size() != columns) {
      fail("found " + std::to_string(f.size()) + " columns, line " + std::to_string(first_data_line) + " has " +
           std::to_string(columns));
    }
    const std::size_t k = columns - 4;  // first of t x y theta
    if (k == 1) {
      long long index = 0;
      const auto [ptr, ec] = std::from_chars(f[0].data(), f[0].data() + f[0].size(), index);
      if (ec != std::errc() || ptr != f[0].data() + f[0].size() || index < 0) {
        fail("index is not a non-negative integer: '" + std::string(f[0]) + "'");
      }
    }
    static constexpr const char* kNames[] = {"t", "x", "y", "theta"};
    double v[4];
    for (std::size_t i = 0; i < 4; ++i) {
      const std::optional<double> d = parse_double(f[k + i]);
      if (!d) fail(std::string(kNames[i]) + " is not a number: '" + std::string(f[k + i]) + "'");
      if (!std::isfinite(*d)) fail(std::string(kNames[i]) + " is not finite: '" + std::string(f[k + i]) + "'");
      v[i] = *d;
    }
    if (std::abs(v[0]) > 9.0e12) fail("t does not fit in microseconds: " + std::string(f[k]));
    poses.push_back(StampedPose{static_cast<int64_t>(std::llround(v[0] * 1e6)), Pose2(v[1], v[2], wrap_angle(v[3]))});
  });
  return poses;
}

void write_trajectory(const std::filesystem::path& file, const std::vector<StampedPose>& poses,
                      const std::vector<std::string>& header_comments) {
  std::string text;
  for (const std::string& comment : header_comments) {
    if (comment.find_first_of("\r\n") != std::string::npos) {
      throw std::invalid_argument("write_trajectory: a header comment spans several lines");
    }
    text += "# " + comment + "\n";
  }
  char buf[128];
  for (std::size_t i = 0; i < poses.size(); ++i) {
    const Pose2& p = poses[i].pose;
    if (!std::isfinite(p.x) || !std::isfinite(p.y) || !std::isfinite(p.phi)) {
      throw std::invalid_argument("write_trajectory: pose " + std::to_string(i) + " is not finite");
    }
    std::snprintf(buf, sizeof buf, " %.6f %.6f %.6f\n", p.x, p.y, p.phi);
    text += seconds_text(poses[i].utime);
    text += buf;
  }
  write_text_file(file, text, false);
}

}  // namespace lmf::io
