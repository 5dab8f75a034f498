#include "lmf/mission/config_file.hpp"

#include <filesystem>
#include <stdexcept>
#include <string>

#include <gtest/gtest.h>

namespace lmf::mission {
namespace {

TEST(MissionConfigFile, EveryShippedConfigLoads) {
  int loaded = 0;
  for (const auto& entry : std::filesystem::directory_iterator(LMF_CONFIG_DIR)) {
    if (entry.path().extension() != ".json") continue;
    SCOPED_TRACE(entry.path().string());
    EXPECT_NO_THROW(load_mission_config(entry.path()));
    ++loaded;
  }
  EXPECT_GE(loaded, 1);
}

TEST(MissionConfigFile, ReadsSectionsAndKeepsDefaults) {
  const MissionConfig c = parse_mission_config(
      R"({"local_map": {"ship_distance_m": 5, "extraction": {"split_distance_m": 0.06}},
          "global_map": {"alpha": 0.01}, "sighting_noise": {"seed": 7}})");
  EXPECT_DOUBLE_EQ(c.local_map.ship_distance_m, 5.0);
  EXPECT_DOUBLE_EQ(c.local_map.extraction.split_distance_m, 0.06);
  EXPECT_DOUBLE_EQ(c.global_map.alpha, 0.01);
  EXPECT_EQ(c.sighting_noise.seed, 7u);
  EXPECT_DOUBLE_EQ(c.sighting_noise.sigma_xy_m, SightingNoise{}.sigma_xy_m);
}

TEST(MissionConfigFile, ReadsTheFrameRegistration) {
  const MissionConfig c = parse_mission_config(
      R"({"global_map": {"registration": {"enabled": false, "window_m": 2.5, "window_rad": 0.2,
          "resolution_m": 0.08, "min_score": 0.5, "ambiguity_ratio": 0.8, "min_constraint": 0.1,
          "own_recent_maps": 2}}})");
  const fusion::FrameRegistrationConfig& g = c.global_map.registration;
  EXPECT_FALSE(g.enabled);
  EXPECT_DOUBLE_EQ(g.window_m, 2.5);
  EXPECT_DOUBLE_EQ(g.window_rad, 0.2);
  EXPECT_DOUBLE_EQ(g.resolution_m, 0.08);
  EXPECT_DOUBLE_EQ(g.min_score, 0.5);
  EXPECT_DOUBLE_EQ(g.ambiguity_ratio, 0.8);
  EXPECT_DOUBLE_EQ(g.min_constraint, 0.1);
  EXPECT_EQ(g.own_recent_maps, 2);
  EXPECT_THROW(parse_mission_config(R"({"global_map": {"registration": {"window": 1}}})"), std::invalid_argument);
  EXPECT_THROW(parse_mission_config(R"({"global_map": {"registration": {"min_score": 2}}})"), std::invalid_argument);
}

TEST(MissionConfigFile, UnknownKeysAndBadValuesNameTheKey) {
  try {
    parse_mission_config(R"({"local_map": {"ship_distanse_m": 5}})", "robot.json");
    FAIL() << "an unknown key was accepted";
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find("ship_distanse_m"), std::string::npos) << e.what();
    EXPECT_NE(std::string(e.what()).find("robot.json"), std::string::npos) << e.what();
  }
  EXPECT_THROW(parse_mission_config(R"({"global_map": {"alpha": "high"}})"), std::invalid_argument);
  EXPECT_THROW(parse_mission_config(R"({"sighting_noise": {"sigma_xy_m": -1}})"), std::invalid_argument);
  EXPECT_THROW(parse_mission_config(R"({"local_map": {"ship_distance_m": 0}})"), std::invalid_argument);
}

}  // namespace
}  // namespace lmf::mission
