#include "lmf/io/carmen.hpp"

#include <cmath>
#include <filesystem>
#include <fstream>
#include <numbers>
#include <sstream>
#include <string>

#include <gtest/gtest.h>

#include "test_support.hpp"

namespace lmf::io {
namespace {

namespace fs = std::filesystem;

fs::path temp_path(const std::string& name) { return fs::path(::testing::TempDir()) / ("lmf_carmen_" + name); }

void write_text(const fs::path& file, const std::string& text) {
  std::ofstream f(file, std::ios::binary);
  f << text;
}

std::string read_bytes(const fs::path& file) {
  std::ifstream f(file, std::ios::binary);
  std::stringstream s;
  s << f.rdbuf();
  return s.str();
}

// A FLASER line with n beams of range r, odometry (x, y, theta) and time stamp ts.
std::string flaser(std::size_t n, const std::string& r = "1.5", const std::string& pose = "1 2 0.5",
                   const std::string& ts = "12.25") {
  std::string s = "FLASER " + std::to_string(n);
  for (std::size_t i = 0; i < n; ++i) s += " " + r;
  return s + " " + pose + " " + pose + " " + ts + " host " + ts;
}

struct Expected {
  const char* name;
  std::size_t scans;
  std::size_t beams;
  std::size_t odom;  // corrected log only
  std::size_t neff;  // corrected log only
};

class CarmenDatasets : public ::testing::TestWithParam<Expected> {};

TEST_P(CarmenDatasets, ReadNoisyAndCorrectedLogs) {
  LMF_REQUIRE_DATASETS(dir);
  const Expected e = GetParam();
  const CarmenLog noisy = read_carmen_log(dir / (std::string(e.name) + "-noisy.log.gz"));
  const CarmenLog corrected = read_carmen_log(dir / (std::string(e.name) + "-corrected.log.gz"));
  ASSERT_EQ(noisy.scans.size(), e.scans);
  ASSERT_EQ(corrected.scans.size(), e.scans);
  EXPECT_TRUE(noisy.odometry.empty());
  EXPECT_TRUE(noisy.skipped.empty());
  EXPECT_TRUE(noisy.params.empty());
  EXPECT_EQ(corrected.odometry.size(), e.odom);
  ASSERT_EQ(corrected.skipped.size(), 1u);
  EXPECT_EQ(corrected.skipped.at("NEFF"), e.neff);
  for (const CarmenLog* log : {&noisy, &corrected}) {
    for (const LaserScan& s : log->scans) {
      ASSERT_EQ(s.ranges_m.size(), e.beams);
      EXPECT_DOUBLE_EQ(s.angle_min_rad, -std::numbers::pi / 2.0);
      // The last beam points at +90 degrees (odd n) or one step short of it (even n).
      const double last = s.beam_angle(e.beams - 1);
      EXPECT_NEAR(last, e.beams % 2 == 1 ? std::numbers::pi / 2.0 : std::numbers::pi / 2.0 - s.angle_increment_rad,
                  1e-12);
      for (const double r : s.ranges_m) ASSERT_TRUE(std::isfinite(r) && r >= 0.0 && r < 100.0);
    }
  }
  // The noisy logs start at the origin with strictly increasing synthesized times.
  EXPECT_DOUBLE_EQ(noisy.scans.front().odometry.x, 0.0);
  for (std::size_t i = 1; i < noisy.scans.size(); ++i) EXPECT_GT(noisy.scans[i].utime, noisy.scans[i - 1].utime);
}

INSTANTIATE_TEST_SUITE_P(Logs, CarmenDatasets,
                         ::testing::Values(Expected{"belgioioso", 395, 361, 4442, 395},
                                           Expected{"freiburg-101", 292, 360, 4569, 292},
                                           Expected{"orebro", 237, 181, 255, 237}),
                         [](const auto& param_info) {
                           std::string n = param_info.param.name;
                           for (char& c : n) c = (c == '-') ? '_' : c;
                           return n;
                         });

TEST(CarmenDatasetValues, BelgioiosoFieldsAreDecoded) {
  LMF_REQUIRE_DATASETS(dir);
  const CarmenLog noisy = read_carmen_log(dir / "belgioioso-noisy.log.gz");
  // Line 4 of the file (after two comments): "... 0.112803 -0.052506 -0.605407 1000.394140 eval 1000.394140".
  const LaserScan& s = noisy.scans.at(1);
  EXPECT_EQ(s.utime, 1000394140);
  EXPECT_DOUBLE_EQ(s.odometry.x, 0.112803);
  EXPECT_DOUBLE_EQ(s.odometry.y, -0.052506);
  EXPECT_DOUBLE_EQ(s.odometry.phi, -0.605407);
  EXPECT_DOUBLE_EQ(s.ranges_m.back(), 3.35);
  EXPECT_DOUBLE_EQ(s.angle_increment_rad, std::numbers::pi / 360.0);
  const CarmenLog corrected = read_carmen_log(dir / "belgioioso-corrected.log.gz");
  // Set twice in the file (0.0, then -0.04): the last value wins.
  EXPECT_EQ(corrected.params.at("robot_frontlaser_offset"), "-0.04");
  EXPECT_EQ(corrected.params.size(), 169u);  // 171 PARAM lines, 169 distinct names
  EXPECT_EQ(noisy.scans.front().ranges_m, corrected.scans.front().ranges_m);
}

TEST(CarmenRead, PlainFileCommentsBlankLinesAndLineNumbers) {
  const fs::path file = temp_path("plain.log");
  write_text(file, "# comment\n\n   \nPARAM a 1 nohost 0\nPARAM a 2 nohost 0\nNEFF 3\nNEFF 4\r\n" + flaser(181) +
                       "\r\nODOM 1 2 3 0 0 0 5.5 h 5.5\n" + flaser(360, "2", "0 0 0", "7"));  // no final newline
  const CarmenLog log = read_carmen_log(file);
  ASSERT_EQ(log.scans.size(), 2u);
  EXPECT_EQ(log.scans[0].ranges_m.size(), 181u);
  EXPECT_EQ(log.scans[0].utime, 12250000);
  EXPECT_DOUBLE_EQ(log.scans[0].odometry.phi, 0.5);
  EXPECT_DOUBLE_EQ(log.scans[0].angle_increment_rad, std::numbers::pi / 180.0);
  EXPECT_DOUBLE_EQ(log.scans[0].max_range_m, CarmenReadOptions{}.flaser_max_range_m);
  EXPECT_EQ(log.scans[1].ranges_m.size(), 360u);
  EXPECT_EQ(log.scans[1].utime, 7000000);
  ASSERT_EQ(log.odometry.size(), 1u);
  EXPECT_EQ(log.odometry[0].utime, 5500000);
  EXPECT_NEAR(log.odometry[0].pose.phi, 3.0, 1e-12);
  EXPECT_EQ(log.params.at("a"), "2");
  EXPECT_EQ(log.skipped.at("NEFF"), 2u);
  fs::remove(file);
}

TEST(CarmenRead, VeryLongLinesAreReadWhole) {
  // 4096 beams of 22 characters: a 90 KB line, longer than the reader's chunk.
  const fs::path file = temp_path("long.log");
  write_text(file, flaser(4096, "1.00000000000000000000") + "\n" + flaser(4096, "2.5") + "\n");
  const CarmenLog log = read_carmen_log(file);
  ASSERT_EQ(log.scans.size(), 2u);
  EXPECT_EQ(log.scans[0].ranges_m.size(), 4096u);
  EXPECT_DOUBLE_EQ(log.scans[0].ranges_m.back(), 1.0);
  EXPECT_DOUBLE_EQ(log.scans[1].ranges_m.front(), 2.5);
  fs::remove(file);
}

TEST(CarmenRead, RobotLaser1UsesItsOwnGeometry) {
  // type start fov res maxr acc remmode n r.. m rem.. laser(3) robot(3) tv rv fs ss ta ts host lts
  const std::string line =
      "ROBOTLASER1 0 -1.5 3.0 0.5 30.0 0.01 0 7 1 2 3 4 5 6 7 2 0.1 0.2 "
      "9 9 9 1.0 2.0 -0.25 0.1 0.2 0.3 0.4 0.5 3.000001 host 3.1";
  CarmenLog log;
  parse_carmen_line(line, "x.log", 1, {}, log);
  ASSERT_EQ(log.scans.size(), 1u);
  const LaserScan& s = log.scans[0];
  EXPECT_DOUBLE_EQ(s.angle_min_rad, -1.5);
  EXPECT_DOUBLE_EQ(s.angle_increment_rad, 0.5);
  EXPECT_DOUBLE_EQ(s.max_range_m, 30.0);
  EXPECT_EQ(s.ranges_m, (std::vector<double>{1, 2, 3, 4, 5, 6, 7}));
  EXPECT_DOUBLE_EQ(s.odometry.x, 1.0);
  EXPECT_DOUBLE_EQ(s.odometry.phi, -0.25);
  EXPECT_EQ(s.utime, 3000001);
  CarmenLog bad;
  EXPECT_THROW(parse_carmen_line(line + " extra", "x.log", 1, {}, bad), CarmenParseError);
}

// Each bad line, alone on line 3 of a file after a comment and a good scan,
// must fail with "file:3: " and the given fragment.
struct BadLine {
  std::string line;
  std::string fragment;
};

TEST(CarmenRead, BadLinesNameFileLineAndProblem) {
  std::string missing_one = flaser(361);
  missing_one.replace(missing_one.find(" 1.5"), 4, "");
  const std::vector<BadLine> cases = {
      {missing_one, "FLASER: expected 361 ranges, found 360"},
      {flaser(361) + " 7", "FLASER: expected 361 ranges, found 362"},
      {flaser(5, "-0.3"), "negative range -0.3"},
      {flaser(5, "1.5x"), "range 0 is not a number: '1.5x'"},
      {flaser(5, "1.5", "1 nan 0"), "laser pose y is NaN"},
      {flaser(5, "1.5", "1 2 0", "abc"), "timestamp is not a number"},
      {flaser(5, "1.5", "1 2 0", "1e300"), "does not fit"},
      {"FLASER 0 1 2 3 4 5 6 7 h 8", "beam count 0 outside 2..4096"},
      {"FLASER 5000", "beam count 5000 outside 2..4096"},
      {"FLASER 3.5 1 2 3", "beam count is not an integer"},
      {"FLASER", "missing the beam count"},
      {"FLASER 4 1 2", "expected 4 ranges, line has only 4 fields"},
      {"ODOM 1 2 3 0 0 0 5.5 h", "ODOM: expected 9 fields, found 8"},
      {"ODOM 1 2 NaN 0 0 0 5.5 h 5.5", "ODOM: pose theta is NaN"},
      {"PARAM lonely", "PARAM: expected a name and a value"},
      {"ROBOTLASER1 0 -1.5 3.0 0 30 0 0 2 1 1 0 0 0 0 0 0 0 0 0 0 0 0 1 h 1", "angular resolution must be positive"},
  };
  const fs::path file = temp_path("bad.log");
  for (const BadLine& c : cases) {
    write_text(file, "# header\n" + flaser(10) + "\n" + c.line + "\n" + flaser(10) + "\n");
    try {
      read_carmen_log(file);
      ADD_FAILURE() << "no error for: " << c.line.substr(0, 80);
    } catch (const CarmenParseError& e) {
      const std::string what = e.what();
      EXPECT_EQ(what.rfind(file.string() + ":3: ", 0), 0u) << what;
      EXPECT_NE(what.find(c.fragment), std::string::npos) << "expected '" << c.fragment << "' in: " << what;
      EXPECT_EQ(e.line(), 3u);
      EXPECT_EQ(e.file(), file);
    }
  }
  fs::remove(file);
}

// Lasers write NaN or inf for a beam with no return: a reading, not a format
// error. It becomes the scan's "no return" value and is counted.
TEST(CarmenRead, NaNAndInfiniteRangesAreNoReturn) {
  std::string nan_17 = flaser(20);
  {
    std::size_t pos = 0;
    for (int i = 0; i <= 17; ++i) pos = nan_17.find(" 1.5", pos + 1);
    nan_17.replace(pos, 4, " nan");
  }
  const fs::path file = temp_path("no_return.log");
  write_text(file, flaser(10) + "\n" + nan_17 + "\n" + flaser(5, "inf") + "\n" + flaser(5, "-inf") + "\n");
  const CarmenLog log = read_carmen_log(file);
  ASSERT_EQ(log.scans.size(), 4u);
  EXPECT_EQ(log.no_return_readings, 11u);
  const LaserScan& with_nan = log.scans[1];
  EXPECT_EQ(with_nan.ranges_m[17], with_nan.max_range_m);
  EXPECT_EQ(with_nan.ranges_m[16], 1.5);
  for (double r : log.scans[2].ranges_m) EXPECT_EQ(r, log.scans[2].max_range_m);
  EXPECT_FALSE(log.cut_short.has_value());
  // Elsewhere a non-finite number is still an error.
  write_text(file, flaser(5, "1.5", "1 nan 0") + "\n");
  EXPECT_THROW(read_carmen_log(file), CarmenParseError);
  fs::remove(file);
}

// A logger killed while it wrote a line leaves the last line cut and without
// its newline: the log is read up to it, and the cut is reported. The same
// line with its newline, or anywhere but last, is an error.
TEST(CarmenRead, ALastLineCutByAKilledLoggerIsReportedNotFatal) {
  const std::string good = flaser(181);
  const std::string cut = good.substr(0, good.size() / 3);
  const fs::path file = temp_path("cut_line.log");
  write_text(file, good + "\n" + good + "\n" + cut);
  const CarmenLog log = read_carmen_log(file);
  EXPECT_EQ(log.scans.size(), 2u);
  EXPECT_EQ(log.laser_poses.size(), 2u);
  ASSERT_TRUE(log.cut_short.has_value());
  EXPECT_NE(log.cut_short->find(file.string() + ":3: FLASER: expected 181 ranges"), std::string::npos) << *log.cut_short;
  EXPECT_NE(log.cut_short->find("cut"), std::string::npos) << *log.cut_short;

  write_text(file, good + "\n" + good + "\n" + cut + "\n");
  EXPECT_THROW(read_carmen_log(file), CarmenParseError);
  write_text(file, good + "\n" + cut + "\n" + good);
  EXPECT_THROW(read_carmen_log(file), CarmenParseError);
  // A whole last line without a newline is simply read.
  write_text(file, good + "\n" + good);
  const CarmenLog whole = read_carmen_log(file);
  EXPECT_EQ(whole.scans.size(), 2u);
  EXPECT_FALSE(whole.cut_short.has_value());
  fs::remove(file);
}

TEST(CarmenRead, MissingAndCorruptFilesThrowRuntimeError) {
  EXPECT_THROW(read_carmen_log("/nonexistent/dir/x.log"), std::runtime_error);
  // A gzip stream cut in half.
  const fs::path full = temp_path("full.log.gz");
  std::vector<LaserScan> scans(50);
  for (auto& s : scans) {
    s.angle_min_rad = -std::numbers::pi / 2.0;
    s.angle_increment_rad = beam_increment_for_180deg(361);
    s.ranges_m.assign(361, 3.0);
  }
  write_carmen_log(full, scans);
  const std::string bytes = read_bytes(full);
  const fs::path cut = temp_path("cut.log.gz");
  write_text(cut, bytes.substr(0, bytes.size() / 2));
  EXPECT_THROW(read_carmen_log(cut), std::runtime_error);
  fs::remove(full);
  fs::remove(cut);
}

std::vector<LaserScan> sample_scans() {
  std::vector<LaserScan> scans;
  for (int k = 0; k < 20; ++k) {
    LaserScan s;
    const std::size_t n = k % 2 == 0 ? 361 : 180;
    s.utime = 1'700'000'000'123'456 + k * 200'001;
    s.odometry = Pose2(0.1234567 * k, -2.5 + 0.01 * k, wrap_angle(0.4 * k));
    s.angle_min_rad = -std::numbers::pi / 2.0;
    s.angle_increment_rad = beam_increment_for_180deg(n);
    s.max_range_m = 81.0;
    for (std::size_t i = 0; i < n; ++i) s.ranges_m.push_back(0.0123456 * static_cast<double>(i + k));
    scans.push_back(std::move(s));
  }
  return scans;
}

void expect_round_trip(const fs::path& file, const CarmenWriteOptions& options, bool expect_gzip) {
  const std::vector<LaserScan> scans = sample_scans();
  write_carmen_log(file, scans, options);
  const std::string bytes = read_bytes(file);
  ASSERT_GE(bytes.size(), 2u);
  const bool gz = static_cast<unsigned char>(bytes[0]) == 0x1f && static_cast<unsigned char>(bytes[1]) == 0x8b;
  EXPECT_EQ(gz, expect_gzip) << file;
  if (!expect_gzip) {
    EXPECT_EQ(bytes.rfind("# made by a test\nFLASER 361 0.000 0.012 0.025", 0), 0u) << bytes.substr(0, 80);
  }
  const CarmenLog log = read_carmen_log(file);
  ASSERT_EQ(log.scans.size(), scans.size());
  for (std::size_t k = 0; k < scans.size(); ++k) {
    const LaserScan& a = scans[k];
    const LaserScan& b = log.scans[k];
    EXPECT_EQ(b.utime, a.utime);
    EXPECT_TRUE(is_near(b.odometry, a.odometry, 1e-6, 1e-6));
    EXPECT_DOUBLE_EQ(b.angle_min_rad, a.angle_min_rad);
    EXPECT_DOUBLE_EQ(b.angle_increment_rad, a.angle_increment_rad);
    ASSERT_EQ(b.ranges_m.size(), a.ranges_m.size());
    for (std::size_t i = 0; i < a.ranges_m.size(); ++i) EXPECT_NEAR(b.ranges_m[i], a.ranges_m[i], 0.0005 + 1e-12);
  }
  fs::remove(file);
}

TEST(CarmenWrite, PlainRoundTrip) {
  CarmenWriteOptions options;
  options.header_comments = {"made by a test"};
  expect_round_trip(temp_path("rt.log"), options, false);
}

TEST(CarmenWrite, GzipRoundTripByOptionAndByName) {
  CarmenWriteOptions options;
  options.header_comments = {"made by a test"};
  expect_round_trip(temp_path("rt-by-name.log.gz"), options, true);
  options.gzip = true;
  expect_round_trip(temp_path("rt-by-option.log"), options, true);
}

TEST(CarmenWrite, NegativeTimeStampsKeepMicroseconds) {
  LaserScan s = sample_scans()[0];
  s.utime = -1'500'001;
  const std::string line = carmen_flaser_line(s, "h");
  EXPECT_NE(line.find(" -1.500001 h -1.500001"), std::string::npos) << line.substr(line.size() - 60);
  CarmenLog log;
  parse_carmen_line(line, "x", 1, {}, log);
  EXPECT_EQ(log.scans.at(0).utime, -1'500'001);
}

TEST(CarmenWrite, RejectsScansFlaserCannotExpress) {
  const fs::path file = temp_path("reject.log");
  auto scans = sample_scans();
  scans[3].angle_min_rad = -1.0;
  EXPECT_THROW(write_carmen_log(file, scans), std::invalid_argument);
  EXPECT_FALSE(fs::exists(file));  // nothing half written
  scans = sample_scans();
  scans[2].ranges_m[5] = std::nan("");
  EXPECT_THROW(write_carmen_log(file, scans), std::invalid_argument);
  scans = sample_scans();
  scans[1].ranges_m[0] = -1.0;
  EXPECT_THROW(write_carmen_log(file, scans), std::invalid_argument);
  scans = sample_scans();
  scans[0].ranges_m.resize(1);
  EXPECT_THROW(write_carmen_log(file, scans), std::invalid_argument);
  CarmenWriteOptions bad_host;
  bad_host.host = "two words";
  EXPECT_THROW(write_carmen_log(file, sample_scans(), bad_host), std::invalid_argument);
  EXPECT_THROW(write_carmen_log("/nonexistent/dir/x.log", sample_scans()), std::runtime_error);
}

}  // namespace
}  // namespace lmf::io
