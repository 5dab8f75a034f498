// Frame registration (lmf/fusion/frame_registration.hpp) and the fusion step
// that uses it (fusion_steps.hpp, relocate_frame).
#include "lmf/fusion/frame_registration.hpp"

#include <cmath>
#include <vector>

#include <gtest/gtest.h>

#include "fusion/registration_segments.hpp"
#include "fusion/synthetic_maps.hpp"
#include "lmf/fusion/global_map.hpp"

namespace lmf::fusion {
namespace {

using synthetic::in_frame;
using synthetic::in_world;
using synthetic::Wall;

// A room with a pillar of walls off its centre: nothing repeats within the window.
std::vector<Wall> building() {
  std::vector<Wall> walls = synthetic::room(4.0, 0.0, 8.0, 5.0);
  walls.push_back({Pose2(5.5, 0.8, 0.0), 1.2});
  walls.push_back({Pose2(6.1, 1.4, M_PI / 2), 1.2});
  return walls;
}

TEST(FrameRegistrationTest, FindsTheFrameWhereThePredictionIsOff) {
  const std::vector<Wall> walls = building();
  const Pose2 x_WL_true(2.0, -0.5, 0.3);
  const Pose2 predicted = compose(x_WL_true, Pose2(0.45, -0.3, 0.06));
  const FrameRegistrationConfig config;
  const std::optional<FrameRegistration> reg =
      register_frame(in_frame(walls, x_WL_true), in_world(walls), predicted, config);
  ASSERT_TRUE(reg.has_value());
  const Pose2 error = between(x_WL_true, reg->x_WL);
  EXPECT_LT(std::hypot(error.x, error.y), 2.0 * config.resolution_m);
  EXPECT_LT(std::abs(error.phi), 2.0 * reg->angular_step_rad);
  EXPECT_GT(reg->score, 0.9);
  EXPECT_LT(reg->prior_score, 0.5 * reg->score);
  EXPECT_FALSE(reg->ambiguous);
  EXPECT_FALSE(reg->degenerate);
}

TEST(FrameRegistrationTest, APredictionThatIsRightStaysWithinAStep) {
  const std::vector<Wall> walls = building();
  const Pose2 x_WL(1.0, 1.0, -0.2);
  const std::optional<FrameRegistration> reg =
      register_frame(in_frame(walls, x_WL), in_world(walls), x_WL, FrameRegistrationConfig{});
  ASSERT_TRUE(reg.has_value());
  const Pose2 error = between(x_WL, reg->x_WL);
  EXPECT_LE(std::hypot(error.x, error.y), 0.05 + 1e-9);
  EXPECT_LE(std::abs(error.phi), reg->angular_step_rad + 1e-9);
  EXPECT_FALSE(reg->ambiguous);
}

TEST(FrameRegistrationTest, ACorridorIsDegenerate) {
  // Two long parallel walls: nothing fixes the position along them.
  const std::vector<Wall> walls = {{Pose2(0.0, -1.0, 0.0), 30.0}, {Pose2(0.0, 1.0, M_PI), 30.0}};
  const std::vector<Wall> seen = {{Pose2(0.0, -1.0, 0.0), 8.0}, {Pose2(0.0, 1.0, M_PI), 8.0}};
  const Pose2 x_WL(0.0, 0.0, 0.0);
  const std::optional<FrameRegistration> reg =
      register_frame(in_frame(seen, x_WL), in_world(walls), compose(x_WL, Pose2(0.5, 0.3, 0.0)), FrameRegistrationConfig{});
  ASSERT_TRUE(reg.has_value());
  EXPECT_TRUE(reg->degenerate);
  EXPECT_NEAR(reg->x_WL.y, 0.0, 0.05 + 1e-9);  // across the corridor it is found
}

TEST(FrameRegistrationTest, APeriodicCombLeavesItsAxisUnresolved) {
  // A comb: a long base wall and teeth every metre; the local map sees three
  // teeth and the base, which fit equally one period to either side: the
  // walls fix y and the heading, not x.
  std::vector<Wall> walls = {{Pose2(0.0, 0.0, 0.0), 20.0}};
  for (int i = -9; i <= 9; ++i) walls.push_back({Pose2(i * 1.0, 0.6, M_PI / 2), 1.2});
  std::vector<Wall> seen = {{Pose2(0.0, 0.0, 0.0), 2.6}};
  for (int i = -1; i <= 1; ++i) seen.push_back({Pose2(i * 1.0, 0.6, M_PI / 2), 1.2});
  const Pose2 x_WL(0.0, 0.0, 0.0);
  const std::optional<FrameRegistration> reg =
      register_frame(in_frame(seen, x_WL), in_world(walls), compose(x_WL, Pose2(0.5, 0.1, 0.0)), FrameRegistrationConfig{});
  ASSERT_TRUE(reg.has_value());
  EXPECT_FALSE(reg->ambiguous);
  ASSERT_TRUE(reg->unresolved.has_value());
  EXPECT_GT(std::abs(reg->unresolved->x()), 0.99);
  EXPECT_NEAR(reg->x_WL.y, 0.0, 0.05 + 1e-9);
  EXPECT_NEAR(reg->x_WL.phi, 0.0, reg->angular_step_rad + 1e-9);
}

TEST(FrameRegistrationTest, AGridOfPillarsIsAmbiguous) {
  // Square pillars every metre in x and y: the local map's 2 x 2 of them fit
  // one period off in either direction.
  std::vector<Wall> walls;
  const auto pillar = [](double x, double y) {
    return synthetic::room(x, y, 0.3, 0.3);
  };
  for (int i = -4; i <= 4; ++i) {
    for (int j = -4; j <= 4; ++j) {
      for (const Wall& w : pillar(i, j)) walls.push_back(w);
    }
  }
  std::vector<Wall> seen;
  for (int i = 0; i <= 1; ++i) {
    for (int j = 0; j <= 1; ++j) {
      for (const Wall& w : pillar(i, j)) seen.push_back(w);
    }
  }
  const Pose2 x_WL(0.0, 0.0, 0.0);
  const std::optional<FrameRegistration> reg =
      register_frame(in_frame(seen, x_WL), in_world(walls), compose(x_WL, Pose2(0.4, 0.4, 0.0)), FrameRegistrationConfig{});
  ASSERT_TRUE(reg.has_value());
  EXPECT_TRUE(reg->ambiguous);
  EXPECT_FALSE(reg->unresolved.has_value());
}

// Every window validate() allows runs: the widest registers a frame 2.5 m off.
TEST(FrameRegistrationTest, TheWidestValidWindowRuns) {
  FrameRegistrationConfig config;
  config.window_m = 63 * config.resolution_m;
  ASSERT_NO_THROW(config.validate());
  const std::vector<Wall> walls = building();
  const Pose2 x_WL(2.0, -0.5, 0.3);
  std::optional<FrameRegistration> reg;
  ASSERT_NO_THROW(reg = register_frame(in_frame(walls, x_WL), in_world(walls), compose(x_WL, Pose2(2.5, 0.0, 0.0)),
                                       config));
  ASSERT_TRUE(reg.has_value());
}

TEST(FrameRegistrationTest, NothingToRegisterAgainst) {
  const std::vector<Wall> walls = building();
  const Pose2 x_WL(2.0, -0.5, 0.3);
  EXPECT_FALSE(register_frame(in_frame(walls, x_WL), {}, x_WL, FrameRegistrationConfig{}).has_value());
  // Walls far beyond the window.
  std::vector<Wall> far = walls;
  for (Wall& w : far) w.x_WS.x += 100.0;
  EXPECT_FALSE(register_frame(in_frame(walls, x_WL), in_world(far), x_WL, FrameRegistrationConfig{}).has_value());
  EXPECT_FALSE(register_frame({}, in_world(walls), x_WL, FrameRegistrationConfig{}).has_value());
}

TEST(FrameRegistrationTest, ConfigValidation) {
  FrameRegistrationConfig c;
  EXPECT_NO_THROW(c.validate());
  c.resolution_m = 0.0;
  EXPECT_THROW(c.validate(), std::invalid_argument);
  c = {};
  c.min_score = 1.0;
  EXPECT_THROW(c.validate(), std::invalid_argument);
  c = {};
  c.ambiguity_ratio = 0.0;
  EXPECT_THROW(c.validate(), std::invalid_argument);
  c = {};
  c.window_m = -1.0;
  EXPECT_THROW(c.validate(), std::invalid_argument);
  c = {};
  c.own_recent_maps = -1;
  EXPECT_THROW(c.validate(), std::invalid_argument);
  c = {};
  c.window_m = 63 * c.resolution_m;  // the widest window the search's pyramid holds
  EXPECT_NO_THROW(c.validate());
  c.window_m = 64 * c.resolution_m;
  EXPECT_THROW(c.validate(), std::invalid_argument);
  GlobalMapConfig g;
  g.registration.window_rad = std::nan("");
  EXPECT_THROW(g.validate(), std::invalid_argument);
}

// The fusion: the first local map ends with a pose that is 0.3 m and 2.3° off
// while its covariance claims a centimetre. The second map's walls, seen from
// the true pose, then fail the χ² test from the predicted frame.
struct OverconfidentRevisit {
  std::vector<Wall> walls = building();
  Pose2 x_L0R_true = Pose2(2.0, 0.5, 0.3);
  Pose2 x_L0R_claimed = compose(Pose2(2.0, 0.5, 0.3), Pose2(0.3, -0.2, 0.04));
  synthetic::Noise tight{0.01, 0.002, 0.005, 0.002, 0.5};

