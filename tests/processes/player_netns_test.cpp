// The real lmf-agent and lmf-player processes over UDP multicast inside a
// private network namespace (scripts/lib/netns.sh) on a tiny simulated
// mission; skipped where namespaces are not allowed. The full system with
// lmf-server is tested elsewhere.
#include <sys/wait.h>

#include <cstdio>
#include <regex>
#include <string>

#include <gtest/gtest.h>

#include "player_test_support.hpp"

namespace {

TEST(PlayerAgentProcesses, LockstepReplayInANetworkNamespace) {
  lmf::testing::TempDir dir("lmf-player-netns");
  lmf::testing::write_sim_mission(dir.path(), 8.0, 4, 2);
  // `timeout` bounds the whole run; the PID namespace of lmf_netns_exec kills
  // whatever is left inside when its first process ends.
  const std::string command = std::string("timeout --kill-after=2 60 bash '") + LMF_SOURCE_DIR +
                              "/tests/processes/player_netns.sh' '" + LMF_AGENT_EXE + "' '" + LMF_PLAYER_EXE +
                              "' '" + dir.path().string() + "' 2>&1";
  FILE* pipe = ::popen(command.c_str(), "r");
  ASSERT_NE(pipe, nullptr);
  std::string output;
  char buffer[512];
  while (std::fgets(buffer, sizeof buffer, pipe) != nullptr) output += buffer;
  const int status = ::pclose(pipe);
  ASSERT_TRUE(WIFEXITED(status)) << output;
  const int code = WEXITSTATUS(status);
  if (code == 77) GTEST_SKIP() << output;
  ASSERT_EQ(code, 0) << (code == 124 ? "timed out\n" : "") << output;

  std::smatch m;
  ASSERT_TRUE(std::regex_search(output, m, std::regex(R"(scans sent (\d+)/(\d+), acked (\d+), resends \d+, given up (\d+))")))
      << output;
  EXPECT_EQ(m[1], m[2]) << output;
  EXPECT_EQ(m[3], m[2]) << "every scan acked\n" << output;
  EXPECT_EQ(m[4], "0") << output;
  EXPECT_GT(std::stoi(m[2].str()), 50) << output;
  // Both agents stopped cleanly on SIGTERM after shipping their last map.
  const std::regex agent_line(R"(lmf-agent (\d): stopped; (\d+) scans, (\d+) local maps shipped.*mission end received)");
  int agents = 0;
  for (auto it = std::sregex_iterator(output.begin(), output.end(), agent_line); it != std::sregex_iterator(); ++it) {
    ++agents;
    EXPECT_GT(std::stoi((*it)[2].str()), 0) << output;
    EXPECT_GE(std::stoi((*it)[3].str()), 1) << output;
  }
  EXPECT_EQ(agents, 2) << output;
  EXPECT_NE(output.find("player exit 0, agent exits 0 0"), std::string::npos) << output;
}

}  // namespace
