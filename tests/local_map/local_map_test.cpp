// The local map's steps on constructed cases (docs/design.md §4): pairing, the other
// face, fusion, perpendicular constraints, the frame shift, prediction, the ship
// policy and snapshot/reset.
#include "lmf/front_end/constant_velocity_prior.hpp"
#include "lmf/local_map/local_map.hpp"

#include <cmath>
#include <numbers>
#include <optional>
#include <random>
#include <stdexcept>
#include <string>
#include <vector>

#include <gtest/gtest.h>

#include "lmf/local_map/local_map_measurements.hpp"
#include "lmf/spmap/covariance_check.hpp"
#include "lmf/spmap/segment_ops.hpp"
#include "scan/synthetic_scan.hpp"
#include "test_support.hpp"
#include "wall_observation.hpp"

namespace lmf {
namespace {

using spmap::EntityId;
using testing::matrices_near;
using testing::observe_wall;
using testing::perturbed;

constexpr double kPi = std::numbers::pi;
constexpr int64_t kScanPeriodUs = 200000;

// The lateral error of the physical point at x = a of a segment's frame and its
// angular error are (1, a; 0, 1) p: used to compare covariances across frame shifts.
Eigen::Matrix2d point_map(double a) {
  Eigen::Matrix2d T;
  T << 1.0, a, 0.0, 1.0;
  return T;
}

TEST(LocalMapConfig, DefaultsAreValidAndBadFieldsAreNamed) {
  EXPECT_NO_THROW(LocalMapConfig{}.validate());
  const auto message_of = [](const LocalMapConfig& c) {
    try {
      c.validate();
    } catch (const std::invalid_argument& e) {
      return std::string(e.what());
    }
    return std::string("no exception");
  };
  LocalMapConfig c;
  c.pairing_alpha = 1.5;
  EXPECT_NE(message_of(c).find("pairing_alpha"), std::string::npos);
  c = {};
  c.odom_translation_noise_ratio = -0.1;
  EXPECT_NE(message_of(c).find("odom_translation_noise_ratio"), std::string::npos);
  c = {};
  c.ship_distance_m = 0.0;
  EXPECT_NE(message_of(c).find("ship_distance_m"), std::string::npos);
  c = {};
  c.max_segments = 0;
  EXPECT_NE(message_of(c).find("max_segments"), std::string::npos);
  c = {};
  c.constraint_max_angle_rad = 1.0;
  EXPECT_NE(message_of(c).find("constraint_max_angle_rad"), std::string::npos);
  c = {};
  c.extraction.min_points = 1;
  EXPECT_NE(message_of(c).find("min_points"), std::string::npos);
  c = {};
  c.overlap_gap_tolerance_m = std::nan("");
  EXPECT_THROW(LocalMap{c}, std::invalid_argument);
}

TEST(LocalMapPrediction, CovarianceGrowsWithMotion) {
  LocalMap small;
  LocalMap large;
  small.predict(Pose2(0.5, 0.0, 0.1));
  large.predict(Pose2(1.0, 0.0, 0.2));
  EXPECT_TRUE(is_near(small.x_LR(), Pose2(0.5, 0.0, 0.1), 1e-12, 1e-12));
  EXPECT_GT(small.robot_covariance().trace(), 0.0);
  EXPECT_GT(large.robot_covariance().trace(), small.robot_covariance().trace());
  // Every further step adds noise: P_RR grows (in the PSD order).
  Eigen::Matrix3d before = small.robot_covariance();
  for (int k = 0; k < 5; ++k) {
    small.predict(Pose2(0.5, 0.02, 0.05));
    const Eigen::Matrix3d after = small.robot_covariance();
    EXPECT_GT(after.trace(), before.trace());
    EXPECT_TRUE(spmap::check_covariance(after).ok());
    before = after;
  }
  EXPECT_NEAR(small.span_m(), 0.5 + 5.0 * std::hypot(0.5, 0.02), 1e-12);
}

TEST(LocalMapPrediction, TransformsTheCrossCovariances) {
  LocalMap lm;
  lm.predict(Pose2(1.0, 0.0, 0.3));
  const ObservedSegment e = observe_wall(lm.x_LR(), {0.0, 2.0}, {3.0, 2.0});
  lm.update(0, Pose2(), {e});  // first call: sets the odometry reference only
  ASSERT_EQ(lm.num_segments(), 1u);
  const EntityId s = lm.segment_ids().front();
  const Eigen::MatrixXd P_RS = lm.map().block(lm.robot(), s);
  ASSERT_GT(P_RS.norm(), 0.0);

  const Pose2 u(0.5, 0.1, -0.2);
  const local_map::PredictionJacobians pj = local_map::prediction_jacobians(lm.x_LR(), u);
  const Eigen::Matrix3d P_RR = lm.robot_covariance();
  const Eigen::Matrix3d Q = local_map::odometry_noise(u, lm.config());
  lm.update(kScanPeriodUs, u, {});
  EXPECT_TRUE(matrices_near(lm.map().block(lm.robot(), s), pj.J_R * P_RS, 1e-12));
  EXPECT_TRUE(matrices_near(lm.robot_covariance(), pj.J_R * P_RR * pj.J_R.transpose() +
                                                       pj.J_u * Q * pj.J_u.transpose(),
                            1e-12));
}

TEST(LocalMapPairing, WallSeenTwiceIsPairedAndTheMapDoesNotGrow) {
  LocalMap lm;
  const ScanReport r1 = lm.update(0, Pose2(), {observe_wall(Pose2(), {-1.0, 2.0}, {3.0, 2.0})});
  EXPECT_EQ(r1.segments_added, 1);
  EXPECT_EQ(r1.map_segments, 1);
  ASSERT_TRUE(r1.covariance_health.ok());

  const Pose2 x_LR_true(0.5, 0.0, 0.0);
  const ObservedSegment e = perturbed(observe_wall(x_LR_true, {-0.5, 2.0}, {4.0, 2.0}), 0.004, 0.002);
  const ScanReport r2 = lm.update(kScanPeriodUs, x_LR_true, {e});
  EXPECT_EQ(r2.pairings_tried, 1);
  EXPECT_EQ(r2.pairings_accepted_individual, 1);
  EXPECT_EQ(r2.pairings_accepted_joint, 1);
  EXPECT_EQ(r2.update_rows, 2);
  EXPECT_EQ(r2.segments_added, 0);
  EXPECT_EQ(r2.segments_extended, 1);
  EXPECT_EQ(r2.map_segments, 1);
  EXPECT_TRUE(r2.covariance_health.ok()) << r2.covariance_health.describe();
  // The segment now covers both views, [-1, 4] along the wall.
  const spmap::Entity& s = lm.map().entity(lm.segment_ids().front());
  EXPECT_NEAR(s.length_m, 5.0, 0.05);
  EXPECT_NEAR(s.location.transform_point({0.0, 0.0}).x(), 1.5, 0.05);
  EXPECT_NEAR(s.location.y, 2.0, 0.02);
  // The pairing corrected the robot towards the truth and shrank its covariance.
  EXPECT_LT(lm.robot_covariance()(1, 1), local_map::odometry_noise(x_LR_true, lm.config())(1, 1));
}

TEST(LocalMapPairing, WallSeenFromTheOtherFaceIsNotPaired) {
  LocalMap lm;
  lm.update(0, Pose2(), {observe_wall(Pose2(), {-2.0, 2.0}, {6.0, 2.0})});
  ASSERT_EQ(lm.num_segments(), 1u);
  // The robot is now on the other side of the (thin) wall: the same line, the other face.
  const Pose2 x_LR_true(0.5, 4.0, 0.0);
  const ObservedSegment e = observe_wall(x_LR_true, {-2.0, 2.0}, {6.0, 2.0});
  const ScanReport r = lm.update(kScanPeriodUs, x_LR_true, {e});
  EXPECT_EQ(r.pairings_tried, 1);
  EXPECT_EQ(r.pairings_rejected_overlap, 0);  // they overlap: the Mahalanobis test must reject
  EXPECT_EQ(r.pairings_rejected_individual, 1);
  EXPECT_EQ(r.pairings_accepted_individual, 0);
  EXPECT_EQ(r.segments_added, 1);
  EXPECT_EQ(r.map_segments, 2);
  // The two faces point opposite ways (anti-parallel: the constraint step may tie them).
  const std::vector<EntityId> ids = lm.segment_ids();
  EXPECT_NEAR(std::abs(wrap_angle(lm.map().entity(ids[0]).location.phi - lm.map().entity(ids[1]).location.phi)),
              kPi, 0.1);
}

TEST(LocalMapPairing, FarAwayCollinearObservationFailsTheOverlapTest) {
  LocalMap lm;
  lm.add_segment_for_test(Pose2(1.0, 2.0, kPi), 2.0, Eigen::Vector2d(1e-4, 1e-5).asDiagonal());
  // Same line, 3 m beyond the end of the map segment.
  const ScanReport r = lm.update(0, Pose2(), {observe_wall(Pose2(), {5.0, 2.0}, {7.0, 2.0})});
  EXPECT_EQ(r.pairings_rejected_overlap, 1);
  EXPECT_EQ(r.segments_added, 1);
  EXPECT_EQ(r.map_segments, 2);
}

// A turn on the spot with a 2.5-sigma heading error: every right pairing is off
// by the same rotation, while a spurious map segment D sits exactly where wall A
// appears from the predicted pose. Greedy JC takes D first and rejects the rest;
// the restarts find the larger set {A, B, C} and correct the heading.
TEST(LocalMapJointCompatibility, RestartsRecoverFromAnEarlySpuriousPairing) {
  const Pose2 predicted(0.0, 0.0, 1.0);
  const Pose2 truth(0.0, 0.0, 1.2);
  const Eigen::Matrix2d known = Eigen::Vector2d(1e-4, 1e-5).asDiagonal();
  const std::vector<std::pair<Eigen::Vector2d, Eigen::Vector2d>> walls = {
      {{-3.0, 3.0}, {3.0, 3.0}}, {{3.0, -3.0}, {3.0, 3.0}}, {{-3.0, -3.0}, {3.0, -3.0}}};
  for (const std::size_t restarts : {std::size_t{0}, std::size_t{3}}) {
    LocalMapConfig config;
    config.joint_compatibility_restarts = restarts;
    config.constraints_enabled = false;
    LocalMap lm(config);
    lm.predict(predicted);  // sigma_phi = 8 % of 1 rad
    std::vector<ObservedSegment> scan;
    for (const auto& [a, b] : walls) {
      const ObservedSegment e = observe_wall(truth, a, b);
      lm.add_segment_for_test(compose(truth, e.location), e.length_m, known);  // the true wall, well known
      scan.push_back(e);
    }
    // D: where wall A's observation lands when placed with the predicted pose.
    lm.add_segment_for_test(compose(predicted, scan[0].location), scan[0].length_m, known);
    const ScanReport r = lm.update(0, Pose2(), scan);
    EXPECT_EQ(r.pairings_accepted_individual, 4) << restarts;
    if (restarts == 0) {
      EXPECT_EQ(r.pairings_accepted_joint, 1);
      EXPECT_EQ(r.joint_compatibility_restarts, 0);
      EXPECT_NEAR(lm.x_LR().phi, predicted.phi, 0.02);
    } else {
      EXPECT_EQ(r.pairings_accepted_joint, 3);
      EXPECT_GE(r.joint_compatibility_restarts, 1);
      EXPECT_NEAR(lm.x_LR().phi, truth.phi, 0.02);
    }
  }
}

TEST(LocalMapFusion, CollinearSegmentsJoinedByOneObservationAreFused) {
  LocalMap lm;
  const Eigen::Matrix2d cov = Eigen::Vector2d(0.02 * 0.02, 0.01 * 0.01).asDiagonal();
  // Two pieces of one wall at y = 2 (seen from below: direction -x), 1 m apart.
  const EntityId first = lm.add_segment_for_test(Pose2(1.0, 2.01, kPi), 2.0, cov);
  const EntityId second = lm.add_segment_for_test(Pose2(4.0, 1.99, kPi - 0.005), 2.0, cov);
  const ScanReport r = lm.update(0, Pose2(), {observe_wall(Pose2(), {-0.5, 2.0}, {5.5, 2.0})});
  EXPECT_EQ(r.pairings_accepted_individual, 2);
  EXPECT_EQ(r.pairings_accepted_joint, 2);
  EXPECT_EQ(r.segments_fused, 1);
  EXPECT_EQ(r.fusions_rejected, 0);
  EXPECT_EQ(r.segments_added, 0);
  ASSERT_EQ(r.map_segments, 1);
  EXPECT_TRUE(lm.map().contains(first));
  EXPECT_FALSE(lm.map().contains(second));
  const spmap::Entity& s = lm.map().entity(first);
  // One segment covering both pieces and the observation: x in [-0.5, 5.5].
  EXPECT_NEAR(s.length_m, 6.0, 0.02);
  EXPECT_NEAR(s.location.x, 2.5, 0.02);
  EXPECT_NEAR(s.location.y, 2.0, 0.01);
  EXPECT_TRUE(r.covariance_health.ok()) << r.covariance_health.describe();
  EXPECT_EQ(lm.snapshot().covariance.rows(), 5);
}

TEST(LocalMapConstraints, NearlyPerpendicularNewSegmentIsConstrained) {
  LocalMap lm;
  lm.update(0, Pose2(), {observe_wall(Pose2(), {-1.0, 2.0}, {3.0, 2.0})});
  ASSERT_EQ(lm.num_segments(), 1u);
  const EntityId wall = lm.segment_ids().front();

  const Pose2 x_LR_true(0.5, 0.0, 0.0);
  // The old wall again, and a new one at x = 4, fitted 0.6° off perpendicular.
  const ObservedSegment seen_again = observe_wall(x_LR_true, {-0.5, 2.0}, {3.5, 2.0});
  const ObservedSegment corner = perturbed(observe_wall(x_LR_true, {4.0, -1.0}, {4.0, 3.0}), 0.0, 0.01);
  const ScanReport r = lm.update(kScanPeriodUs, x_LR_true, {seen_again, corner});
  EXPECT_EQ(r.segments_added, 1);
  EXPECT_EQ(r.constraints_tried, 1);
  EXPECT_EQ(r.constraints_applied, 1);
  EXPECT_EQ(r.constraint_rows_dropped, 0);
  ASSERT_EQ(lm.num_segments(), 2u);
  const EntityId added = lm.segment_ids().back();

  // Exactly perpendicular now, and the relative angle is perfectly known.
  const double relative = wrap_angle(lm.map().entity(added).location.phi - lm.map().entity(wall).location.phi);
  EXPECT_NEAR(std::abs(relative), kPi / 2.0, 1e-9);
  const Eigen::MatrixXd& P = lm.map().covariance();
  const Eigen::Index ia = lm.map().entity(wall).offset + 1;
  const Eigen::Index ib = lm.map().entity(added).offset + 1;
  EXPECT_NEAR(P(ia, ia) + P(ib, ib) - 2.0 * P(ia, ib), 0.0, 1e-12 * P(ia, ia) + 1e-15);
  // P is singular now, but still symmetric PSD.
  EXPECT_TRUE(r.covariance_health.ok()) << r.covariance_health.describe();
  EXPECT_TRUE(spmap::check_covariance(P).ok());

  // A third wall parallel to the first: one constraint to the group, the row to
  // the other member would be redundant and is never built.
  const Pose2 x_LR_2(1.0, 0.0, 0.0);
  const ScanReport r3 = lm.update(2 * kScanPeriodUs, x_LR_2,
                                  {observe_wall(x_LR_2, {0.0, 2.0}, {3.5, 2.0}),
                                   perturbed(observe_wall(x_LR_2, {-1.0, -2.0}, {3.0, -2.0}), 0.0, -0.008)});
  EXPECT_EQ(r3.segments_added, 1);
  EXPECT_EQ(r3.constraints_tried, 1);
  EXPECT_EQ(r3.constraints_applied, 1);
  const EntityId third = lm.segment_ids().back();
  EXPECT_NEAR(std::abs(wrap_angle(lm.map().entity(third).location.phi - lm.map().entity(wall).location.phi)), kPi,
              1e-9);
  EXPECT_NEAR(std::abs(wrap_angle(lm.map().entity(third).location.phi - lm.map().entity(added).location.phi)),
              kPi / 2.0, 1e-9);
  EXPECT_TRUE(r3.covariance_health.ok()) << r3.covariance_health.describe();
}

TEST(LocalMapConstraints, TwoNewSegmentsOfOneScanAreConstrainedToEachOther) {
  LocalMap lm;
  const ScanReport r = lm.update(0, Pose2(), {observe_wall(Pose2(), {-1.0, 2.0}, {3.0, 2.0}),
                                              perturbed(observe_wall(Pose2(), {4.0, -1.0}, {4.0, 3.0}), 0.0, 0.005)});
  EXPECT_EQ(r.segments_added, 2);
  EXPECT_EQ(r.constraints_applied, 1);
  const std::vector<EntityId> ids = lm.segment_ids();
  EXPECT_NEAR(std::abs(wrap_angle(lm.map().entity(ids[1]).location.phi - lm.map().entity(ids[0]).location.phi)),
              kPi / 2.0, 1e-9);
}

TEST(LocalMapConstraints, SwitchOffAndMahalanobisGate) {
  LocalMapConfig config;
  config.constraints_enabled = false;
  LocalMap off(config);
  const std::vector<ObservedSegment> scan = {observe_wall(Pose2(), {-1.0, 2.0}, {3.0, 2.0}),
                                             perturbed(observe_wall(Pose2(), {4.0, -1.0}, {4.0, 3.0}), 0.0, 0.01)};
  const ScanReport r = off.update(0, Pose2(), scan);
  EXPECT_EQ(r.constraints_tried, 0);
  EXPECT_EQ(r.constraints_applied, 0);
  const std::vector<EntityId> ids = off.segment_ids();
  EXPECT_GT(std::abs(std::abs(wrap_angle(off.map().entity(ids[1]).location.phi -
                                         off.map().entity(ids[0]).location.phi)) -
                     kPi / 2.0),
            0.005);

  // 0.1 rad off perpendicular with 0.005 rad angular noise: within the angle
  // window but far outside the chi2(1) gate.
  LocalMap on;
  const ScanReport r2 =
      on.update(0, Pose2(), {observe_wall(Pose2(), {-1.0, 2.0}, {3.0, 2.0}),
                             perturbed(observe_wall(Pose2(), {4.0, -1.0}, {4.0, 3.0}), 0.0, 0.1)});
  EXPECT_EQ(r2.constraints_tried, 1);
  EXPECT_EQ(r2.constraints_rejected_individual, 1);
  EXPECT_EQ(r2.constraints_applied, 0);
}

TEST(LocalMapGeometricUpdate, FrameShiftKeepsTheCovarianceMeaning) {
  // A segment correlated with the robot, as the local map builds them.
  LocalMap lm;
  lm.predict(Pose2(1.0, 0.2, 0.3));
  lm.update(0, Pose2(), {observe_wall(lm.x_LR(), {0.0, 3.0}, {2.0, 3.0})});
  const EntityId s = lm.segment_ids().front();
  spmap::StochasticMap map = lm.map();
  const double old_length = map.entity(s).length_m;
  const Pose2 old_location = map.entity(s).location;
  const Eigen::MatrixXd P_SS = map.block(s, s);
  const Eigen::MatrixXd P_SR = map.block(s, lm.robot());

  // Grow the segment by 1.5 m at its +x end: its frame moves by dx = 0.75 m.
  spmap::extend_segment(map, s, {-0.5 * old_length, 0.5 * old_length + 1.5});
  const double dx = 0.75;
  EXPECT_NEAR(map.entity(s).length_m, old_length + 1.5, 1e-12);
  EXPECT_TRUE(is_near(map.entity(s).location, compose(old_location, Pose2(dx, 0.0, 0.0)), 1e-12, 1e-12));
  // The error of the same physical points (x = a in the old frame, a - dx in
  // the new one) keeps its covariance and its correlation with the robot.
  for (double a : {-1.0, 0.0, 0.4, 2.0}) {
    const Eigen::Matrix2d T_old = point_map(a);
    const Eigen::Matrix2d T_new = point_map(a - dx);
    EXPECT_TRUE(matrices_near(T_new * map.block(s, s) * T_new.transpose(), T_old * P_SS * T_old.transpose(), 1e-12));
    EXPECT_TRUE(matrices_near(T_new * map.block(s, lm.robot()), T_old * P_SR, 1e-12));
  }
}

TEST(LocalMapShipPolicy, ShipsOnDistanceAndOnSize) {
  LocalMapConfig config;
  config.ship_distance_m = 2.0;
  config.max_segments = 2;
  LocalMap lm(config);
  for (int k = 0; k <= 4; ++k) {
    EXPECT_FALSE(lm.should_ship()) << k;
    lm.update(k * kScanPeriodUs, Pose2(0.5 * k, 0.0, 0.0), {});
  }
  EXPECT_NEAR(lm.span_m(), 2.0, 1e-12);
  EXPECT_FALSE(lm.should_ship());  // "more than" 2 m
  const ScanReport r = lm.update(5 * kScanPeriodUs, Pose2(2.5, 0.0, 0.0), {});
  EXPECT_TRUE(r.should_ship);
  EXPECT_TRUE(lm.should_ship());

  LocalMap crowded(config);
  crowded.update(0, Pose2(), {observe_wall(Pose2(), {-1.0, 2.0}, {3.0, 2.0}),
                              observe_wall(Pose2(), {-1.0, -2.0}, {3.0, -2.0})});
  EXPECT_FALSE(crowded.should_ship());
  crowded.update(kScanPeriodUs, Pose2(), {observe_wall(Pose2(), {6.0, 1.0}, {8.0, 4.0})});
  EXPECT_EQ(crowded.num_segments(), 3u);
  EXPECT_TRUE(crowded.should_ship());
}

TEST(LocalMapSnapshot, SnapshotAndResetRoundTrip) {
  LocalMap lm(LocalMapConfig{}, 7);
  std::vector<Pose2> odometry = {{0.0, 0.0, 0.0}, {0.5, 0.0, 0.02}, {1.0, 0.05, 0.03}};
  for (std::size_t k = 0; k < odometry.size(); ++k) {
    const Pose2& x = odometry[k];
    lm.update(1000 + static_cast<int64_t>(k) * kScanPeriodUs, x,
              {observe_wall(x, {-1.0, 2.0}, {4.0, 2.0}), observe_wall(x, {4.0, -1.0}, {4.0, 3.0})});
  }
  const LocalMapSnapshot snap = lm.snapshot();
  EXPECT_EQ(snap.robot_id, 7);
  EXPECT_EQ(snap.seq, 0);
  EXPECT_EQ(snap.first_utime, 1000);
  EXPECT_EQ(snap.last_utime, 1000 + 2 * kScanPeriodUs);
  EXPECT_TRUE(is_near(snap.x_LR, lm.x_LR(), 0.0, 0.0));
  ASSERT_EQ(snap.segments.size(), lm.num_segments());
  ASSERT_EQ(snap.covariance.rows(), static_cast<Eigen::Index>(3 + 2 * snap.segments.size()));
  // Robot first, then the segments in state order: the map's P (robot added first).
  EXPECT_TRUE(matrices_near(snap.covariance, lm.map().covariance(), 0.0));
  EXPECT_TRUE(matrices_near(snap.covariance.topLeftCorner(3, 3), lm.robot_covariance(), 0.0));
  const std::vector<EntityId> ids = lm.segment_ids();
  for (std::size_t i = 0; i < ids.size(); ++i) {
    EXPECT_TRUE(is_near(snap.segments[i].location, lm.map().entity(ids[i]).location, 0.0, 0.0));
    EXPECT_EQ(snap.segments[i].length_m, lm.map().entity(ids[i]).length_m);
  }
  ASSERT_EQ(snap.scan_poses.size(), 3u);
  EXPECT_EQ(snap.scan_poses.back().utime, snap.last_utime);
  EXPECT_TRUE(is_near(snap.scan_poses.back().x_LR, snap.x_LR, 0.0, 0.0));
  EXPECT_TRUE(spmap::check_covariance(snap.covariance).ok());

  lm.reset();
  EXPECT_EQ(lm.seq(), 1);
  EXPECT_EQ(lm.num_segments(), 0u);
  EXPECT_TRUE(is_near(lm.x_LR(), Pose2(), 0.0, 0.0));
  EXPECT_TRUE(matrices_near(lm.robot_covariance(), Eigen::Matrix3d::Zero(), 0.0));
  EXPECT_EQ(lm.span_m(), 0.0);
  EXPECT_FALSE(lm.should_ship());
  const LocalMapSnapshot empty = lm.snapshot();
  EXPECT_EQ(empty.seq, 1);
  EXPECT_EQ(empty.first_utime, snap.last_utime);  // L is the robot's pose at that scan
  EXPECT_TRUE(empty.segments.empty());
  EXPECT_TRUE(empty.scan_poses.empty());
  EXPECT_EQ(empty.covariance.rows(), 3);

  // The odometry reference survives the reset: the next scan predicts with the
  // motion since the last scan of the previous map.
  const Pose2 next(1.6, 0.1, 0.1);
  lm.update(1000 + 3 * kScanPeriodUs, next, {});
  EXPECT_TRUE(is_near(lm.x_LR(), between(odometry.back(), next), 1e-12, 1e-12));
  EXPECT_GT(lm.robot_covariance().trace(), 0.0);
}

// A restarted agent continues its chain of local maps in a fresh LocalMap:
// resume() must leave exactly the state reset() leaves after the origin scan,
// so the next scan predicts with the odometry since that scan.
TEST(LocalMapSnapshot, ResumeContinuesTheChainFromTheOriginOdometry) {
  const std::vector<Pose2> odometry = {{0.0, 0.0, 0.0}, {0.5, 0.0, 0.02}, {1.0, 0.05, 0.03}};
  const auto walls = [](const Pose2& x) {
    return std::vector<ObservedSegment>{observe_wall(x, {-1.0, 2.0}, {4.0, 2.0}),
                                        observe_wall(x, {4.0, -1.0}, {4.0, 3.0})};
  };
  LocalMap uninterrupted(LocalMapConfig{}, 7);
  for (std::size_t k = 0; k < odometry.size(); ++k) {
    uninterrupted.update(1000 + static_cast<int64_t>(k) * kScanPeriodUs, odometry[k], walls(odometry[k]));
  }
  const int64_t origin_utime = 1000 + 2 * kScanPeriodUs;
  uninterrupted.reset();  // map 1 starts at the robot's pose at the last scan

  LocalMap resumed(LocalMapConfig{}, 7);
  resumed.resume(1, origin_utime, odometry.back());
  EXPECT_EQ(resumed.seq(), 1);
  EXPECT_EQ(resumed.num_segments(), 0u);
  EXPECT_TRUE(is_near(resumed.x_LR(), Pose2(), 0.0, 0.0));
  EXPECT_TRUE(matrices_near(resumed.robot_covariance(), Eigen::Matrix3d::Zero(), 0.0));
  EXPECT_EQ(resumed.snapshot().first_utime, origin_utime);

  // The next scan (some scans later: the motion in between is one odometry step).
  const Pose2 later(2.4, 0.3, 0.25);
  const int64_t later_utime = 1000 + 9 * kScanPeriodUs;
  uninterrupted.update(later_utime, later, walls(later));
  resumed.update(later_utime, later, walls(later));
  const LocalMapSnapshot a = uninterrupted.snapshot();
  const LocalMapSnapshot b = resumed.snapshot();
  EXPECT_EQ(b.seq, a.seq);
  EXPECT_EQ(b.first_utime, a.first_utime);
  EXPECT_EQ(b.last_utime, later_utime);
  EXPECT_TRUE(is_near(b.x_LR, a.x_LR, 0.0, 0.0));
  ASSERT_EQ(b.segments.size(), a.segments.size());
  EXPECT_TRUE(matrices_near(b.covariance, a.covariance, 0.0));
  EXPECT_EQ(resumed.span_m(), uninterrupted.span_m());

  // Without observations the robot sits at the odometric displacement with the
  // odometry noise model's covariance J_u Q J_uᵀ (step 1 from pose 0, covariance 0).
  LocalMap bridged(LocalMapConfig{}, 7);
  bridged.resume(4, origin_utime, odometry.back());
  bridged.update(later_utime, later, {});
  const Pose2 u = between(odometry.back(), later);
  const local_map::PredictionJacobians pj = local_map::prediction_jacobians(Pose2(), u);
  const Eigen::Matrix3d expected = pj.J_u * local_map::odometry_noise(u, LocalMapConfig{}) * pj.J_u.transpose();
  EXPECT_EQ(bridged.seq(), 4);
  EXPECT_TRUE(is_near(bridged.x_LR(), u, 1e-12, 1e-12));
  EXPECT_TRUE(matrices_near(bridged.robot_covariance(), expected, 1e-15));
  EXPECT_GT(bridged.robot_covariance().trace(), 0.0);
  bridged.reset();
  EXPECT_EQ(bridged.seq(), 5);
  EXPECT_EQ(bridged.snapshot().first_utime, later_utime);

  // Map 0 resumed from the first scan's reading: its origin stays that scan's pose.
  LocalMap first;
  first.resume(0, 1000, odometry.front());
  first.update(1000 + kScanPeriodUs, odometry[1], {});
  EXPECT_EQ(first.seq(), 0);
  EXPECT_TRUE(is_near(first.x_LR(), between(odometry.front(), odometry[1]), 1e-12, 1e-12));
  EXPECT_EQ(first.snapshot().first_utime, 1000);

  // Bad input: state unchanged.
  EXPECT_THROW(first.resume(-1, 0, Pose2()), std::invalid_argument);
  EXPECT_THROW(first.resume(3, 0, Pose2(0.0, std::nan(""), 0.0)), std::invalid_argument);
  EXPECT_EQ(first.seq(), 0);
  EXPECT_TRUE(is_near(first.x_LR(), between(odometry.front(), odometry[1]), 1e-12, 1e-12));
}

TEST(LocalMapSupervision, CovarianceIsCheckedAtTheConfiguredInterval) {
  LocalMapConfig config;
  config.covariance_check_interval = 2;
  LocalMap lm(config);
  const ScanReport r1 = lm.update(0, Pose2(), {observe_wall(Pose2(), {-1.0, 2.0}, {3.0, 2.0})});
  EXPECT_FALSE(r1.covariance_checked);
  const ScanReport r2 = lm.update(kScanPeriodUs, Pose2(0.5, 0.0, 0.0), {});
  EXPECT_TRUE(r2.covariance_checked);
  EXPECT_TRUE(r2.covariance_health.ok());
  EXPECT_TRUE(r2.covariance_health.symmetric);
  EXPECT_TRUE(lm.check_covariance().ok());
  // The default checks one scan in covariance_check_interval, not every scan.
  const std::size_t interval = LocalMapConfig().covariance_check_interval;
  ASSERT_GT(interval, 1u);
  LocalMap by_default;
  std::size_t checked = 0;
  for (std::size_t k = 0; k < interval; ++k) {
    checked += by_default.update(static_cast<int64_t>(k) * kScanPeriodUs, Pose2(), {}).covariance_checked ? 1 : 0;
  }
  EXPECT_EQ(checked, 1u);
}

// Whatever the interval (here: never between ships), the scan that makes the
// map ship checks P, so an indefinite covariance is caught before it leaves.
TEST(LocalMapSupervision, ALossOfPositiveSemidefinitenessIsCaughtOnTheScanThatShips) {
  for (const std::size_t interval : {std::size_t{0}, std::size_t{1000}}) {
    LocalMapConfig config;
    config.covariance_check_interval = interval;
    config.ship_distance_m = 1.0;
    LocalMap lm(config);
    lm.update(0, Pose2(), {});
    // A segment far from the path whose covariance is indefinite (eigenvalues 1.01e-2 and -0.99e-2).
    Eigen::Matrix2d indefinite;
    indefinite << 1e-4, 1e-2, 1e-2, 1e-4;
    lm.add_segment_for_test(Pose2(0.0, 50.0, 0.0), 2.0, indefinite);
    ScanReport report;
    int scans = 1;
    for (; scans < 10 && !report.should_ship; ++scans) {
      report = lm.update(scans * kScanPeriodUs, Pose2(0.3 * scans, 0.0, 0.0), {});
      if (!report.should_ship) {
        EXPECT_FALSE(report.covariance_checked) << "interval " << interval;
      }
    }
    ASSERT_TRUE(report.should_ship) << "interval " << interval;
    EXPECT_TRUE(report.covariance_checked) << "interval " << interval;
    EXPECT_FALSE(report.covariance_health.ok()) << "interval " << interval;
    EXPECT_FALSE(report.covariance_health.positive_semidefinite) << "interval " << interval;
  }
}

TEST(LocalMapInput, MalformedObservationsAreSkippedAndBadOdometryThrows) {
  LocalMap lm;
  ObservedSegment nan_location = observe_wall(Pose2(), {-1.0, 2.0}, {3.0, 2.0});
  nan_location.location.x = std::nan("");
  ObservedSegment zero_length = observe_wall(Pose2(), {-1.0, -2.0}, {3.0, -2.0});
  zero_length.length_m = 0.0;
  ObservedSegment indefinite = observe_wall(Pose2(), {5.0, -1.0}, {5.0, 3.0});
  indefinite.covariance << 1e-4, 1e-2, 1e-2, 1e-4;
  const ScanReport r = lm.update(0, Pose2(), {nan_location, zero_length, indefinite,
                                              observe_wall(Pose2(), {-1.0, 3.0}, {3.0, 3.0})});
  EXPECT_EQ(r.observations, 4);
  EXPECT_EQ(r.observations_rejected, 3);
  EXPECT_EQ(r.segments_added, 1);

  const spmap::StochasticMap before = lm.map();
  EXPECT_THROW(lm.update(kScanPeriodUs, Pose2(std::nan(""), 0.0, 0.0), {}), std::invalid_argument);
  EXPECT_TRUE(matrices_near(lm.map().covariance(), before.covariance(), 0.0));
  EXPECT_EQ(lm.snapshot().scan_poses.size(), 1u);
}

// A robot driving down a corridor with exact odometry and noiseless walls: the
// map holds one segment per wall and the pose stays exact.
TEST(LocalMapScenario, CorridorWithExactDataStaysExact) {
  LocalMap lm;
  const std::vector<std::pair<Eigen::Vector2d, Eigen::Vector2d>> walls = {
      {{-2.0, 1.5}, {30.0, 1.5}}, {{-2.0, -1.5}, {30.0, -1.5}}, {{12.0, -1.5}, {12.0, 1.5}}};
  for (int k = 0; k < 20; ++k) {
    const Pose2 x(0.5 * k, 0.0, 0.0);
    std::vector<ObservedSegment> scan;
    for (int w = 0; w < 2; ++w) {
      const double y = walls[static_cast<std::size_t>(w)].first.y();
      scan.push_back(observe_wall(x, {x.x - 3.0, y}, {x.x + 3.0, y}));
    }
    scan.push_back(observe_wall(x, walls[2].first, walls[2].second));
    const ScanReport r = lm.update(k * kScanPeriodUs, x, scan);
    ASSERT_TRUE(r.covariance_health.ok()) << k << ": " << r.covariance_health.describe();
    ASSERT_EQ(r.observations_discarded, 0) << k;
  }
  EXPECT_EQ(lm.num_segments(), 3u);
  EXPECT_TRUE(is_near(lm.x_LR(), Pose2(9.5, 0.0, 0.0), 1e-6, 1e-8));
}

// Step 1 with scan matching (LocalMapConfig::scan_matching): the same scans
// and biased odometry (6 % long, 0.02 rad per step to the left) through a room,
// with and without it. The match runs from the second scan on and brings the
// pose estimate closer to the truth (the model noise keeps it conservative).
TEST(LocalMapScanMatching, PredictionWithTheMatchBeatsTheOdometry) {
  testing::SyntheticWorld room;
  room.walls = {{{-2.0, -4.0}, {12.0, -4.0}}, {{12.0, -4.0}, {12.0, 1.0}}, {{12.0, 1.0}, {7.0, 1.0}},
                {{7.0, 1.0}, {7.0, 5.0}},     {{7.0, 5.0}, {-2.0, 5.0}},  {{-2.0, 5.0}, {-2.0, -4.0}},
                {{3.0, 4.0}, {3.0, 5.0}}};
  room.discs = {{{5.0, -2.0}, 0.3}};
  std::mt19937 rng(3);
  std::vector<LaserScan> scans;
  std::vector<Pose2> truth;
  Pose2 odometry;
  for (int k = 0; k < 15; ++k) {
    const Pose2 x_WR(0.4 * k, 0.5 * std::sin(0.3 * k), 0.15 * std::cos(0.3 * k));
    if (k > 0) {
      const Pose2 u = between(truth.back(), x_WR);
      odometry = compose(odometry, Pose2(1.06 * u.x, 1.06 * u.y, u.phi + 0.02));
    }
    truth.push_back(x_WR);
    LaserScan scan = testing::make_scan(room, x_WR, 361, 80.0, 0.01, &rng);
    scan.utime = k * kScanPeriodUs;
    scan.odometry = odometry;
    scans.push_back(scan);
  }
  auto final_error = [&](bool matching, int* matched) {
    LocalMapConfig config;
    config.scan_matching.enabled = matching;
    LocalMap lm(config);
    *matched = 0;
    for (std::size_t k = 0; k < scans.size(); ++k) {
      const ScanReport r = lm.process_scan(scans[k]);
      EXPECT_EQ(r.scan_match_tried, matching && k > 0) << k;
      if (r.scan_matched) {
        ++*matched;
        EXPECT_GT(r.scan_match_points, 100) << k;
      }
      EXPECT_TRUE(lm.check_covariance().ok()) << k;
    }
    const Pose2 e = between(lm.x_LR(), between(truth.front(), truth.back()));
    return std::hypot(e.x, e.y) + 2.0 * std::abs(e.phi);  // m, and rad at 2 m
  };
  int matched_without = 0;
  int matched_with = 0;
  const double without = final_error(false, &matched_without);
  const double with = final_error(true, &matched_with);
  EXPECT_EQ(matched_without, 0);
  EXPECT_EQ(matched_with, 14);
  // Seeds 1-5: 0.061-0.066 with, 0.079-0.082 without (dead reckoning: 0.4 m).
  EXPECT_LT(with, 0.85 * without) << "with matching " << with << ", without " << without;
}

// Scans without odometry (a laser alone): the constant-velocity prior and the
// scan match carry the motion. Told that the scans have none, the local map
// follows a smooth path; taking the missing odometry for "standing still", it
// cannot (its prior says a few mm, so the window is centred on no motion and
// the match is pulled back to it).
TEST(LocalMapScanMatching, ScansWithoutOdometryAreMappedByTheMatchAlone) {
  testing::SyntheticWorld room;
  room.walls = {{{-2.0, -4.0}, {12.0, -4.0}}, {{12.0, -4.0}, {12.0, 1.0}}, {{12.0, 1.0}, {7.0, 1.0}},
                {{7.0, 1.0}, {7.0, 5.0}},     {{7.0, 5.0}, {-2.0, 5.0}},  {{-2.0, 5.0}, {-2.0, -4.0}},
                {{3.0, 4.0}, {3.0, 5.0}}};
  std::mt19937 rng(5);
  std::vector<LaserScan> scans;
  std::vector<Pose2> truth;
  for (int k = 0; k < 40; ++k) {
    const Pose2 x_WR(0.2 * k, 0.6 * std::sin(0.1 * k), 0.06 * std::cos(0.1 * k));
    truth.push_back(x_WR);
    LaserScan scan = testing::make_scan(room, x_WR, 361, 80.0, 0.01, &rng);
    scan.utime = k * kScanPeriodUs;
    scan.odometry = Pose2();  // none
    scans.push_back(scan);
  }
  auto final_error = [&](bool told) {
    LocalMapConfig config;
    config.scans_have_odometry = !told;
    LocalMap lm(config);
    for (const LaserScan& scan : scans) {
      lm.process_scan(scan);
      EXPECT_TRUE(lm.check_covariance().ok());
    }
    const Pose2 e = between(lm.x_LR(), between(truth.front(), truth.back()));
    return std::hypot(e.x, e.y) + 2.0 * std::abs(e.phi);  // m, and rad at 2 m
  };
  const double told = final_error(true);
  const double not_told = final_error(false);
  EXPECT_LT(told, 0.1) << "7.8 m of travel";
  EXPECT_GT(not_told, 1.0);
}

TEST(ConstantVelocityPrior, GoesOnAsItWentWithTheWindowAsItsSpread) {
  ScanMatcherConfig matching;
  ConstantVelocityPrior prior(matching);
  EXPECT_TRUE(is_near(prior.predict(100000), Pose2(), 0.0, 0.0));  // nothing seen: standing
  prior.observe(Pose2(0.1, -0.02, 0.03), 100000);                  // in 0.1 s
  EXPECT_TRUE(is_near(prior.predict(200000), Pose2(0.2, -0.04, 0.06), 1e-12, 1e-12));
  prior.observe(Pose2(0.5, 0.0, 0.0), 0);  // no time passed: nothing learned
  EXPECT_TRUE(is_near(prior.predict(100000), Pose2(0.1, -0.02, 0.03), 1e-12, 1e-12));
  const Eigen::Vector3d sigma = prior.covariance().diagonal().cwiseSqrt();
  EXPECT_NEAR(sigma.x(), matching.search_window_m / 3.0, 1e-12);
  EXPECT_NEAR(sigma.y(), matching.search_window_m / 3.0, 1e-12);
  EXPECT_NEAR(sigma.z(), matching.search_window_rad / 3.0, 1e-12);
}

TEST(LocalMapConfig, ScansWithoutOdometryNeedTheScanMatch) {
  LocalMapConfig config;
  config.scans_have_odometry = false;
  EXPECT_NO_THROW(config.validate());
  config.scan_matching.enabled = false;
  EXPECT_THROW(config.validate(), std::invalid_argument);
}

// The scan history behind step 1 is relative to the robot: a new local map
// (reset) keeps matching against the scans before it; resume() (the scans
// are gone) starts it again.
TEST(LocalMapScanMatching, TheScanHistorySurvivesReset) {
  testing::SyntheticWorld room;
  room.walls = {{{-2.0, -4.0}, {12.0, -4.0}}, {{12.0, -4.0}, {12.0, 5.0}}, {{12.0, 5.0}, {-2.0, 5.0}},
                {{-2.0, 5.0}, {-2.0, -4.0}}, {{5.0, 2.0}, {5.0, 5.0}}};
  LocalMap lm;
  for (int k = 0; k < 6; ++k) {
    LaserScan scan = testing::make_scan(room, Pose2(0.4 * k, 0.0, 0.05 * k), 361);
    scan.utime = k * kScanPeriodUs;
    if (k == 3) lm.reset();
    if (k == 5) lm.resume(lm.seq() + 1, scan.utime - kScanPeriodUs, Pose2(0.4 * 4, 0.0, 0.05 * 4));
    const ScanReport r = lm.process_scan(scan);
    EXPECT_EQ(r.scan_match_tried, k > 0 && k != 5) << k;
    EXPECT_EQ(r.scan_matched, k > 0 && k != 5) << k;
  }
}

// The motion filter (LocalMapConfig::motion_filter): a robot creeping 5 cm per
// scan is taken every fourth scan (0.2 m, the keyframe, is nearest at the
// fourth); the scans between leave the filter as it was and are dead-reckoned
// from the last scan taken, and the local map's trajectory holds every scan.
// A map that must end at a skipped scan takes it (take_skipped_scan).
TEST(LocalMapMotionFilter, ScansThatAreNoNewViewAreDeadReckonedAndLeaveTheFilterAsItWas) {
  testing::SyntheticWorld room;
  room.walls = {{{-2.0, -4.0}, {12.0, -4.0}}, {{12.0, -4.0}, {12.0, 5.0}}, {{12.0, 5.0}, {-2.0, 5.0}},
                {{-2.0, 5.0}, {-2.0, -4.0}}, {{5.0, 2.0}, {5.0, 5.0}}};
  constexpr int kScans = 18;  // the last one (17) skipped
  const auto run = [&](bool motion_filter) {
    LocalMapConfig config;
    config.motion_filter = motion_filter;
    LocalMap lm(config);
    int taken = 0;
    for (int k = 0; k < kScans; ++k) {
      const Pose2 x_WR(0.05 * k, 0.0, 0.0);
      LaserScan scan = testing::make_scan(room, x_WR, 361);
      scan.utime = k * kScanPeriodUs;
      scan.odometry = x_WR;
      const Eigen::MatrixXd P_before = lm.snapshot().covariance;
      const Pose2 x_LR_before = lm.x_LR();
      const ScanReport r = lm.process_scan(scan);
      EXPECT_EQ(r.scan_skipped, motion_filter && k % 4 != 0) << k;
      if (r.scan_skipped) {
        EXPECT_FALSE(r.scan_match_tried) << k;
        EXPECT_TRUE(lm.snapshot().covariance == P_before) << k;
        EXPECT_TRUE(is_near(lm.x_LR(), x_LR_before, 0.0, 0.0)) << k;
        // The corrected odometry since the last scan taken, with its noise.
        EXPECT_NEAR(r.x_LR.x, 0.05 * k, 0.01) << k;
        EXPECT_TRUE(is_near(lm.x_LR_at_last_scan(), r.x_LR, 0.0, 0.0)) << k;
        EXPECT_GT(lm.robot_covariance_at_last_scan().trace(), lm.robot_covariance().trace()) << k;
      } else {
        ++taken;
        EXPECT_EQ(r.scan_matched, k > 0) << k;
        EXPECT_TRUE(is_near(r.x_LR, lm.x_LR(), 0.0, 0.0)) << k;
        EXPECT_TRUE(is_near(lm.x_LR_at_last_scan(), lm.x_LR(), 0.0, 0.0)) << k;
        EXPECT_TRUE(lm.robot_covariance_at_last_scan() == lm.robot_covariance()) << k;
      }
    }
    // The map ends at the last scan: taken now if it was skipped.
    const std::optional<ScanReport> last = lm.take_skipped_scan();
    EXPECT_EQ(last.has_value(), motion_filter);
    if (last) {
      EXPECT_TRUE(last->scan_matched);
      ++taken;
    }
    EXPECT_FALSE(lm.take_skipped_scan().has_value());
    const LocalMapSnapshot snapshot = lm.snapshot();
    EXPECT_EQ(snapshot.scan_poses.size(), static_cast<std::size_t>(kScans));
    EXPECT_EQ(snapshot.last_utime, (kScans - 1) * kScanPeriodUs);
    EXPECT_TRUE(is_near(snapshot.scan_poses.back().x_LR, snapshot.x_LR, 0.0, 0.0));
    EXPECT_NEAR(snapshot.x_LR.x, 0.05 * (kScans - 1), 0.01);
    return taken;
  };
  EXPECT_EQ(run(true), 6);  // 0, 4, 8, 12, 16, and 17 at the end
  EXPECT_EQ(run(false), kScans);
}

// Free-space evidence (LocalMapConfig::see_through): a box face seen by the
// first scans (another robot standing there) and gone from the later ones is
// removed once the beams pass through where it was; the room's walls stay.
TEST(LocalMapSeeThrough, AnObjectThatLeavesIsRemovedAndTheWallsStay) {
  testing::SyntheticWorld room;
  room.walls = {{{-2.0, -4.0}, {9.0, -4.0}}, {{9.0, -4.0}, {9.0, 5.0}}, {{9.0, 5.0}, {-2.0, 5.0}},
                {{-2.0, 5.0}, {-2.0, -4.0}}};
  testing::SyntheticWorld with_object = room;
  with_object.walls.push_back({{4.0, 0.5}, {4.0, 1.3}});
  std::mt19937 rng(5);
  std::vector<LaserScan> scans;
  for (int k = 0; k < 14; ++k) {
    const Pose2 x_WR(0.1 * k, 0.0, 0.0);
    LaserScan scan = testing::make_scan(k < 6 ? with_object : room, x_WR, 361, 80.0, 0.005, &rng);
    scan.utime = k * kScanPeriodUs;
    scan.odometry = x_WR;
    scans.push_back(scan);
  }
  const auto object_segments = [](const LocalMap& lm) {
    int n = 0;
    for (const EntityId id : lm.segment_ids()) {
      const Pose2 x = lm.map().root_location(id);
      if (std::abs(x.x - 4.0) < 0.2 && x.y > 0.3 && x.y < 1.5) ++n;
    }
    return n;
  };
  for (const bool enabled : {true, false}) {
    LocalMapConfig config;
    config.see_through.enabled = enabled;
    LocalMap lm(config);
    int removed = 0;
    for (std::size_t k = 0; k < scans.size(); ++k) {
      const ScanReport r = lm.process_scan(scans[k]);
      removed += r.segments_seen_through;
      EXPECT_EQ(r.map_segments, static_cast<int>(lm.num_segments()));
      if (k == 5) {
        EXPECT_EQ(object_segments(lm), 1) << "the object is mapped while it is there";
      }
      if (k < 6) {
        EXPECT_EQ(r.segments_seen_through, 0) << k;
      }
      EXPECT_TRUE(lm.check_covariance().ok()) << k;
    }
    EXPECT_EQ(object_segments(lm), enabled ? 0 : 1) << "see_through.enabled = " << enabled;
    EXPECT_EQ(removed, enabled ? 1 : 0);
    EXPECT_EQ(lm.num_segments(), enabled ? 3u : 4u);  // the three walls in view stay
  }
}

}  // namespace
}  // namespace lmf
