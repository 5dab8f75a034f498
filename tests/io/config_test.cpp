#include "lmf/io/config.hpp"

#include <cstdint>
#include <filesystem>
#include <fstream>
#include <numbers>
#include <string>
#include <vector>

#include <gtest/gtest.h>

namespace lmf::io {
namespace {

// What the message of the std::invalid_argument thrown by f() is ("" if none).
template <typename F>
std::string error_of(F&& f) {
  try {
    f();
  } catch (const std::invalid_argument& e) {
    return e.what();
  }
  return "";
}

enum class Mode { kFast, kCareful };

struct Example {
  double max_range_m = 80.0;
  int seed = 1;
  std::size_t max_segments = 100;
  bool enabled = true;
  std::string name = "default";
  std::vector<double> sigmas = {0.1};
  Pose2 start;
  Mode mode = Mode::kFast;
  double inner_alpha = 0.01;
};

Example parse(JsonReader& r) {
  Example e;
  r.read("max_range_m", e.max_range_m, positive());
  r.read("seed", e.seed);
  r.read("max_segments", e.max_segments, at_least(1));
  r.read("enabled", e.enabled);
  r.read("name", e.name);
  r.read("sigmas", e.sigmas, non_negative());
  r.read("start", e.start);
  r.read_choice("mode", e.mode, {{"fast", Mode::kFast}, {"careful", Mode::kCareful}});
  if (JsonReader* inner = r.optional_section("inner")) inner->read("alpha", e.inner_alpha, in_open(0.0, 1.0));
  r.finish();
  return e;
}

Example parse_text(const std::string& text) {
  JsonReader r = JsonReader::from_string(text, "cfg.json");
  return parse(r);
}

TEST(JsonReader, ReadsTypedFieldsAndKeepsDefaults) {
  const Example e = parse_text(R"({
    // comments are allowed
    "max_range_m": 30, "seed": -7, "max_segments": 12, "enabled": false, "name": "a",
    "sigmas": [0.5, 1], "start": [1, 2, 3.5], "mode": "careful", "inner": {"alpha": 0.05}
  })");
  EXPECT_DOUBLE_EQ(e.max_range_m, 30.0);
  EXPECT_EQ(e.seed, -7);
  EXPECT_EQ(e.max_segments, 12u);
  EXPECT_FALSE(e.enabled);
  EXPECT_EQ(e.name, "a");
  EXPECT_EQ(e.sigmas, (std::vector<double>{0.5, 1.0}));
  EXPECT_DOUBLE_EQ(e.start.x, 1.0);
  EXPECT_NEAR(e.start.phi, 3.5 - 2.0 * std::numbers::pi, 1e-12);
  EXPECT_EQ(e.mode, Mode::kCareful);
  EXPECT_DOUBLE_EQ(e.inner_alpha, 0.05);

