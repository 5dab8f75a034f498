// The local map on a real log with noisy odometry (datasets/README.md): one
// robot over the first 10 m of travel of belgioioso must stay close to the
// reference trajectory, aligned at scan 0 (the reference pose of scan 0 is L).
#include <cmath>
#include <cstdio>
#include <numbers>
#include <vector>

#include <gtest/gtest.h>

#include "lmf/io/carmen.hpp"
#include "lmf/io/trajectory.hpp"
#include "lmf/local_map/local_map.hpp"
#include "test_support.hpp"

namespace lmf {
namespace {

constexpr double kRadToDeg = 180.0 / std::numbers::pi;

TEST(LocalMapDataset, BelgioiosoFirstTenMetres) {
  LMF_REQUIRE_DATASETS(dir);
  const io::CarmenLog log = io::read_carmen_log(dir / "belgioioso-noisy.log.gz");
  const std::vector<StampedPose> reference = io::read_trajectory(dir / "belgioioso-noisy.gt");
  ASSERT_EQ(log.scans.size(), reference.size());

  LocalMapConfig config;
  config.ship_distance_m = 1e9;  // one local map over the whole stretch
  config.max_segments = 100000;
  LocalMap lm(config);

  double travelled_m = 0.0;
  std::size_t k = 0;
  int total_paired = 0;
  for (; k < log.scans.size(); ++k) {
    if (k > 0) {
      const Pose2 step = between(reference[k - 1].pose, reference[k].pose);
      travelled_m += std::hypot(step.x, step.y);
    }
    const ScanReport r = lm.process_scan(log.scans[k]);
    ASSERT_TRUE(r.covariance_health.ok()) << "scan " << k << ": " << r.covariance_health.describe();
    total_paired += r.pairings_accepted_joint;
    if (travelled_m >= 10.0) break;
  }
  ASSERT_LT(k, log.scans.size()) << "the log is shorter than 10 m";

  const Pose2 truth = between(reference.front().pose, reference[k].pose);
  const Pose2 odometry = between(log.scans.front().odometry, log.scans[k].odometry);
  const Pose2 estimate = lm.x_LR();
  const double error_m = std::hypot(estimate.x - truth.x, estimate.y - truth.y);
  const double error_deg = std::abs(wrap_angle(estimate.phi - truth.phi)) * kRadToDeg;
  const double odometry_error_m = std::hypot(odometry.x - truth.x, odometry.y - truth.y);
  const double odometry_error_deg = std::abs(wrap_angle(odometry.phi - truth.phi)) * kRadToDeg;
  std::printf("belgioioso, scan %zu (%.2f m travelled): local map error %.3f m / %.2f deg, "
              "odometry error %.3f m / %.2f deg, %zu segments, %d pairings\n",
              k, travelled_m, error_m, error_deg, odometry_error_m, odometry_error_deg, lm.num_segments(),
              total_paired);
  EXPECT_LT(error_m, 0.2);
  EXPECT_LT(error_deg, 2.0);
  EXPECT_GT(total_paired, 0);
}

}  // namespace
}  // namespace lmf
