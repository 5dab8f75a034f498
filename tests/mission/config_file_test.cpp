#include "lmf/mission/config_file.hpp"

#include <filesystem>
#include <stdexcept>
#include <string>

#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include "lmf/fusion/global_map_archive.hpp"

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

// A valid value other than the default, written to the JSON object j too.
struct Nudge {
  nlohmann::json& j;
  void operator()(const char* name, double& v) const { j[name] = v = (v == 0.0 ? 1e-3 : v * 1.001); }
  void operator()(const char* name, bool& v) const { j[name] = v = !v; }
  void operator()(const char* name, int& v) const { j[name] = v = v + 1; }
  void operator()(const char* name, fusion::HealthCheck& v) const {
    v = v == fusion::HealthCheck::kNone ? fusion::HealthCheck::kTouched : fusion::HealthCheck::kNone;
    for (const auto& [choice, value] : fusion::kHealthCheckNames) {
      if (value == v) j[name] = choice;
    }
  }
  void operator()(const char* name, fusion::FrameRegistrationConfig& g) const { section(name, g); }
  void operator()(const char* name, fusion::PlaceRecognitionConfig& g) const { section(name, g); }
  template <class Section>
  void section(const char* name, Section& g) const {
    nlohmann::json fields = nlohmann::json::object();
    fusion::visit_fields(g, Nudge{fields});
    j[name] = fields;
  }
};

// Nudges only the k-th field (counting into sections); `at` counts every field.
struct NudgeOne {
  int k = 0;
  int at = 0;
  void operator()(const char*, fusion::FrameRegistrationConfig& g) { fusion::visit_fields(g, *this); }
  void operator()(const char*, fusion::PlaceRecognitionConfig& g) { fusion::visit_fields(g, *this); }
  template <class T>
  void operator()(const char* name, T& v) {
    if (at++ != k) return;
    nlohmann::json unused = nlohmann::json::object();
    Nudge{unused}(name, v);
  }
};

// Every field of GlobalMapConfig, as visit_fields lists it: written to JSON
// changed from its default, read back by the config reader, and each one seen
// by same_config (the archive's comparison).
TEST(MissionConfigFile, EveryGlobalMapFieldIsReadAndCompared) {
  fusion::GlobalMapConfig nudged;
  nlohmann::json global = nlohmann::json::object();
  fusion::visit_fields(nudged, Nudge{global});
  ASSERT_NO_THROW(nudged.validate());
  const MissionConfig read = parse_mission_config(nlohmann::json{{"global_map", global}}.dump());
  EXPECT_TRUE(fusion::same_config(read.global_map, nudged));
  EXPECT_FALSE(fusion::same_config(read.global_map, fusion::GlobalMapConfig{}));

  fusion::GlobalMapConfig counted;
  NudgeOne count{-1};
  fusion::visit_fields(counted, count);
  EXPECT_GE(count.at, 25);
  for (int k = 0; k < count.at; ++k) {
    fusion::GlobalMapConfig one;
    NudgeOne nudge{k};
    fusion::visit_fields(one, nudge);
    EXPECT_FALSE(fusion::same_config(one, fusion::GlobalMapConfig{})) << "field " << k;
  }
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
          "own_recent_maps": 2, "confirm_pairings": false}}})");
  const fusion::FrameRegistrationConfig& g = c.global_map.registration;
  EXPECT_FALSE(g.enabled);
  EXPECT_DOUBLE_EQ(g.window_m, 2.5);
  EXPECT_DOUBLE_EQ(g.window_rad, 0.2);
  EXPECT_DOUBLE_EQ(g.resolution_m, 0.08);
  EXPECT_DOUBLE_EQ(g.min_score, 0.5);
  EXPECT_DOUBLE_EQ(g.ambiguity_ratio, 0.8);
  EXPECT_DOUBLE_EQ(g.min_constraint, 0.1);
  EXPECT_EQ(g.own_recent_maps, 2);
  EXPECT_FALSE(g.confirm_pairings);
  EXPECT_THROW(parse_mission_config(R"({"global_map": {"registration": {"window": 1}}})"), std::invalid_argument);
  EXPECT_THROW(parse_mission_config(R"({"global_map": {"registration": {"min_score": 2}}})"), std::invalid_argument);
}

// A registration window the search cannot hold (more than 63 cells of
// resolution_m per side) is refused when the file is read, naming the key, not
// in the middle of a mission; the widest one it holds runs.
TEST(MissionConfigFile, ARegistrationWindowTheSearchCannotHoldIsRefusedWhenRead) {
  try {
    parse_mission_config(R"({"global_map": {"registration": {"window_m": 4}}})", "wide.json");
    FAIL() << "window_m 4 at resolution_m 0.05 was accepted";
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find("window_m"), std::string::npos) << e.what();
    EXPECT_NE(std::string(e.what()).find("wide.json"), std::string::npos) << e.what();
  }
  const MissionConfig widest = parse_mission_config(R"({"global_map": {"registration": {"window_m": 3.15}}})");
  EXPECT_DOUBLE_EQ(widest.global_map.registration.window_m, 3.15);
  EXPECT_NO_THROW(parse_mission_config(R"({"global_map": {"registration": {"window_m": 4, "resolution_m": 0.1}}})"));
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
