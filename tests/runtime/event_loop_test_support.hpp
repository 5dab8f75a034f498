// Event-loop helpers shared by the runtime, process and fuzz tests.
#pragma once

#include "runtime/event_loop.hpp"

namespace lmf::testing {

// Options for a loop inside a test process: SIGINT/SIGTERM stay with gtest.
inline runtime::EventLoopOptions no_signals() {
  runtime::EventLoopOptions options;
  options.handle_signals = false;
  return options;
}

}  // namespace lmf::testing
