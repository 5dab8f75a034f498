// The front end's pipeline (front_end.hpp): motion prior, registration against
// the local submap, the motion handed on, learning, the submap going on.
#include "lmf/front_end/front_end.hpp"

#include <algorithm>
#include <cmath>
#include <random>

#include <gtest/gtest.h>

#include "front_end/room_world.hpp"

namespace lmf {
namespace {

MotionPriorConfig config() {
  MotionPriorConfig c;
  c.odometry_prior = OdometryErrorModel::proportional(0.08, 0.08, 0.01, 0.001, 0.0005);
  return c;
}

LaserScan scan_at(const Pose2& truth, const Pose2& odometry, int64_t utime) {
  LaserScan scan = testing::make_scan(testing::room_with_pillar(), truth, 361);
  scan.odometry = odometry;
  scan.utime = utime;
  return scan;
}

TEST(FrontEnd, TheFirstScanHasNoMotionAndNothingToRegisterAgainst) {
  FrontEnd front_end({config()});
  const RegisteredScan first = front_end.register_scan(scan_at(Pose2(), Pose2(), 0));
  EXPECT_FALSE(first.motion.has_value());
  EXPECT_FALSE(first.registration_tried);
  EXPECT_EQ(front_end.local_submap().size(), 1U);
}

TEST(FrontEnd, TheRegisteredMotionCorrectsTheOdometryAndTeachesTheModel) {
  FrontEnd front_end({config()});
  front_end.register_scan(scan_at(Pose2(), Pose2(), 0));
  // The odometry says 0.55 m and 0.1 rad; the robot went 0.5 m and 0.08 rad.
  const Pose2 truth(0.5, 0.0, 0.08);
  const RegisteredScan second = front_end.register_scan(scan_at(truth, Pose2(0.55, 0.0, 0.1), 100000));
  ASSERT_TRUE(second.registration.has_value());
  ASSERT_TRUE(second.motion.has_value());
  // Within 3 σ of its own covariance on each axis, and far closer than the odometry.
  const Eigen::Matrix3d& Q = second.motion->Q;
  EXPECT_TRUE(Q.isApprox(second.registration->covariance));
  EXPECT_NEAR(second.motion->u.x, truth.x, 3.0 * std::sqrt(Q(0, 0)));
  EXPECT_NEAR(second.motion->u.y, truth.y, 3.0 * std::sqrt(Q(1, 1)));
  EXPECT_NEAR(second.motion->u.phi, truth.phi, 3.0 * std::sqrt(Q(2, 2)));
  EXPECT_LT(std::abs(second.motion->u.phi - truth.phi), 0.2 * 0.02);
  EXPECT_GT(second.odometry_learning_weight, 0.0);
  EXPECT_EQ(front_end.motion_prior().odometry_learning_stats().increments, 1U);
  EXPECT_EQ(front_end.local_submap().size(), 2U);
}

TEST(FrontEnd, AFailedRegistrationHandsOnThePriorAndRestartsTheSubmap) {
  FrontEnd front_end({config()});
  front_end.register_scan(scan_at(Pose2(), Pose2(), 0));
  front_end.register_scan(scan_at(Pose2(0.3, 0.0, 0.0), Pose2(0.3, 0.0, 0.0), 100000));
  ASSERT_EQ(front_end.local_submap().size(), 2U);
  // A scan that sees nothing: the motion is the corrected odometry, its
  // covariance the model's raised to the search window's σ (window / 3) per axis.
  LaserScan blind = scan_at(Pose2(0.6, 0.0, 0.0), Pose2(0.6, 0.0, 0.0), 200000);
  for (double& r : blind.ranges_m) r = blind.max_range_m;
  const Pose2 u(0.3, 0.0, 0.0);
  const RegisteredScan step = front_end.register_scan(blind);
  EXPECT_TRUE(step.registration_tried);
  EXPECT_FALSE(step.registration.has_value());
  ASSERT_TRUE(step.motion.has_value());
  const OdometryErrorModel& model = front_end.odometry_model();
  EXPECT_NEAR(step.motion->u.x, model.corrected(u).x, 1e-12);
  const Eigen::Matrix3d Q = model.covariance(u);
  const ScanMatcherConfig& window = config().scan_matching;
  EXPECT_DOUBLE_EQ(step.motion->Q(0, 0), std::max(Q(0, 0), std::pow(window.search_window_m / 3.0, 2)));
  EXPECT_DOUBLE_EQ(step.motion->Q(1, 1), std::max(Q(1, 1), std::pow(window.search_window_m / 3.0, 2)));
  EXPECT_DOUBLE_EQ(step.motion->Q(2, 2), std::max(Q(2, 2), std::pow(window.search_window_rad / 3.0, 2)));
  EXPECT_GT(step.motion->Q(2, 2), Q(2, 2));  // the model alone claimed more than it could show
  EXPECT_EQ(step.odometry_learning_weight, 0.0);
  EXPECT_EQ(front_end.local_submap().size(), 1U);
}

TEST(FrontEnd, WithoutOdometryTheMotionIsPredictedAtConstantVelocity) {
  MotionPriorConfig c = config();
  c.scans_have_odometry = false;
  FrontEnd front_end({c});
  // The odometry field is ignored: it stays zero while the robot moves 0.2 m per 0.1 s.
  front_end.register_scan(scan_at(Pose2(), Pose2(), 0));
  const RegisteredScan second = front_end.register_scan(scan_at(Pose2(0.2, 0.0, 0.0), Pose2(), 100000));
  ASSERT_TRUE(second.registration.has_value());
  EXPECT_NEAR(second.motion->u.x, 0.2, 0.01);
  EXPECT_EQ(second.odometry_learning_weight, 0.0);  // no odometry model to teach
  // The next prediction goes on at that velocity.
  const std::optional<MotionPrior::Prediction> next = front_end.motion_prior().predict(200000, Pose2());
  ASSERT_TRUE(next.has_value());
  EXPECT_NEAR(next->motion.u.x, second.motion->u.x, 1e-12);
}

TEST(FrontEnd, AResumedChainPredictsFromTheGivenReadingWithoutRegistering) {
  FrontEnd front_end({config()});
  front_end.register_scan(scan_at(Pose2(), Pose2(), 0));
  front_end.resume(500000, Pose2(1.0, 0.0, 0.0));
  EXPECT_TRUE(front_end.local_submap().empty());
  const RegisteredScan step = front_end.register_scan(scan_at(Pose2(1.4, 0.0, 0.0), Pose2(1.4, 0.0, 0.0), 600000));
  EXPECT_FALSE(step.registration_tried);
  ASSERT_TRUE(step.motion.has_value());
  EXPECT_NEAR(step.motion->u.x, 0.4, 1e-9);
}

// Stage 0: a scan short of a keyframe (0.2 m, 0.1 rad) from the last scan
// taken by more than half its step is not a new view; the next one spans it.
// Without odometry nothing is known of the motion before the registration, so
// every scan is taken.
TEST(FrontEnd, AScanThatIsNoNewViewIsSkippedAndTheNextOneSpansIt) {
  FrontEnd front_end({config()});
  front_end.register_scan(scan_at(Pose2(), Pose2(), 0));
  const RegisteredScan near = front_end.register_scan(scan_at(Pose2(0.1, 0.0, 0.05), Pose2(0.1, 0.0, 0.05), 100000));
  EXPECT_TRUE(near.skipped);
  EXPECT_FALSE(near.registration_tried);
  ASSERT_TRUE(near.motion.has_value());
  EXPECT_NEAR(near.motion->u.x, front_end.odometry_model().corrected(Pose2(0.1, 0.0, 0.05)).x, 1e-12);
  EXPECT_EQ(front_end.local_submap().size(), 1U);
  EXPECT_EQ(front_end.motion_prior().odometry_learning_stats().increments, 0U);
  const RegisteredScan far = front_end.register_scan(scan_at(Pose2(0.25, 0.0, 0.05), Pose2(0.25, 0.0, 0.05), 200000));
  EXPECT_FALSE(far.skipped);
  ASSERT_TRUE(far.registration.has_value());
  EXPECT_NEAR(far.motion->u.x, 0.25, 0.02);  // from the first scan
  EXPECT_EQ(front_end.local_submap().size(), 2U);
  // A turn of a keyframe's angle is a new view too.
  const RegisteredScan turned = front_end.register_scan(scan_at(Pose2(0.25, 0.0, 0.16), Pose2(0.25, 0.0, 0.16), 300000));
  EXPECT_FALSE(turned.skipped);
  // Steps of 0.15 m: 0.15 is nearer the keyframe than 0.3 would be, so each is taken.
  EXPECT_FALSE(front_end.register_scan(scan_at(Pose2(0.4, 0.0, 0.16), Pose2(0.4, 0.0, 0.16), 400000)).skipped);
  EXPECT_FALSE(front_end.register_scan(scan_at(Pose2(0.55, 0.0, 0.16), Pose2(0.55, 0.0, 0.16), 500000)).skipped);

  FrontEndConfig unfiltered{config()};
  unfiltered.motion_filter = false;
  FrontEnd every_scan(unfiltered);
  every_scan.register_scan(scan_at(Pose2(), Pose2(), 0));
  EXPECT_FALSE(every_scan.register_scan(scan_at(Pose2(0.1, 0.0, 0.0), Pose2(0.1, 0.0, 0.0), 100000)).skipped);

  MotionPriorConfig without_odometry = config();
  without_odometry.scans_have_odometry = false;
  FrontEnd laser_alone({without_odometry});
  laser_alone.register_scan(scan_at(Pose2(), Pose2(), 0));
  const RegisteredScan second = laser_alone.register_scan(scan_at(Pose2(0.05, 0.0, 0.0), Pose2(), 100000));
  EXPECT_FALSE(second.skipped);
  EXPECT_TRUE(second.registration_tried);
}

TEST(FrontEnd, TheOdometryStepIsThePriorAlone) {
  FrontEnd front_end({config()});
  EXPECT_FALSE(front_end.odometry_step(0, Pose2()).has_value());
  const std::optional<MotionIncrement> m = front_end.odometry_step(100000, Pose2(0.5, 0.1, 0.2));
  ASSERT_TRUE(m.has_value());
  const Pose2 u(0.5, 0.1, 0.2);
  EXPECT_NEAR(m->u.phi, front_end.odometry_model().corrected(u).phi, 1e-12);
  EXPECT_TRUE(m->Q.isApprox(front_end.odometry_model().covariance(u)));
  EXPECT_TRUE(front_end.local_submap().empty());  // no points: nothing to match later scans against
}

}  // namespace
}  // namespace lmf
