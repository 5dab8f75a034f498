// Tests of the real-robot odometry model (lmf/sim/odometry.hpp, RealOdometry): determinism per
// seed, systematic errors that show in the mean, heading noise when driving straight, glitch
// rates as configured, and validation.
#include <cmath>
#include <limits>
#include <numbers>
#include <vector>

#include <gtest/gtest.h>

#include "lmf/sim/mission.hpp"
#include "lmf/sim/odometry.hpp"
#include "lmf/sim/random.hpp"

namespace lmf::sim {
namespace {

// Every random term off: only what the systematic errors do.
RealOdometryConfig noise_free() {
  RealOdometryConfig c;
  c.translation_noise_fraction = 0.0;
  c.rotation_noise_fraction = 0.0;
  c.heading_noise_rad2_per_m = 0.0;
  c.heading_noise_per_step_rad = 0.0;
  c.slip_per_m = 0.0;
  c.slip_per_rad = 0.0;
  c.heading_glitch_rate_per_m = 0.0;
  c.translation_glitch_rate_per_m = 0.0;
  return c;
}

// The default noise without glitches.
RealOdometryConfig without_glitches() {
  RealOdometryConfig c;
  c.heading_glitch_rate_per_m = 0.0;
  c.translation_glitch_rate_per_m = 0.0;
  return c;
}

std::vector<Pose2> increments(RobotOdometry& odometry, const std::vector<Pose2>& truth) {
  std::vector<Pose2> out;
  for (const Pose2& u : truth) out.push_back(odometry.increment(u));
  return out;
}

std::vector<Pose2> a_route() {
  std::vector<Pose2> route;
  for (int i = 0; i < 500; ++i) route.emplace_back(0.1 + 0.001 * (i % 7), 0.002 * (i % 3), 0.05 * std::sin(0.1 * i));
  return route;
}

TEST(RealOdometry, SameSeedSameIncrementsDifferentSeedDifferent) {
  const RealOdometryConfig config;
  RobotOdometry a(OdometryModel::kReal, OdometryNoiseConfig{}, config, 7);
  RobotOdometry b(OdometryModel::kReal, OdometryNoiseConfig{}, config, 7);
  RobotOdometry c(OdometryModel::kReal, OdometryNoiseConfig{}, config, 8);
  EXPECT_EQ(a.errors().translation_scale, b.errors().translation_scale);
  EXPECT_NE(a.errors().translation_scale, c.errors().translation_scale);
  const std::vector<Pose2> ua = increments(a, a_route());
  const std::vector<Pose2> ub = increments(b, a_route());
  const std::vector<Pose2> uc = increments(c, a_route());
  int differ = 0;
  for (std::size_t i = 0; i < ua.size(); ++i) {
    EXPECT_EQ(ua[i].x, ub[i].x);
    EXPECT_EQ(ua[i].y, ub[i].y);
    EXPECT_EQ(ua[i].phi, ub[i].phi);
    if (ua[i].x != uc[i].x) ++differ;
  }
  EXPECT_EQ(differ, static_cast<int>(ua.size()));
}

TEST(RealOdometry, StandingStillReportsNoMotion) {
  Rng rng(3);
  const RealOdometry odometry(RealOdometryConfig{}, rng);
  for (int i = 0; i < 100; ++i) {
    const Pose2 u = odometry.increment(Pose2(), rng);
    EXPECT_EQ(u.x, 0.0);
    EXPECT_EQ(u.y, 0.0);
    EXPECT_EQ(u.phi, 0.0);
  }
}

TEST(RealOdometry, NoiseFreeIncrementIsTheSystematicErrorExactly) {
  const RealOdometryErrors errors{1.05, 0.9, 0.01};
  const RealOdometry odometry(noise_free(), errors);
  Rng rng(1);
  const Pose2 u = odometry.increment(Pose2(0.4, 0.03, 0.2), rng);
  const double d = std::hypot(0.4, 0.03);
  EXPECT_NEAR(u.x, 1.05 * 0.4, 1e-15);
  EXPECT_NEAR(u.y, 1.05 * 0.03, 1e-15);
  EXPECT_NEAR(u.phi, 0.9 * 0.2 + 0.01 * d, 1e-15);
}

// The scale errors show in the mean of many noisy increments: the random part averages out.
TEST(RealOdometry, ScaleErrorsShowInTheMean) {
  const RealOdometryErrors errors{1.03, 0.95, 0.0};
  const RealOdometryConfig config = without_glitches();  // glitches have a non-zero mean
  const RealOdometry odometry(config, errors);
  Rng rng(11);
  const Pose2 u(0.5, 0.0, 0.3);
  const int n = 20000;
  double sum_x = 0.0;
  double sum_phi = 0.0;
  for (int i = 0; i < n; ++i) {
    const Pose2 v = odometry.increment(u, rng);
    sum_x += v.x;
    sum_phi += v.phi;
  }
  // Standard errors of the means: 0.02 * 0.5 / sqrt(n) = 7e-5 m and ~0.013 / sqrt(n) = 1e-4 rad.
  EXPECT_NEAR(sum_x / n, 1.03 * 0.5, 5e-4);
  EXPECT_NEAR(sum_phi / n, 0.95 * 0.3, 7e-4);
}

// Drawn per robot, the systematic errors spread as configured.
TEST(RealOdometry, SystematicErrorsAreDrawnWithTheConfiguredSpread) {
  const RealOdometryConfig config;
  const int robots = 4000;
  double sum2_t = 0.0;
  double sum2_r = 0.0;
  double sum2_b = 0.0;
  for (int i = 0; i < robots; ++i) {
    const RobotOdometry odometry(OdometryModel::kReal, OdometryNoiseConfig{}, config, derive_seed(99, i));
    sum2_t += std::pow(odometry.errors().translation_scale - 1.0, 2);
    sum2_r += std::pow(odometry.errors().rotation_scale - 1.0, 2);
    sum2_b += std::pow(odometry.errors().heading_bias_rad_per_m, 2);
  }
  // The sample standard deviation is within ~3 standard errors (sigma / sqrt(2 n) = 1.1 %).
  EXPECT_NEAR(std::sqrt(sum2_t / robots), config.translation_scale_sigma, 0.04 * config.translation_scale_sigma);
  EXPECT_NEAR(std::sqrt(sum2_r / robots), config.rotation_scale_sigma, 0.04 * config.rotation_scale_sigma);
  EXPECT_NEAR(std::sqrt(sum2_b / robots), config.heading_bias_sigma_rad_per_m,
              0.04 * config.heading_bias_sigma_rad_per_m);
  // The proportional model has none.
  const RobotOdometry proportional(OdometryModel::kProportional, OdometryNoiseConfig{}, config, 1);
  EXPECT_EQ(proportional.errors().translation_scale, 1.0);
  EXPECT_EQ(proportional.errors().heading_bias_rad_per_m, 0.0);
}

// Driving straight, the heading still wanders: per metre and per step, and slip moves it sideways.
TEST(RealOdometry, HeadingNoiseAndSlipDoNotVanishWhenDrivingStraight) {
  const RealOdometryConfig config = without_glitches();
  const RealOdometry odometry(config, RealOdometryErrors{});
  Rng rng(5);
  const Pose2 straight(0.5, 0.0, 0.0);
  const int n = 40000;
  double sum2_phi = 0.0;
  double sum2_y = 0.0;
  for (int i = 0; i < n; ++i) {
    const Pose2 v = odometry.increment(straight, rng);
    sum2_phi += v.phi * v.phi;
    sum2_y += v.y * v.y;
  }
  const double expected_phi =
      std::sqrt(config.heading_noise_rad2_per_m * 0.5 + std::pow(config.heading_noise_per_step_rad, 2));
  EXPECT_NEAR(std::sqrt(sum2_phi / n), expected_phi, 0.02 * expected_phi);
  EXPECT_NEAR(std::sqrt(sum2_y / n), config.slip_per_m * 0.5, 0.02 * config.slip_per_m * 0.5);
}

// Glitches arrive at the configured rate per metre, with the configured sizes.
TEST(RealOdometry, GlitchRatesAreAsConfigured) {
  RealOdometryConfig config = noise_free();
  config.heading_glitch_rate_per_m = 0.05;
  config.translation_glitch_rate_per_m = 0.02;
  const RealOdometry odometry(config, RealOdometryErrors{});
  Rng rng(21);
  const Pose2 straight(0.5, 0.0, 0.0);
  const int steps = 40000;  // 20 km: expected 1000 heading and 400 translation glitches
  int heading_glitches = 0;
  int translation_glitches = 0;
  int positive = 0;
  for (int i = 0; i < steps; ++i) {
    const Pose2 v = odometry.increment(straight, rng);
    if (v.phi != 0.0) {
      ++heading_glitches;
      if (v.phi > 0.0) ++positive;
      EXPECT_GE(std::abs(v.phi), config.heading_glitch_min_rad);
      EXPECT_LE(std::abs(v.phi), config.heading_glitch_max_rad);
    }
    if (v.x != 0.5) {
      ++translation_glitches;
      EXPECT_GE(v.x - 0.5, config.translation_glitch_min_m - 1e-12);
      EXPECT_LE(v.x - 0.5, config.translation_glitch_max_m + 1e-12);
    }
  }
  // Binomial with p = 1 - exp(-rate * 0.5): expected 994 and 400, standard deviations 31 and 20.
  EXPECT_NEAR(heading_glitches, steps * -std::expm1(-0.05 * 0.5), 130);
  EXPECT_NEAR(translation_glitches, steps * -std::expm1(-0.02 * 0.5), 80);
  EXPECT_NEAR(positive, heading_glitches / 2, 100);  // either sign
}

TEST(RealOdometry, ValidateRejectsBadValues) {
  EXPECT_NO_THROW(RealOdometryConfig{}.validate());
  const double nan = std::numeric_limits<double>::quiet_NaN();
  const auto rejects = [](auto change) {
    RealOdometryConfig c;
    change(c);
    EXPECT_THROW(c.validate(), std::invalid_argument);
  };
  rejects([](RealOdometryConfig& c) { c.translation_scale_sigma = -0.01; });
  rejects([&](RealOdometryConfig& c) { c.rotation_scale_sigma = nan; });
  rejects([](RealOdometryConfig& c) { c.heading_bias_sigma_rad_per_m = 0.5; });
  rejects([](RealOdometryConfig& c) { c.translation_noise_fraction = 1.5; });
  rejects([](RealOdometryConfig& c) { c.rotation_noise_fraction = -1.0; });
  rejects([&](RealOdometryConfig& c) { c.heading_noise_rad2_per_m = nan; });
  rejects([](RealOdometryConfig& c) { c.heading_noise_per_step_rad = -0.001; });
  rejects([](RealOdometryConfig& c) { c.slip_per_m = 2.0; });
  rejects([](RealOdometryConfig& c) { c.slip_per_rad = -0.1; });
  rejects([](RealOdometryConfig& c) { c.heading_glitch_rate_per_m = -1.0; });
  rejects([](RealOdometryConfig& c) { c.heading_glitch_min_rad = 0.2, c.heading_glitch_max_rad = 0.1; });
  rejects([](RealOdometryConfig& c) { c.heading_glitch_max_rad = 2.0; });
  rejects([&](RealOdometryConfig& c) { c.translation_glitch_rate_per_m = nan; });
  rejects([](RealOdometryConfig& c) { c.translation_glitch_min_m = 0.3, c.translation_glitch_max_m = 0.2; });
  // Through the mission and the constructor too.
  MissionConfig mission;
  mission.real_odometry.slip_per_m = -1.0;
  EXPECT_THROW(mission.validate(), std::invalid_argument);
  Rng rng(1);
  RealOdometryConfig bad;
  bad.rotation_noise_fraction = 3.0;
  EXPECT_THROW(RealOdometry(bad, rng), std::invalid_argument);
  EXPECT_THROW(parse_odometry_model("wheels"), std::invalid_argument);
  EXPECT_EQ(parse_odometry_model(odometry_model_name(OdometryModel::kReal)), OdometryModel::kReal);
}

// In a mission: the real model changes only the odometry (same scans, same truth), deterministically,
// and the robots' systematic errors are recorded.
TEST(RealOdometry, MissionUnderRealOdometryIsDeterministicAndKeepsTheTruth) {
  MissionConfig config;
  config.duration_s = 60.0;
  config.num_robots = 2;
  const Mission proportional = simulate_mission(config);
  config.odometry_model = OdometryModel::kReal;
  const Mission real = simulate_mission(config);
  const Mission again = simulate_mission(config);
  ASSERT_EQ(real.robots.size(), 2u);
  for (std::size_t r = 0; r < 2; ++r) {
    const RobotRun& a = real.robots[r];
    ASSERT_EQ(a.scans.size(), proportional.robots[r].scans.size());
    EXPECT_NE(a.odometry_errors.translation_scale, 1.0);
    EXPECT_EQ(a.odometry_errors.translation_scale, again.robots[r].odometry_errors.translation_scale);
    const std::size_t last = a.scans.size() - 1;
    EXPECT_EQ(a.true_poses[last].x, proportional.robots[r].true_poses[last].x);
    EXPECT_EQ(a.scans[last].ranges_m, proportional.robots[r].scans[last].ranges_m);
    EXPECT_NE(a.scans[last].odometry.x, proportional.robots[r].scans[last].odometry.x);
    EXPECT_EQ(a.scans[last].odometry.x, again.robots[r].scans[last].odometry.x);
    EXPECT_EQ(a.scans[last].odometry.phi, again.robots[r].scans[last].odometry.phi);
  }
}

}  // namespace
}  // namespace lmf::sim
