// The no-return reading of a log that does not state it (no_return_reading.hpp),
// and the CARMEN reader using it for FLASER scans.
#include "lmf/io/no_return_reading.hpp"

#include <cmath>
#include <filesystem>
#include <fstream>
#include <numbers>
#include <string>
#include <vector>

#include <gtest/gtest.h>

#include "lmf/io/carmen.hpp"
#include "test_support.hpp"

namespace lmf::io {
namespace {

// A scan of 181 beams: walls at 1.0 + 0.01 i + 0.001 k (k the scan), and
// beams [first_free, last_free] with no return, read as `ceiling`.
LaserScan scan_with_ceiling(int k, double ceiling, int first_free, int last_free) {
  LaserScan scan;
  scan.max_range_m = 81.0;
  for (int i = 0; i < 181; ++i) {
    const bool free = i >= first_free && i <= last_free;
    scan.ranges_m.push_back(free ? ceiling : 1.0 + 0.01 * i + 0.001 * k);
  }
  return scan;
}

TEST(NoReturnReading, AShortRangeLasersCeilingIsFound) {
  std::vector<LaserScan> scans;
  for (int k = 0; k < 100; ++k) scans.push_back(scan_with_ceiling(k, 5.6, 80, 100));
  const NoReturnReading found = find_no_return_reading(scans);
  ASSERT_TRUE(found.range_m.has_value());
  EXPECT_DOUBLE_EQ(*found.range_m, 5.6);
  EXPECT_EQ(found.scans_touching, 100u);
  EXPECT_EQ(found.scans, 100u);
  EXPECT_EQ(describe(found), "no-return reading 5.600 m (in 100 % of the scans)");
}

TEST(NoReturnReading, AFewReadingsOfAnotherCodeAboveTheCeilingAreAllowed) {
  // As a SICK's 51.15 m with now and then 51.2 m.
  std::vector<LaserScan> scans;
  for (int k = 0; k < 300; ++k) scans.push_back(scan_with_ceiling(k, k == 7 ? 51.2 : 51.15, 80, 100));
  const NoReturnReading found = find_no_return_reading(scans);
  ASSERT_TRUE(found.range_m.has_value());
  EXPECT_DOUBLE_EQ(*found.range_m, 51.15);
  EXPECT_EQ(found.scans_passing, 0u);  // within the pass margin
  scans[8] = scan_with_ceiling(8, 60.0, 80, 100);
  EXPECT_EQ(find_no_return_reading(scans).scans_passing, 1u);
  EXPECT_TRUE(find_no_return_reading(scans).range_m.has_value());
}

TEST(NoReturnReading, AWallAtOneDistanceInManyScansIsNoCeilingWhereOthersReadFarther) {
  // A robot standing before a wall 6.0 m away for 30 scans (a log rounded to
  // centimetres repeats it), then driving on, seeing farther walls.
  std::vector<LaserScan> scans;
  for (int k = 0; k < 30; ++k) scans.push_back(scan_with_ceiling(k, 6.0, 80, 100));
  for (int k = 30; k < 100; ++k) scans.push_back(scan_with_ceiling(k, 9.0 + 0.01 * k, 80, 100));
  const NoReturnReading found = find_no_return_reading(scans);
  EXPECT_FALSE(found.range_m.has_value());
  EXPECT_EQ(found.scans_touching, 30u);
  EXPECT_EQ(found.scans_passing, 70u);
}

TEST(NoReturnReading, TooFewScansOrOneConstantRangeTellNothing) {
  std::vector<LaserScan> few;
  for (int k = 0; k < 9; ++k) few.push_back(scan_with_ceiling(k, 5.6, 80, 100));
  EXPECT_FALSE(find_no_return_reading(few).range_m.has_value());
  std::vector<LaserScan> constant(50, scan_with_ceiling(0, 1.5, 0, 180));
  EXPECT_FALSE(find_no_return_reading(constant).range_m.has_value());
  EXPECT_FALSE(find_no_return_reading({}).range_m.has_value());
}

TEST(NoReturnReading, OnlyTheCountedScansCount) {
  std::vector<LaserScan> scans;
  for (int k = 0; k < 20; ++k) scans.push_back(scan_with_ceiling(k, 5.6, 80, 100));
  for (int k = 0; k < 20; ++k) scans.push_back(scan_with_ceiling(k, 8.0, 80, 100));
  const NoReturnReading found =
      find_no_return_reading(scans, [](const LaserScan& s) { return s.ranges_m[90] == 5.6; });
  ASSERT_TRUE(found.range_m.has_value());
  EXPECT_DOUBLE_EQ(*found.range_m, 5.6);
  EXPECT_EQ(found.scans, 20u);
}

// A FLASER line of `ranges`.
std::string flaser_line(const std::vector<std::string>& ranges, int k) {
  std::string s = "FLASER " + std::to_string(ranges.size());
  for (const std::string& r : ranges) s += " " + r;
  const std::string pose = std::to_string(0.1 * k) + " 0 0";
  const std::string t = std::to_string(k) + ".5";
  return s + " " + pose + " " + pose + " " + t + " host " + t + "\n";
}

TEST(CarmenNoReturn, AFlaserLogsCeilingBecomesItsScansMaximumRange) {
  const std::filesystem::path file = std::filesystem::path(::testing::TempDir()) / "lmf_no_return.log";
  {
    std::ofstream out(file);
    for (int k = 0; k < 40; ++k) {
      std::vector<std::string> ranges;
      for (int i = 0; i < 181; ++i) ranges.push_back(i > 60 && i < 120 ? "8.000" : std::to_string(1.0 + 0.01 * i));
      out << flaser_line(ranges, k);
    }
  }
  const CarmenLog log = read_carmen_log(file);
  ASSERT_TRUE(log.flaser_no_return.range_m.has_value());
  EXPECT_DOUBLE_EQ(*log.flaser_no_return.range_m, 8.0);
  ASSERT_EQ(log.scans.size(), 40u);
  for (const LaserScan& scan : log.scans) EXPECT_DOUBLE_EQ(scan.max_range_m, 8.0);
  // A ceiling at or above the options' range changes nothing.
  CarmenReadOptions options;
  options.flaser_max_range_m = 7.0;
  const CarmenLog capped = read_carmen_log(file, options);
  EXPECT_DOUBLE_EQ(capped.scans.front().max_range_m, 7.0);
  std::filesystem::remove(file);
}

TEST(CarmenNoReturn, TheDatasetsLasersCeilingsAreTheirNoReturnCodes) {
  LMF_REQUIRE_DATASETS(dir);
  // orebro's SICK writes 32.767 m (and a few codes just below it): its scans'
  // maximum range becomes that; belgioioso's 81.91 m lies above the options'
  // 81 m, which stays.
  const CarmenLog orebro = read_carmen_log(dir / "orebro-noisy.log.gz");
  ASSERT_TRUE(orebro.flaser_no_return.range_m.has_value());
  EXPECT_DOUBLE_EQ(*orebro.flaser_no_return.range_m, 32.767);
  EXPECT_DOUBLE_EQ(orebro.scans.front().max_range_m, 32.767);
  const CarmenLog belgioioso = read_carmen_log(dir / "belgioioso-noisy.log.gz");
  ASSERT_TRUE(belgioioso.flaser_no_return.range_m.has_value());
  EXPECT_DOUBLE_EQ(*belgioioso.flaser_no_return.range_m, 81.91);
  EXPECT_DOUBLE_EQ(belgioioso.scans.front().max_range_m, CarmenReadOptions{}.flaser_max_range_m);
}

}  // namespace
}  // namespace lmf::io
