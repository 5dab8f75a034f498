#include "lmf/common/config_check.hpp"

#include <stdexcept>
#include <string>

#include <gtest/gtest.h>

#include "lmf/fusion/global_map.hpp"
#include "lmf/scan/segment_extraction.hpp"

namespace {

std::string message_of(const auto& validate) {
  try {
    validate();
  } catch (const std::invalid_argument& e) {
    return e.what();
  }
  return "(no exception)";
}

TEST(ConfigCheck, NamesTheConfigTheFieldItsValueAndTheRule) {
  const lmf::ConfigCheck require("DemoConfig");
  EXPECT_NO_THROW(require(true, "gain", 0.5, "in (0, 1)"));
  EXPECT_NO_THROW(require(true, "no message"));
  EXPECT_EQ(message_of([&] { require(false, "gain", 1.5, "in (0, 1)"); }),
            "DemoConfig.gain = 1.5 is invalid: it must be in (0, 1)");
  EXPECT_EQ(message_of([&] { require(false, "count", -3, ">= 0"); }), "DemoConfig.count = -3 is invalid: it must be >= 0");
  EXPECT_EQ(message_of([&] { require(false, "gain must be in (0, 1)"); }), "DemoConfig: gain must be in (0, 1)");
}

TEST(ConfigCheck, CoreConfigsReportThroughIt) {
  lmf::ExtractionConfig extraction;
  extraction.min_points = 1;
  EXPECT_EQ(message_of([&] { extraction.validate(); }), "ExtractionConfig.min_points = 1 is invalid: it must be >= 2");
  lmf::fusion::GlobalMapConfig global;
  global.alpha = 2.0;
  EXPECT_EQ(message_of([&] { global.validate(); }), "GlobalMapConfig: alpha must be in (0, 1)");
}

}  // namespace
