#include "lmf/io/trajectory.hpp"

#include <cmath>
#include <filesystem>
#include <fstream>
#include <numbers>
#include <string>

#include <gtest/gtest.h>

#include "lmf/io/carmen.hpp"
#include "test_support.hpp"

namespace lmf::io {
namespace {

namespace fs = std::filesystem;

fs::path temp_path(const std::string& name) { return fs::path(::testing::TempDir()) / ("lmf_traj_" + name); }

void write_text(const fs::path& file, const std::string& text) {
  std::ofstream f(file, std::ios::binary);
  f << text;
}

TEST(TrajectoryDatasets, ReferenceFilesMatchTheNoisyLogsScanForScan) {
  LMF_REQUIRE_DATASETS(dir);
  for (const auto& [name, count] : {std::pair<std::string, std::size_t>{"belgioioso", 395},
                                    {"freiburg-101", 292},
                                    {"orebro", 237}}) {
    SCOPED_TRACE(name);
    const std::vector<StampedPose> gt = read_trajectory(dir / (name + "-noisy.gt"));
    const CarmenLog log = read_carmen_log(dir / (name + "-noisy.log.gz"));
    ASSERT_EQ(gt.size(), count);
    ASSERT_EQ(log.scans.size(), count);
    for (std::size_t i = 0; i < count; ++i) ASSERT_EQ(gt[i].utime, log.scans[i].utime) << i;
  }
  // belgioioso-noisy.gt line 2: "1 1000.394140 0.127110 -0.142727 -1.115560".
  const std::vector<StampedPose> gt = read_trajectory(dir / "belgioioso-noisy.gt");
  EXPECT_EQ(gt[1].utime, 1000394140);
  EXPECT_DOUBLE_EQ(gt[1].pose.x, 0.127110);
  EXPECT_DOUBLE_EQ(gt[1].pose.y, -0.142727);
  EXPECT_DOUBLE_EQ(gt[1].pose.phi, -1.115560);
}

TEST(Trajectory, FourColumnsWithCommentsAndWrapping) {
  const fs::path file = temp_path("four.txt");
  write_text(file, "# t x y theta\n\n1.5 1 2 0.25\n  2.000001\t3 4 4.0  \r\n+3 -1e-3 0 -3.5\n");
  const std::vector<StampedPose> t = read_trajectory(file);
  ASSERT_EQ(t.size(), 3u);
  EXPECT_EQ(t[0].utime, 1500000);
  EXPECT_EQ(t[1].utime, 2000001);
  EXPECT_EQ(t[2].utime, 3000000);
  EXPECT_DOUBLE_EQ(t[0].pose.phi, 0.25);
  EXPECT_NEAR(t[1].pose.phi, 4.0 - 2.0 * std::numbers::pi, 1e-12);
  EXPECT_NEAR(t[2].pose.phi, -3.5 + 2.0 * std::numbers::pi, 1e-12);
  EXPECT_DOUBLE_EQ(t[2].pose.x, -1e-3);
  fs::remove(file);
}

TEST(Trajectory, BadLinesNameFileAndLine) {
  const std::vector<std::pair<std::string, std::string>> cases = {
      {"1 2 3", "expected 4 columns (t x y theta) or 5 (index t x y theta), found 3"},
      {"0 1 2 3 4 5", "found 6"},
      {"1.0 2 3 0", "found 4 columns, line 2 has 5"},
      {"x 1.0 2 3 0", "index is not a non-negative integer: 'x'"},
      {"-1 1.0 2 3 0", "index is not a non-negative integer"},
      {"3 1.0 2 nan 0", "y is not finite"},
      {"3 1.0 2 3 inf", "theta is not finite"},
      {"3 1.0 2 3,5 0", "y is not a number: '3,5'"},
      {"3 1e300 2 3 0", "t does not fit"},
  };
  const fs::path file = temp_path("bad.gt");
  for (const auto& [line, fragment] : cases) {
    write_text(file, "# reference\n0 0.5 1 2 0\n" + line + "\n");
    try {
      read_trajectory(file);
      ADD_FAILURE() << "no error for: " << line;
    } catch (const TrajectoryParseError& e) {
      const std::string what = e.what();
      EXPECT_EQ(what.rfind(file.string() + ":3: ", 0), 0u) << what;
      EXPECT_NE(what.find(fragment), std::string::npos) << "expected '" << fragment << "' in: " << what;
      EXPECT_EQ(e.line(), 3u);
    }
  }
  fs::remove(file);
  EXPECT_THROW(read_trajectory("/nonexistent/x.gt"), std::runtime_error);
}

TEST(Trajectory, WriteReadRoundTripPlainAndGzip) {
  std::vector<StampedPose> poses;
  for (int k = 0; k < 50; ++k) {
    poses.push_back({1'700'000'000'000'001 + 333'333 * k, Pose2(0.1234567 * k, -5.0 + 0.3 * k, wrap_angle(0.7 * k))});
  }
  poses.push_back({-2'000'001, Pose2(1, 2, 3)});
  for (const std::string name : {"rt.txt", "rt.txt.gz"}) {
    const fs::path file = temp_path(name);
    write_trajectory(file, poses, {"estimate of a test"});
    const std::vector<StampedPose> back = read_trajectory(file);
    ASSERT_EQ(back.size(), poses.size());
    for (std::size_t i = 0; i < poses.size(); ++i) {
      EXPECT_EQ(back[i].utime, poses[i].utime);
      EXPECT_TRUE(is_near(back[i].pose, poses[i].pose, 6e-7, 6e-7));
    }
    std::ifstream f(file, std::ios::binary);
    std::string first;
    std::getline(f, first);
    if (name.ends_with(".gz")) {
      EXPECT_EQ(static_cast<unsigned char>(first[0]), 0x1f);
    } else {
      EXPECT_EQ(first, "# estimate of a test");
      std::string second;
      std::getline(f, second);
      EXPECT_EQ(second, "1700000000.000001 0.000000 -5.000000 0.000000");
    }
    fs::remove(file);
  }
  poses[3].pose.y = std::nan("");
  EXPECT_THROW(write_trajectory(temp_path("nan.txt"), poses), std::invalid_argument);
}

}  // namespace
}  // namespace lmf::io
