// Two processes pass LCM messages over UDP multicast inside a private network
// namespace (scripts/lib/netns.sh); skipped where namespaces are not allowed.
#include <sys/wait.h>

#include <cstdio>
#include <cstdlib>
#include <string>

#include <gtest/gtest.h>

namespace {

TEST(NetworkSandbox, TwoProcessesExchangeAMessage) {
  // `timeout` bounds the whole exchange; the PID namespace of lmf_netns_exec
  // kills whatever is left inside when its first process ends.
  const std::string command = std::string("timeout --kill-after=2 20 bash '") + LMF_SOURCE_DIR +
                              "/tests/runtime/netns_pingpong.sh' '" + LMF_RUNTIME_PEER + "' 2>&1";
  FILE* pipe = ::popen(command.c_str(), "r");
  ASSERT_NE(pipe, nullptr);
  std::string output;
  char buffer[256];
  while (std::fgets(buffer, sizeof buffer, pipe) != nullptr) output += buffer;
  const int status = ::pclose(pipe);
  ASSERT_TRUE(WIFEXITED(status)) << output;
  const int code = WEXITSTATUS(status);
  if (code == 77) GTEST_SKIP() << output;
  EXPECT_EQ(code, 0) << (code == 124 ? "timed out\n" : "") << output;
  EXPECT_NE(output.find("ping: answer for seq"), std::string::npos) << output;
  EXPECT_NE(output.find("LCM_DEFAULT_URL=udpm://239.255.76.67:7667?ttl=0"), std::string::npos) << output;
}

}  // namespace
