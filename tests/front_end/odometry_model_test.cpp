// The odometry error model and its online learner (odometry_model.hpp): the
// paper's proportional model as a special case, the systematic correction and
// its Jacobian, and recovery of a known model from simulated scan matches —
// with glitches, and with a corridor that constrains no forward motion.
#include "lmf/front_end/odometry_model.hpp"

#include <cmath>
#include <limits>
#include <numbers>
#include <random>
#include <stdexcept>
#include <string>
#include <vector>

#include <Eigen/Cholesky>
#include <Eigen/LU>
#include <Eigen/QR>

#include <gtest/gtest.h>

#include "test_support.hpp"

namespace lmf {
namespace {

constexpr double kDeg = std::numbers::pi / 180.0;

Eigen::Vector3d tangent(const Pose2& p) { return {p.x, p.y, wrap_angle(p.phi)}; }
Pose2 pose(const Eigen::Vector3d& v) { return {v(0), v(1), v(2)}; }

TEST(OdometryErrorModel, ProportionalIsThePapersModel) {
  const OdometryErrorModel m = OdometryErrorModel::proportional(0.08, 0.07, 0.01, 0.002, 0.001);
  const Pose2 u(0.4, 0.1, -0.3);
  const double d = std::hypot(0.4, 0.1);
  const double s_xy = 0.08 * d;
  const double s_phi = 0.07 * 0.3 + 0.01 * d;
  const Eigen::Matrix3d Q = m.covariance(u);
  EXPECT_NEAR(Q(0, 0), s_xy * s_xy + 0.002 * 0.002, 1e-15);
  EXPECT_NEAR(Q(1, 1), s_xy * s_xy + 0.002 * 0.002, 1e-15);
  EXPECT_NEAR(Q(2, 2), s_phi * s_phi + 0.001 * 0.001, 1e-15);
  EXPECT_EQ(Q(0, 1), 0.0);
  const Pose2 c = m.corrected(u);
  EXPECT_EQ(c.x, u.x);
  EXPECT_EQ(c.y, u.y);
  EXPECT_EQ(c.phi, u.phi);
}

TEST(OdometryErrorModel, CorrectionScalesAndBiases) {
  OdometryErrorModel m;
  m.translation_scale = 0.9;
  m.rotation_scale = 1.05;
  m.heading_bias_rad_per_m = 0.02;
  const Pose2 c = m.corrected({0.3, -0.4, 0.5});
  EXPECT_NEAR(c.x, 0.27, 1e-15);
  EXPECT_NEAR(c.y, -0.36, 1e-15);
  EXPECT_NEAR(c.phi, 0.525 + 0.02 * 0.5, 1e-15);
}

TEST(OdometryErrorModel, SystematicJacobianMatchesFiniteDifferences) {
  OdometryErrorModel m;
  m.translation_scale = 0.97;
  m.rotation_scale = 1.04;
  m.heading_bias_rad_per_m = -0.01;
  for (const Pose2& u : {Pose2(0.5, 0.02, 0.1), Pose2(0.1, -0.3, 1.2), Pose2(-0.2, 0.05, -2.5)}) {
    const Pose2 u_bar = m.corrected(u);
    const auto f = [&](const Eigen::VectorXd& theta) -> Eigen::VectorXd {
      OdometryErrorModel n = m;
      n.translation_scale = 1.0 + theta(0);
      n.rotation_scale = 1.0 + theta(1);
      n.heading_bias_rad_per_m = theta(2);
      return tangent(between(u_bar, n.corrected(u)));
    };
    const auto difference = [](const Eigen::VectorXd& a, const Eigen::VectorXd& b) -> Eigen::VectorXd {
      Eigen::VectorXd d = a - b;
      d(2) = wrap_angle(d(2));
      return d;
    };
    const Eigen::MatrixXd numeric = testing::numerical_jacobian(f, m.systematic_parameters(), difference);
    EXPECT_TRUE(testing::matrices_near(m.systematic_jacobian(u), numeric, 1e-8));
  }
}

TEST(NonNegativeLeastSquares, ClampsNegativeCoefficientsAndKeepsTheRest) {
  Eigen::MatrixXd M(2, 2);
  M << 2.0, 0.0, 0.0, 1.0;
  Eigen::VectorXd b(2);
  b << 4.0, -3.0;  // unconstrained (2, -3)
  const Eigen::VectorXd c = non_negative_least_squares(M, b);
  EXPECT_NEAR(c(0), 2.0, 1e-12);
  EXPECT_EQ(c(1), 0.0);
  EXPECT_THROW(non_negative_least_squares(Eigen::MatrixXd::Identity(5, 5), Eigen::VectorXd::Zero(5)),
               std::invalid_argument);
}

TEST(OdometryLearningConfig, ValidateNamesTheField) {
  OdometryLearningConfig c;
  c.student_dof = 0.0;
  try {
    c.validate();
    FAIL() << "expected std::invalid_argument";
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find("student_dof"), std::string::npos) << e.what();
  }
  c = {};
  c.max_scale_error = 1.0;
  EXPECT_THROW(c.validate(), std::invalid_argument);
}

// A robot whose odometry follows `truth`, observed by a laser with information
// `laser` (of the true increment), matched with the learner's current model as
// the prior, as LocalMap::process_scan does. Returns the learner after `steps`.
struct Simulation {
  OdometryErrorModel truth;
  Eigen::Matrix3d laser = Eigen::Vector3d(1.0 / (0.01 * 0.01), 1.0 / (0.01 * 0.01), 1.0 / (0.003 * 0.003)).asDiagonal();
  double glitch_probability = 0.0;
  double glitch_rad = 0.0;
  unsigned seed = 1;
  std::vector<double>* translation_scales = nullptr;  // the learned scale after each step, if given