  std::vector<FusionReport> run(GlobalMap& map) const {
    map.fuse(synthetic::make_snapshot(0, 0, Pose2(), x_L0R_claimed, walls, tight));
    return map.fuse(synthetic::make_snapshot(0, 1, x_L0R_true, Pose2(1.0, -0.5, -0.2), walls, tight));
  }
};

// The robot's own previous map is all there is to register against here;
// by default (own_recent_maps) it is left out, as having drifted with the frame.
GlobalMapConfig own_maps_registered() {
  GlobalMapConfig config;
  config.registration.own_recent_maps = 0;
  return config;
}

TEST(FrameRegistrationTest, AnOverconfidentFrameIsRelocatedAndTheWallsPair) {
  const OverconfidentRevisit revisit;
  GlobalMapConfig config = own_maps_registered();
  config.health = HealthCheck::kFullEigen;
  GlobalMap map(config);
  const std::vector<FusionReport> reports = revisit.run(map);
  ASSERT_EQ(reports.size(), 1u);
  const FusionReport& r = reports[0];
  EXPECT_EQ(r.registration, RegistrationOutcome::kRelocated);
  EXPECT_GT(r.registration_distance2, 50.0);
  EXPECT_NEAR(r.registration_offset.x, -0.3, 0.1);
  EXPECT_NEAR(r.registration_offset.y, 0.2, 0.1);
  EXPECT_EQ(r.pairings_accepted, static_cast<int>(revisit.walls.size()));
  EXPECT_EQ(r.new_segments, 0);
  EXPECT_TRUE(r.covariance_ok());
  // The robot's frame now lies where the walls say (within the registration's steps).
  const Pose2 x_WL_true = compose(revisit.x_L0R_true, Pose2(1.0, -0.5, -0.2));
  const Pose2 error = between(x_WL_true, map.corrected_frame(0)->x_WL);
  EXPECT_LT(std::hypot(error.x, error.y), 0.1);
  EXPECT_LT(std::abs(error.phi), 0.01);
  EXPECT_EQ(map.counts().segments, static_cast<int>(revisit.walls.size()));
}

TEST(FrameRegistrationTest, WithoutRegistrationTheSameRevisitDoublesTheWalls) {
  const OverconfidentRevisit revisit;
  GlobalMapConfig config = own_maps_registered();
  config.registration.enabled = false;
  GlobalMap map(config);
  const std::vector<FusionReport> reports = revisit.run(map);
  ASSERT_EQ(reports.size(), 1u);
  EXPECT_EQ(reports[0].registration, RegistrationOutcome::kNotRun);
  EXPECT_LT(reports[0].pairings_accepted, static_cast<int>(revisit.walls.size()));
  EXPECT_GT(map.counts().segments, static_cast<int>(revisit.walls.size()));
}

TEST(FrameRegistrationTest, TheRobotsOwnRecentMapsAreNotRegisteredAgainst) {
  const OverconfidentRevisit revisit;
  GlobalMap map{GlobalMapConfig{}};
  const std::vector<FusionReport> reports = revisit.run(map);
  ASSERT_EQ(reports.size(), 1u);
  EXPECT_EQ(reports[0].registration, RegistrationOutcome::kNothingNearby);
}

TEST(FrameRegistrationTest, TheRobotsOlderMapsCloseALoop) {
  // Map 0 sees the building; maps 1-4 see nothing (the robot drives a loop
  // elsewhere) and the last of them claims a pose 0.3 m and 2.3° off; map 5
  // sees the building again. Map 0 is older than own_recent_maps: registered against.
  const OverconfidentRevisit revisit;
  GlobalMap map{GlobalMapConfig{}};
  const Pose2 x_L0R(2.0, 0.5, 0.3);
  map.fuse(synthetic::make_snapshot(0, 0, Pose2(), x_L0R, revisit.walls, revisit.tight));
  Pose2 x_WL = x_L0R;
  for (int seq = 1; seq <= 4; ++seq) {
    const Pose2 step = seq == 4 ? Pose2(0.3, -0.2, 0.04) : Pose2();
    map.fuse(synthetic::make_snapshot(0, seq, x_WL, step, {}, revisit.tight));
  }
  const std::vector<FusionReport> reports =
      map.fuse(synthetic::make_snapshot(0, 5, x_L0R, Pose2(1.0, -0.5, -0.2), revisit.walls, revisit.tight));
  ASSERT_EQ(reports.size(), 1u);
  EXPECT_EQ(reports[0].registration, RegistrationOutcome::kRelocated);
  EXPECT_EQ(reports[0].pairings_accepted, static_cast<int>(revisit.walls.size()));
  EXPECT_EQ(map.counts().segments, static_cast<int>(revisit.walls.size()));
}

TEST(FrameRegistrationTest, AConsistentRevisitIsLeftAlone) {
  const OverconfidentRevisit revisit;
  GlobalMap map{own_maps_registered()};
  map.fuse(synthetic::make_snapshot(0, 0, Pose2(), revisit.x_L0R_true, revisit.walls, revisit.tight));
  const std::vector<FusionReport> reports =
      map.fuse(synthetic::make_snapshot(0, 1, revisit.x_L0R_true, Pose2(1.0, -0.5, -0.2), revisit.walls, revisit.tight));
  ASSERT_EQ(reports.size(), 1u);
  EXPECT_EQ(reports[0].registration, RegistrationOutcome::kAgrees);
  EXPECT_EQ(reports[0].pairings_accepted, static_cast<int>(revisit.walls.size()));
}

// Map 0 sees the building; maps 1-4 see nothing; map 5, from where the map
// expects it, sees furniture the map does not hold (walls turned 0.6 rad from
// the building's, beyond the window's headings) and one wall of the building's
// pillar. No pose of the window explains min_score of it, so the
// one segment that lines up with the pillar is a coincidence to the
// registration: with confirm_pairings it is not paired and is counted, as
// long as the window held where the frame may be (maps 1-4 claim `chain`).
struct UnconfirmedLoop {
  std::vector<Wall> walls = building();
  synthetic::Noise tight{0.01, 0.002, 0.005, 0.002, 0.5};
  synthetic::Noise chain = tight;
  Pose2 x_L0R = Pose2(2.0, 0.5, 0.3);