  const Example d = parse_text("{}");
  EXPECT_DOUBLE_EQ(d.max_range_m, 80.0);
  EXPECT_EQ(d.name, "default");
  EXPECT_EQ(d.mode, Mode::kFast);
}

TEST(JsonReader, ErrorsNameSourceKeyAndProblem) {
  const std::vector<std::pair<std::string, std::string>> cases = {
      {R"({"max_range_m": "80"})", "cfg.json: max_range_m: expected a number, got string \"80\""},
      {R"({"max_range_m": -1})", "cfg.json: max_range_m: must be > 0, got -1"},
      {R"({"max_range_m": 0})", "cfg.json: max_range_m: must be > 0, got 0"},
      {R"({"seed": 1.5})", "cfg.json: seed: expected an integer, got number 1.5"},
      {R"({"seed": 3000000000})", "cfg.json: seed: integer out of range"},
      {R"({"max_segments": -3})", "cfg.json: max_segments: integer out of range"},
      {R"({"max_segments": 0})", "cfg.json: max_segments: must be >= 1, got 0"},
      {R"({"enabled": 1})", "cfg.json: enabled: expected true or false, got number 1"},
      {R"({"name": null})", "cfg.json: name: expected a string, got null"},
      {R"({"sigmas": [0.1, -2]})", "cfg.json: sigmas[1]: must be >= 0, got -2"},
      {R"({"sigmas": 0.1})", "cfg.json: sigmas: expected an array"},
      {R"({"start": [1, 2]})", "cfg.json: start: expected [x_m, y_m, theta_rad]"},
      {R"({"start": [1, "x", 2]})", "cfg.json: start[1]: expected a number"},
      {R"({"mode": "slow"})", "cfg.json: mode: \"slow\" is not one of \"fast\", \"careful\""},
      {R"({"inner": {"alpha": 1}})", "cfg.json: inner.alpha: must be in (0, 1), got 1"},
      {R"({"inner": 3})", "cfg.json: inner: expected an object, got number 3"},
      {R"({"max_rnage_m": 3})", "cfg.json: unknown key max_rnage_m"},
      {R"({"zz": 1, "inner": {"alpha": 0.5, "beta": 2}})", "cfg.json: unknown keys zz, inner.beta"},
      {R"([1, 2])", "cfg.json: top level: expected a JSON object, got array"},
      {R"({"a": )", "cfg.json: invalid JSON"},
  };
  for (const auto& [text, expected] : cases) {
    const std::string what = error_of([&] { parse_text(text); });
    EXPECT_NE(what.find(expected), std::string::npos) << "input: " << text << "\nexpected: " << expected
                                                      << "\ngot: " << what;
  }
}

TEST(JsonReader, RequiredSectionsArraysAndIgnore) {
  JsonReader r = JsonReader::from_string(
      R"({"robots": [{"id": 1, "log": "a.log"}, {"id": 2, "log": "b.log", "extra": true}], "bus": {"url": "memq://"},
          "note": "for people"})",
      "multi.json");
  EXPECT_EQ(r.required<std::string>("note").size(), 10u);
  EXPECT_EQ(r.section("bus").required<std::string>("url"), "memq://");
  const std::vector<JsonReader*> robots = r.section_array("robots");
  ASSERT_EQ(robots.size(), 2u);
  for (JsonReader* robot : robots) {
    robot->required<int>("id", positive());
    robot->required<std::string>("log");
  }
  EXPECT_EQ(error_of([&] { r.finish(); }), "multi.json: unknown key robots[1].extra");
  robots[1]->ignore("extra");
  EXPECT_EQ(error_of([&] { r.finish(); }), "");
  EXPECT_EQ(error_of([&] { r.required<double>("missing_m"); }), "multi.json: missing_m: missing (required)");
  EXPECT_EQ(error_of([&] { r.section("nope"); }), "multi.json: nope: missing (required section)");
  EXPECT_EQ(r.optional_section("nope"), nullptr);
  EXPECT_TRUE(r.section_array("nope").empty());
  EXPECT_EQ(error_of([&] { r.section_array("note"); }),
            "multi.json: note: expected an array of objects, got string \"for people\"");
}

TEST(JsonReader, NarrowTypesAndFiles) {
  JsonReader r = JsonReader::from_string(R"({"u8": 255, "u8bad": 256, "f": 1e39, "i64": -9000000000})");
  std::uint8_t u8 = 0;
  EXPECT_TRUE(r.read("u8", u8));
  EXPECT_EQ(u8, 255);
  EXPECT_NE(error_of([&] { r.read("u8bad", u8); }).find("integer out of range"), std::string::npos);
  float f = 0;
  EXPECT_NE(error_of([&] { r.read("f", f); }).find("number out of range"), std::string::npos);
  std::int64_t i64 = 0;
  r.read("i64", i64);
  EXPECT_EQ(i64, -9'000'000'000);

  const auto file = std::filesystem::path(::testing::TempDir()) / "lmf_config_test.json";
  std::ofstream(file) << "{\n  \"max_range_m\": 20,\n  /* block */ \"seed\": 4\n}\n";
  JsonReader from_file = JsonReader::from_file(file);
  EXPECT_EQ(parse(from_file).seed, 4);
  std::ofstream(file) << "{\n  \"max_range_m\": 20,\n  \"seed\": \n}\n";
  const std::string what = error_of([&] { JsonReader::from_file(file); });
  EXPECT_EQ(what.rfind(file.string() + ": invalid JSON", 0), 0u) << what;
  EXPECT_NE(what.find("line 4"), std::string::npos) << what;
  std::filesystem::remove(file);
  EXPECT_NE(error_of([&] { JsonReader::from_file("/nonexistent/x.json"); }).find("cannot open"), std::string::npos);
}

}  // namespace
}  // namespace lmf::io