  OdometryModelLearner run(const OdometryErrorModel& prior, int steps) const {
    OdometryModelLearner learner(prior, OdometryLearningConfig{});
    std::mt19937 rng(seed);
    std::normal_distribution<double> normal;
    std::uniform_real_distribution<double> uniform;
    const Eigen::Matrix3d laser_cov = laser.completeOrthogonalDecomposition().pseudoInverse();
    for (int k = 0; k < steps; ++k) {
      // Odometry reading: mostly driving ~0.5 m, sometimes turning on the spot.
      const bool turning = uniform(rng) < 0.3;
      const Pose2 u = turning ? Pose2(0.05 * uniform(rng), 0.0, (uniform(rng) - 0.5) * 1.6)
                              : Pose2(0.3 + 0.4 * uniform(rng), 0.02 * (uniform(rng) - 0.5), 0.2 * (uniform(rng) - 0.5));
      // True increment: the corrected odometry perturbed by the true noise (and a glitch).
      const Eigen::Matrix3d Q_true = truth.covariance(u);
      Eigen::Vector3d n(std::sqrt(Q_true(0, 0)) * normal(rng), std::sqrt(Q_true(1, 1)) * normal(rng),
                        std::sqrt(Q_true(2, 2)) * normal(rng));
      if (uniform(rng) < glitch_probability) n(2) += uniform(rng) < 0.5 ? glitch_rad : -glitch_rad;
      const Pose2 t = compose(truth.corrected(u), pose(n));
      // Laser-only estimate of t, then the MAP with the learner's prior.
      const Eigen::Vector3d l(std::sqrt(laser_cov(0, 0)) * normal(rng), std::sqrt(laser_cov(1, 1)) * normal(rng),
                              std::sqrt(laser_cov(2, 2)) * normal(rng));
      const Pose2 z = compose(t, pose(l));
      const Pose2 u_bar = learner.model().corrected(u);
      const Eigen::Matrix3d Q = learner.model().covariance(u);
      const Eigen::Vector3d e = (laser + Q.inverse()).ldlt().solve(laser * tangent(between(u_bar, z)));
      learner.observe(u, compose(u_bar, pose(e)), laser);
      if (translation_scales != nullptr) translation_scales->push_back(learner.model().translation_scale);
    }
    return learner;
  }
};

OdometryErrorModel real_robot() {
  OdometryErrorModel m;
  m.translation_scale = 0.95;
  m.rotation_scale = 1.06;
  m.heading_bias_rad_per_m = 0.01;
  m.x_step_m = 0.01;
  m.x_per_m = 0.05;
  m.y_step_m = 0.01;
  m.y_per_m = 0.08;
  m.phi_step_rad = 1.0 * kDeg;
  m.phi_per_m = 2.0 * kDeg;
  m.phi_per_rad = 0.05;
  return m;
}

// The paper's 8 % model as the prior: far too optimistic for `real_robot`.
OdometryErrorModel paper_prior() { return OdometryErrorModel::proportional(0.08, 0.08, 0.01, 0.001, 0.0005); }

// Standard deviation of the heading noise of a 0.5 m straight step, and of a 1 rad turn on the spot.
double straight_phi_sigma(const OdometryErrorModel& m) { return std::sqrt(m.covariance({0.5, 0.0, 0.0})(2, 2)); }
double turn_phi_sigma(const OdometryErrorModel& m) { return std::sqrt(m.covariance({0.0, 0.0, 1.0})(2, 2)); }
double lateral_sigma(const OdometryErrorModel& m) { return std::sqrt(m.covariance({0.5, 0.0, 0.0})(1, 1)); }
double forward_sigma(const OdometryErrorModel& m) { return std::sqrt(m.covariance({0.5, 0.0, 0.0})(0, 0)); }

TEST(OdometryModelLearner, RecoversSystematicAndRandomErrorsFromAPaperPrior) {
  Simulation sim;
  sim.truth = real_robot();
  const OdometryModelLearner learner = sim.run(paper_prior(), 400);
  const OdometryErrorModel& m = learner.model();
  // Tolerances: a few standard errors of estimates from ~300 increments (the
  // learner's memory) of this robot; the prior is 5-10 times too optimistic.
  EXPECT_NEAR(m.translation_scale, 0.95, 0.015);
  EXPECT_NEAR(m.rotation_scale, 1.06, 0.02);
  EXPECT_NEAR(m.heading_bias_rad_per_m, 0.01, 0.012);
  EXPECT_NEAR(straight_phi_sigma(m) / straight_phi_sigma(sim.truth), 1.0, 0.25);
  EXPECT_NEAR(turn_phi_sigma(m) / turn_phi_sigma(sim.truth), 1.0, 0.25);
  EXPECT_NEAR(lateral_sigma(m) / lateral_sigma(sim.truth), 1.0, 0.25);
  EXPECT_NEAR(forward_sigma(m) / forward_sigma(sim.truth), 1.0, 0.25);
  // ... and far from the prior.
  EXPECT_GT(straight_phi_sigma(m) / straight_phi_sigma(paper_prior()), 2.0);
  EXPECT_EQ(learner.stats().increments, 400u);
}

// Odometry that is the prior itself (scale 1), seen by a laser that measures
// the motion along the track to 3 cm a step (a corridor's few doors). The
// scale is a constant of the robot: once the increments outnumber the memory
// it settles instead of following the memory's last 300 (whose estimate has a
// standard error of ~0.007 here, and wandered by that much).
TEST(OdometryModelLearner, TheLearnedScaleSettlesBeyondTheMemory) {
  Simulation sim;
  sim.truth = paper_prior();
  sim.laser = Eigen::Vector3d(1.0 / (0.03 * 0.03), 1.0 / (0.01 * 0.01), 1.0 / (0.003 * 0.003)).asDiagonal();
  std::vector<double> scales;
  sim.translation_scales = &scales;
  const OdometryModelLearner learner = sim.run(paper_prior(), 3000);
  ASSERT_EQ(scales.size(), 3000u);
  double mean = 0.0;
  for (std::size_t k = 2000; k < scales.size(); ++k) mean += scales[k] / 1000.0;
  double variance = 0.0;
  for (std::size_t k = 2000; k < scales.size(); ++k) variance += (scales[k] - mean) * (scales[k] - mean) / 1000.0;
  EXPECT_LT(std::sqrt(variance), 0.002);
  EXPECT_NEAR(learner.model().translation_scale, 1.0, 0.008);
}

// A heading bias beyond what unequal wheels can cause (0.1 rad/m, 5.7°/m, as
// a matcher that keeps rotating its scans would report) is learned only up to
// the physical bound.
TEST(OdometryModelLearner, TheHeadingBiasStaysWithinItsPhysicalBound) {
  Simulation sim;
  sim.truth = real_robot();
  sim.truth.heading_bias_rad_per_m = 0.1;
  const OdometryModelLearner learner = sim.run(paper_prior(), 300);
  const double bound = OdometryLearningConfig{}.max_heading_bias_rad_per_m;
  EXPECT_GT(bound, 0.0);
  EXPECT_NEAR(learner.model().heading_bias_rad_per_m, bound, 1e-12);
  // ... and said to be there.
  EXPECT_EQ(learner.stats().at_bounds, std::vector<std::string>{"heading_bias_rad_per_m"});
  EXPECT_NE(describe_bounds(learner.model(), learner.stats()).find("heading_bias_rad_per_m (0.0350)"),
            std::string::npos);
  // Inside the bound it is learned as before, and nothing is at a bound.
  sim.truth.heading_bias_rad_per_m = -0.5 * bound;
  const OdometryModelLearner inside = sim.run(paper_prior(), 300);
  EXPECT_NEAR(inside.model().heading_bias_rad_per_m, -0.5 * bound, 0.012);
  EXPECT_TRUE(inside.stats().at_bounds.empty());
  EXPECT_EQ(describe_bounds(inside.model(), inside.stats()), "");
}

// A translation scale no wheel has (matches that see the robot stand still
// while the odometry says it drove, as a laser's no-return readings read as
// returns do) is held at its bound, and the learner says so.
TEST(OdometryModelLearner, AScaleBeyondWhatWheelsDoIsHeldAtItsBoundAndReported) {
  Simulation sim;
  sim.truth = real_robot();
  sim.truth.translation_scale = 0.5;
  const OdometryModelLearner learner = sim.run(paper_prior(), 300);
  const double bound = OdometryLearningConfig{}.max_scale_error;
  EXPECT_NEAR(learner.model().translation_scale, 1.0 - bound, 1e-12);
  EXPECT_EQ(learner.stats().at_bounds, std::vector<std::string>{"translation_scale"});
}

TEST(OdometryModelLearner, GlitchesAreDownweightedNotLearnedAsNoise) {
  Simulation clean;
  clean.truth = real_robot();
  Simulation glitchy = clean;
  glitchy.glitch_probability = 0.05;
  glitchy.glitch_rad = 8.0 * kDeg;
  const OdometryModelLearner a = clean.run(paper_prior(), 400);
  const OdometryModelLearner b = glitchy.run(paper_prior(), 400);
  // An 8° glitch in 5 % of the steps would make the heading std of a straight
  // step ~1.9° -> ~2.6° if it were learned as Gaussian noise.
  EXPECT_NEAR(straight_phi_sigma(b.model()) / straight_phi_sigma(a.model()), 1.0, 0.15);
  EXPECT_NEAR(b.model().rotation_scale, 1.06, 0.015);
  EXPECT_GE(b.stats().downweighted, 10u);
  EXPECT_LE(a.stats().downweighted, b.stats().downweighted);
}

TEST(OdometryModelLearner, ADirectionTheLaserDoesNotSeeKeepsThePrior) {
  // A corridor along x: no forward information at all.
  Simulation corridor;
  corridor.truth = real_robot();
  corridor.laser(0, 0) = 0.0;
  const OdometryErrorModel prior = paper_prior();
  const OdometryModelLearner learner = corridor.run(prior, 300);
  EXPECT_NEAR(forward_sigma(learner.model()) / forward_sigma(prior), 1.0, 0.05);
  // ... while the heading is still learned.
  EXPECT_NEAR(straight_phi_sigma(learner.model()) / straight_phi_sigma(corridor.truth), 1.0, 0.25);
}

TEST(OdometryModelLearner, IgnoresNonFiniteInput) {
  OdometryModelLearner learner(paper_prior(), OdometryLearningConfig{});
  const double nan = std::numeric_limits<double>::quiet_NaN();
  EXPECT_EQ(learner.observe({nan, 0.0, 0.0}, {0.5, 0.0, 0.0}, Eigen::Matrix3d::Identity()), 0.0);
  EXPECT_EQ(learner.stats().increments, 0u);
  EXPECT_EQ(learner.model().x_per_m, paper_prior().x_per_m);
}

}  // namespace
}  // namespace lmf
