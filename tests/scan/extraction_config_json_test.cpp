#include "lmf/scan/extraction_config_json.hpp"

#include <filesystem>
#include <fstream>
#include <stdexcept>
#include <string>

#include <unistd.h>

#include <gtest/gtest.h>

namespace lmf {
namespace {

// The exception message of f(), or "" when it does not throw std::invalid_argument.
template <typename F>
std::string error_of(F&& f) {
  try {
    f();
  } catch (const std::invalid_argument& e) {
    return e.what();
  }
  return "";
}

ExtractionConfig parse(const std::string& text) {
  io::JsonReader reader = io::JsonReader::from_string(text, "test.json");
  ExtractionConfig config;
  read_extraction_config(reader, config);
  reader.finish();
  config.validate();
  return config;
}

TEST(ExtractionConfigJson, ReadsFieldsAndKeepsDefaults) {
  const ExtractionConfig c = parse(R"({"split_distance_m": 0.06, "min_points": 8, "range_noise_m": 0.02})");
  EXPECT_DOUBLE_EQ(c.split_distance_m, 0.06);
  EXPECT_EQ(c.min_points, 8);
  EXPECT_DOUBLE_EQ(c.range_noise_m, 0.02);
  EXPECT_DOUBLE_EQ(c.merge_distance_m, ExtractionConfig{}.merge_distance_m);
  EXPECT_DOUBLE_EQ(c.max_range_m, ExtractionConfig{}.max_range_m);
}

TEST(ExtractionConfigJson, RejectsUnknownKeysAndBadValues) {
  EXPECT_NE(error_of([] { parse(R"({"split_distance": 0.06})"); }).find("split_distance"), std::string::npos);
  EXPECT_NE(error_of([] { parse(R"({"split_distance_m": -1})"); }).find("split_distance_m"), std::string::npos);
  EXPECT_NE(error_of([] { parse(R"({"min_points": 2.5})"); }).find("min_points"), std::string::npos);
  EXPECT_NE(error_of([] { parse(R"({"min_points": 1})"); }).find("min_points"), std::string::npos);
  EXPECT_NE(error_of([] { parse(R"({"range_noise_m": "5 cm"})"); }).find("range_noise_m"), std::string::npos);
  // Cross-field checks come from ExtractionConfig::validate().
  EXPECT_NE(error_of([] { parse(R"({"min_range_m": 5, "max_range_m": 4})"); }).find("max_range_m"),
            std::string::npos);
}

TEST(ExtractionConfigJson, LoadsAFile) {
  const std::filesystem::path file =
      std::filesystem::temp_directory_path() / ("lmf_extraction_config_test_" + std::to_string(::getpid()) + ".json");
  {
    std::ofstream out(file);
    out << "// real SICK logs\n{\"split_distance_m\": 0.06, \"merge_distance_m\": 0.06}\n";
  }
  const ExtractionConfig c = load_extraction_config(file);
  EXPECT_DOUBLE_EQ(c.merge_distance_m, 0.06);
  {
    std::ofstream out(file);
    out << R"({"min_range_m": 5, "max_range_m": 4})";
  }
  EXPECT_NE(error_of([&] { load_extraction_config(file); }).find(file.string()), std::string::npos);
  std::filesystem::remove(file);
  EXPECT_THROW(load_extraction_config(file), std::invalid_argument);
}

}  // namespace
}  // namespace lmf
