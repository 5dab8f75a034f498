// Place recognition (lmf/fusion/place_recognition.hpp): the hard cases of
// issue 38 (two identical rooms, a corridor) and the plain one.
#include "lmf/fusion/place_recognition.hpp"

#include <cmath>
#include <vector>

#include <gtest/gtest.h>

#include "fusion/registration_segments.hpp"
#include "fusion/synthetic_maps.hpp"
#include "lmf/fusion/global_map.hpp"
#include "lmf/fusion/wall_directions.hpp"

namespace lmf::fusion {
namespace {

using synthetic::in_frame;
using synthetic::in_world;
using synthetic::Wall;

std::vector<Wall> shifted(const std::vector<Wall>& walls, double dx, double dy) {
  std::vector<Wall> out;
  for (const Wall& w : walls) out.push_back({Pose2(w.x_WS.x + dx, w.x_WS.y + dy, w.x_WS.phi), w.length_m});
  return out;
}

// A room of 8 x 5 m centred at (cx, cy) with an L of 2 m walls off its
// centre: it looks like itself at one pose only (turned by 180°, only the
// room's 26 m of the 30 m of walls fit: a score below 0.9 of the best).
std::vector<Wall> room_with_pillar(double cx, double cy) {
  std::vector<Wall> walls = synthetic::room(cx, cy, 8.0, 5.0);
  walls.push_back({Pose2(cx + 1.5, cy + 0.8, 0.0), 2.0});
  walls.push_back({Pose2(cx + 2.5, cy + 1.8, M_PI / 2), 2.0});
  return walls;
}

// A building of three different rooms along a corridor wall.
std::vector<Wall> building() {
  std::vector<Wall> walls = room_with_pillar(0.0, 0.0);
  for (const Wall& w : synthetic::room(11.0, 1.0, 6.0, 7.0)) walls.push_back(w);
  for (const Wall& w : synthetic::room(5.0, 9.0, 14.0, 4.0)) walls.push_back(w);
  walls.push_back({Pose2(12.5, 9.5, M_PI / 4), 1.5});
  walls.push_back({Pose2(5.0, -6.0, 0.0), 20.0});
  return walls;
}

TEST(PlaceRecognitionTest, FindsALocalMapAnywhereAtAnyHeading) {
  const std::vector<Wall> global = building();
  const FrameRegistrationConfig registration;
  const PlaceRecognitionConfig config;
  for (const Pose2& x_WL : {Pose2(0.5, -0.3, 2.5), Pose2(-2.0, 1.0, -1.2), Pose2(1.0, 0.0, 0.0)}) {
    const PlaceRecognition place =
        recognise_place(in_frame(room_with_pillar(0.0, 0.0), x_WL), in_world(global), registration, config);
    ASSERT_EQ(place.outcome, PlaceOutcome::kPlaced) << to_string(place.outcome) << " score " << place.score << " rival " << place.rival_score << " candidates " << place.candidates;
    const Pose2 error = between(x_WL, place.x_WL);
    EXPECT_LT(std::hypot(error.x, error.y), 2.0 * registration.resolution_m);
    EXPECT_LT(std::abs(error.phi), 2.0 * place.angular_step_rad);
    EXPECT_GT(place.score, 0.9);
    EXPECT_LT(place.rival_score, registration.ambiguity_ratio * place.score);
  }
}

TEST(PlaceRecognitionTest, TwoIdenticalRoomsAreAmbiguous) {
  // The same room twice, 12 m apart: a local map of one of them fits both.
  const std::vector<Wall> one = room_with_pillar(0.0, 0.0);
  std::vector<Wall> two = one;
  for (const Wall& w : shifted(one, 12.0, 0.0)) two.push_back(w);
  const Pose2 x_WL(0.3, 0.2, 0.7);
  const std::vector<RegistrationSegment> local = in_frame(one, x_WL);
  const PlaceRecognition single = recognise_place(local, in_world(one), {}, {});
  EXPECT_EQ(single.outcome, PlaceOutcome::kPlaced) << to_string(single.outcome);
  const PlaceRecognition twin = recognise_place(local, in_world(two), {}, {});
  EXPECT_EQ(twin.outcome, PlaceOutcome::kAmbiguous) << to_string(twin.outcome);
  EXPECT_GE(twin.candidates, 2);
  EXPECT_GT(twin.rival_score, 0.9 * twin.score);
}

TEST(PlaceRecognitionTest, ACorridorIsDegenerate) {
  const std::vector<Wall> global = {{Pose2(0.0, -1.0, 0.0), 30.0}, {Pose2(0.0, 1.0, M_PI), 30.0},
                                    {Pose2(15.0, 0.0, M_PI / 2), 2.0}};
  const std::vector<Wall> seen = {{Pose2(0.0, -1.0, 0.0), 8.0}, {Pose2(0.0, 1.0, M_PI), 8.0}};
  const PlaceRecognition place = recognise_place(in_frame(seen, Pose2(1.0, 0.0, 0.2)), in_world(global), {}, {});
  EXPECT_EQ(place.outcome, PlaceOutcome::kDegenerate) << to_string(place.outcome);
}

TEST(PlaceRecognitionTest, AnUnmappedRoomIsNotFound) {
  // A round-ish room of short walls at odd angles is nowhere in the building.
  std::vector<Wall> unmapped;
  for (int k = 0; k < 7; ++k) {
    const double a = 2.0 * M_PI * k / 7.0;
    unmapped.push_back({Pose2(3.0 * std::cos(a), 3.0 * std::sin(a), a + M_PI / 2), 2.4});
  }
  const PlaceRecognition place =
      recognise_place(in_frame(unmapped, Pose2(2.0, 1.0, 0.4)), in_world(building()), {}, {});
  EXPECT_EQ(place.outcome, PlaceOutcome::kNotFound) << to_string(place.outcome) << " score " << place.score;
}

TEST(PlaceRecognitionTest, NothingToSearchIsNotFound) {
  EXPECT_EQ(recognise_place({}, in_world(building()), {}, {}).outcome, PlaceOutcome::kNotFound);
  EXPECT_EQ(recognise_place(in_world(building()), {}, {}, {}).outcome, PlaceOutcome::kNotFound);
}

// The headings the global search tries (wall_directions.hpp): directions are
// taken modulo π, and a heading counts a local wall only where a global wall
// runs within its tolerance.
TEST(PlaceRecognitionTest, WallDirectionsWrapAroundPiAndGateTheHeadings) {
  const WallDirections directions({{Pose2(0.0, 0.0, 0.001), 4.0}, {Pose2(3.0, 0.0, M_PI / 2), 4.0}});
  EXPECT_TRUE(directions.any_within(M_PI - 0.001, 0.01));
  EXPECT_TRUE(directions.any_within(-M_PI / 2, 0.01));
  EXPECT_TRUE(directions.any_within(0.02, 0.03));
  EXPECT_FALSE(directions.any_within(0.02, 0.005));
  EXPECT_FALSE(directions.any_within(M_PI / 4, 0.2));
  EXPECT_TRUE(directions.any_within(M_PI / 4, M_PI));
  EXPECT_FALSE(WallDirections({}).any_within(0.0, M_PI));

  // A local room of 8 m walls (tolerance: the step plus 0.1 rad) and a 0.4 m
  // stub (turning it by a radian moves its ends by half a cell): everything
  // lines up at every quarter turn; half-way between, only the stub counts.
  std::vector<RegistrationSegment> local;
  for (const Wall& w : synthetic::room(0.0, 0.0, 8.0, 8.0)) local.push_back({w.x_WS, w.length_m});
  local.push_back({Pose2(1.0, 1.0, 0.3), 0.4});
  const double step = 0.02;
  const double cell = 0.4;
  EXPECT_NEAR(parallel_share(local, directions, 0.0, step, cell), 1.0, 1e-12);
  EXPECT_NEAR(parallel_share(local, directions, M_PI / 2 + 0.01, step, cell), 1.0, 1e-12);
  EXPECT_NEAR(parallel_share(local, directions, M_PI / 4, step, cell), 0.4 / 32.4, 1e-12);
  EXPECT_EQ(parallel_share({}, directions, 0.0, step, cell), 0.0);
}

TEST(PlaceRecognitionTest, ConfigIsValidated) {
  PlaceRecognitionConfig config;
  EXPECT_NO_THROW(config.validate());
  config.resolution_m = 0.0;
  EXPECT_THROW(config.validate(), std::invalid_argument);
  config = {};
  config.min_score = 1.0;
  EXPECT_THROW(config.validate(), std::invalid_argument);
  config = {};
  config.max_candidates = 0;
  EXPECT_THROW(config.validate(), std::invalid_argument);
  config = {};
  config.min_score = 0.0;
  EXPECT_THROW(config.validate(), std::invalid_argument);
}

// --- In the global map: a robot without a sighting joins where its local map is found.

// The map's config with place recognition on.
GlobalMapConfig recognising() {
  GlobalMapConfig config;
  config.place_recognition.enabled = true;
  return config;
}

TEST(PlaceRecognitionJoin, ARobotWithoutASightingJoinsWhereItsMapIsFound) {
  GlobalMap map(recognising());
  const std::vector<Wall> walls = building();
  map.fuse(synthetic::make_snapshot(0, 0, Pose2(), Pose2(1.0, 0.0, 0.0), walls));
  ASSERT_TRUE(map.is_joined(0));
  const Pose2 x_WL_true(1.0, 0.5, 2.2);  // robot 1's frame: unknown to the map
  const std::vector<FusionReport> reports =
      map.fuse(synthetic::make_snapshot(1, 0, x_WL_true, Pose2(0.5, 0.0, 0.0), room_with_pillar(0.0, 0.0)));
  ASSERT_TRUE(map.is_joined(1));
  ASSERT_EQ(reports.size(), 1U);
  ASSERT_TRUE(map.how_joined(1).has_value());
  EXPECT_EQ(map.how_joined(1)->how, JoinKind::kPlace);
  EXPECT_EQ(map.how_joined(1)->seq, 0);
  EXPECT_EQ(map.how_joined(0)->how, JoinKind::kFirst);
  EXPECT_EQ(map.place_recognition_counts().placed, 1);
  // Its walls were paired with the map's: no segment was added.
  EXPECT_EQ(map.counts().segments, static_cast<int>(walls.size()));
  // After the fusion, robot 1's frame is that of its next local map, where it ended.
  const Pose2 error = between(compose(x_WL_true, Pose2(0.5, 0.0, 0.0)), map.corrected_frame(1)->x_WL);
  EXPECT_LT(std::hypot(error.x, error.y), 0.05);
  EXPECT_LT(std::abs(error.phi), 0.01);
}

TEST(PlaceRecognitionJoin, InTwoIdenticalRoomsNothingJoins) {
  GlobalMap map(recognising());
  std::vector<Wall> two = room_with_pillar(0.0, 0.0);
  for (const Wall& w : room_with_pillar(12.0, 0.0)) two.push_back(w);
  map.fuse(synthetic::make_snapshot(0, 0, Pose2(), Pose2(1.0, 0.0, 0.0), two));
  const std::vector<FusionReport> reports =
      map.fuse(synthetic::make_snapshot(1, 0, Pose2(12.5, 0.5, 0.4), Pose2(), room_with_pillar(12.0, 0.0)));
  EXPECT_TRUE(reports.empty());
  EXPECT_FALSE(map.is_joined(1));
  EXPECT_TRUE(map.is_queued(1, 0));
  EXPECT_EQ(map.place_recognition_counts().ambiguous, 1);
  EXPECT_EQ(map.place_recognition_counts().placed, 0);
}

TEST(PlaceRecognitionJoin, AQueuedMapIsTriedAgainWhenTheMapGrows) {
  // Robot 1's first local map lies where robot 0 has not been yet: it waits,
  // and joins once robot 0 has mapped that room.
  GlobalMap map(recognising());
  map.fuse(synthetic::make_snapshot(0, 0, Pose2(), Pose2(11.0, 1.0, 0.0), synthetic::room(11.0, 1.0, 6.0, 7.0)));
  const Pose2 x_WL_true(0.5, 0.0, -0.7);
  EXPECT_TRUE(map.fuse(synthetic::make_snapshot(1, 0, x_WL_true, Pose2(), room_with_pillar(0.0, 0.0))).empty());
  EXPECT_FALSE(map.is_joined(1));
  EXPECT_EQ(map.place_recognition_counts().not_found, 1);
  map.fuse(synthetic::make_snapshot(0, 1, Pose2(11.0, 1.0, 0.0), Pose2(), room_with_pillar(0.0, 0.0)));
  ASSERT_TRUE(map.is_joined(1));
  EXPECT_EQ(map.how_joined(1)->how, JoinKind::kPlace);
  EXPECT_FALSE(map.is_queued(1, 0));
  EXPECT_TRUE(map.has_fused(1, 0));
}

TEST(PlaceRecognitionJoin, TurnedOffByDefaultTheMapsWait) {
  GlobalMap map;
  map.fuse(synthetic::make_snapshot(0, 0, Pose2(), Pose2(1.0, 0.0, 0.0), building()));
  EXPECT_TRUE(map.fuse(synthetic::make_snapshot(1, 0, Pose2(1.0, 0.5, 2.2), Pose2(), room_with_pillar(0.0, 0.0))).empty());
  EXPECT_FALSE(map.is_joined(1));
  EXPECT_EQ(map.place_recognition_counts().placed + map.place_recognition_counts().not_found, 0);
}

}  // namespace
}  // namespace lmf::fusion