  std::vector<Wall> last_map() const {
    std::vector<Wall> seen;
    for (const auto& [x, y] : {std::pair{2.0, -1.0}, std::pair{2.5, 0.2}, std::pair{1.5, 1.2}}) {
      seen.push_back({Pose2(x, y, 0.6), 2.0});
      seen.push_back({Pose2(x + 0.3, y - 0.4, 0.6 + M_PI / 2), 1.5});
    }
    seen.push_back(walls[4]);  // the pillar's first wall
    return seen;
  }
  FusionReport run(GlobalMap& map) const {
    map.fuse(synthetic::make_snapshot(0, 0, Pose2(), x_L0R, walls, tight));
    for (int seq = 1; seq <= 4; ++seq) map.fuse(synthetic::make_snapshot(0, seq, x_L0R, Pose2(), {}, chain));
    const std::vector<FusionReport> reports =
        map.fuse(synthetic::make_snapshot(0, 5, x_L0R, Pose2(0.5, 0.0, 0.1), last_map(), tight));
    EXPECT_EQ(reports.size(), 1u);
    return reports.empty() ? FusionReport{} : reports[0];
  }
};

TEST(FrameRegistrationTest, PairingsTheRegistrationDoesNotConfirmAreRefused) {
  const UnconfirmedLoop loop;
  ASSERT_EQ(loop.walls[4].length_m, 1.2);
  GlobalMap map{GlobalMapConfig{}};
  const FusionReport r = loop.run(map);
  EXPECT_EQ(r.registration, RegistrationOutcome::kNothingNearby);
  EXPECT_GE(r.unconfirmed_pairs, 1);
  EXPECT_EQ(r.pairings_accepted, 0);
  EXPECT_EQ(r.new_segments, static_cast<int>(loop.last_map().size()));
  EXPECT_EQ(r.pairs_considered, r.gate_rejected + r.unconfirmed_pairs);  // maps 2-4, its own recent ones, are empty
}

// The chain of maps 1-4 claims 0.3 m each (times local_map_covariance_scale):
// the frame's χ² region reaches beyond the window, where the registration did
// not look; the gate decides, as without confirmation.
TEST(FrameRegistrationTest, BeyondItsWindowTheRegistrationDoesNotVeto) {
  UnconfirmedLoop loop;
  loop.chain.robot_xy_m = 0.3;
  GlobalMap map{GlobalMapConfig{}};
  const FusionReport r = loop.run(map);
  EXPECT_EQ(r.registration, RegistrationOutcome::kNothingNearby);
  EXPECT_EQ(r.unconfirmed_pairs, 0);
  EXPECT_GE(r.pairings_accepted, 1);
}

TEST(FrameRegistrationTest, WithoutConfirmationTheCoincidenceIsPaired) {
  const UnconfirmedLoop loop;
  GlobalMapConfig config;
  config.registration.confirm_pairings = false;
  GlobalMap map(config);
  const FusionReport r = loop.run(map);
  EXPECT_EQ(r.registration, RegistrationOutcome::kNothingNearby);
  EXPECT_EQ(r.unconfirmed_pairs, 0);
  EXPECT_GE(r.pairings_accepted, 1);
}

}  // namespace
}  // namespace lmf::fusion
