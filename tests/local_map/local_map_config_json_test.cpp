// LocalMapConfig from JSON: known keys set, unknown keys and bad values rejected by name.
#include "lmf/local_map/local_map_config_json.hpp"

#include <stdexcept>
#include <string>

#include <gtest/gtest.h>

namespace lmf {
namespace {

std::string error_of(const std::string& text) {
  try {
    io::JsonReader reader = io::JsonReader::from_string(text, "test.json");
    LocalMapConfig config;
    read_local_map_config(reader, config);
    reader.finish();
    config.validate();
  } catch (const std::invalid_argument& e) {
    return e.what();
  }
  return "no exception";
}

TEST(LocalMapConfigJson, ReadsKnownKeysAndTheExtractionSection) {
  io::JsonReader reader = io::JsonReader::from_string(
      R"({"ship_distance_m": 12.5, "constraints_enabled": false, "max_segments": 40,
          "observation_angular_noise_rad": 0.0, "joint_compatibility_restarts": 0,
          "observation_end_noise_m": 0.04,
          "extraction": {"split_distance_m": 0.08},
          "scan_matching": {"enabled": true, "point_sigma_m": 0.05, "max_iterations": 12,
                            "range_noise_per_m": 0.01, "range_noise_from_residuals": false},
          "see_through": {"enabled": false, "margin_m": 0.4, "min_beams": 8, "min_coverage": 0.5}})",
      "test.json");
  LocalMapConfig config;
  read_local_map_config(reader, config);
  reader.finish();
  EXPECT_EQ(config.ship_distance_m, 12.5);
  EXPECT_FALSE(config.constraints_enabled);
  EXPECT_EQ(config.max_segments, 40u);
  EXPECT_EQ(config.observation_angular_noise_rad, 0.0);
  EXPECT_EQ(config.joint_compatibility_restarts, 0u);
  EXPECT_EQ(config.observation_end_noise_m, 0.04);
  EXPECT_EQ(config.extraction.split_distance_m, 0.08);
  EXPECT_TRUE(config.scan_matching.enabled);
  EXPECT_EQ(config.scan_matching.point_sigma_m, 0.05);
  EXPECT_EQ(config.scan_matching.max_iterations, 12);
  EXPECT_EQ(config.scan_matching.range_noise_per_m, 0.01);
  EXPECT_FALSE(config.scan_matching.range_noise_from_residuals);
  EXPECT_EQ(config.scan_matching.last_gate_m, ScanMatcherConfig{}.last_gate_m);
  EXPECT_FALSE(config.see_through.enabled);
  EXPECT_EQ(config.see_through.margin_m, 0.4);
  EXPECT_EQ(config.see_through.min_beams, 8);
  EXPECT_EQ(config.see_through.min_coverage, 0.5);
  EXPECT_EQ(config.see_through.min_fraction, SeeThroughConfig{}.min_fraction);
  EXPECT_EQ(config.pairing_alpha, LocalMapConfig{}.pairing_alpha);  // absent: default
}

TEST(LocalMapConfigJson, RejectsUnknownKeysAndBadValuesByName) {
  EXPECT_NE(error_of(R"({"ship_distance": 10})").find("ship_distance"), std::string::npos);
  EXPECT_NE(error_of(R"({"pairing_alpha": 1.5})").find("pairing_alpha"), std::string::npos);
  EXPECT_NE(error_of(R"({"max_segments": -3})").find("max_segments"), std::string::npos);
  EXPECT_NE(error_of(R"({"extraction": {"min_points": 1}})").find("min_points"), std::string::npos);
  EXPECT_NE(error_of(R"({"extraction": {"bogus": 1}})").find("bogus"), std::string::npos);
  EXPECT_NE(error_of(R"({"observation_end_noise_m": -0.1})").find("observation_end_noise_m"), std::string::npos);
  EXPECT_NE(error_of(R"({"scan_matching": {"gate": 1}})").find("gate"), std::string::npos);
  EXPECT_NE(error_of(R"({"scan_matching": {"last_gate_m": 5.0}})").find("first_gate_m"), std::string::npos);
  EXPECT_NE(error_of(R"({"scan_matching": {"prior_alpha": 0}})").find("prior_alpha"), std::string::npos);
  EXPECT_NE(error_of(R"({"scan_matching": {"range_noise_per_m": -0.01}})").find("range_noise_per_m"),
            std::string::npos);
  EXPECT_NE(error_of(R"({"see_through": {"bogus": 1}})").find("bogus"), std::string::npos);
  EXPECT_NE(error_of(R"({"see_through": {"min_beams": 0}})").find("min_beams"), std::string::npos);
  EXPECT_NE(error_of(R"({"see_through": {"min_coverage": 2}})").find("min_coverage"), std::string::npos);
  EXPECT_EQ(error_of(R"({})"), "no exception");
}

TEST(LocalMapConfigJson, ShippedConfigFilesLoad) {
  const LocalMapConfig sim = load_local_map_config(LMF_SOURCE_DIR "/tools/lmf_nees_sim.json");
  EXPECT_EQ(sim.extraction.split_distance_m, 0.1);
  EXPECT_EQ(sim.observation_end_noise_m, 0.04);
}

}  // namespace
}  // namespace lmf
