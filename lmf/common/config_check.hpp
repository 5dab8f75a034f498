// Validation of configuration values with one message format for every
// config struct of the core. Each validate() makes one checker named after its
// struct and states each rule as a condition:
//
//   const ConfigCheck require("ScanMatcherConfig");
//   require(max_iterations >= 1, "max_iterations", max_iterations, ">= 1");
//     // "ScanMatcherConfig.max_iterations = 0 is invalid: it must be >= 1"
//   require(turn_radius_m >= 0.1, "turn_radius_m must be >= 0.1");
//     // "MotionConfig: turn_radius_m must be >= 0.1"
//
// Both throw std::invalid_argument when the condition is false.
#pragma once

#include <sstream>
#include <stdexcept>
#include <string>
#include <string_view>

namespace lmf {

class ConfigCheck {
 public:
  explicit ConfigCheck(std::string_view config) : config_(config) {}

  // "<config>.<field> = <value> is invalid: it must be <requirement>"
  template <typename T>
  void operator()(bool ok, std::string_view field, const T& value, std::string_view requirement) const {
    if (ok) return;
    std::ostringstream msg;
    msg << config_ << '.' << field << " = " << value << " is invalid: it must be " << requirement;
    throw std::invalid_argument(msg.str());
  }

  // "<config>: <what>"
  void operator()(bool ok, std::string_view what) const {
    if (!ok) throw std::invalid_argument(config_ + ": " + std::string(what));
  }

 private:
  std::string config_;
};

}  // namespace lmf
