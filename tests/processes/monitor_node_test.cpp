// lmf-monitor's node: live over memq:// (JSON lines that parse, the table),
// and from an lcm-logger file written here with lcm::LogFile (JSON lines per
// log-time refresh, the map and timing SVGs); the lmf-monitor binary on it.
#include <chrono>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <limits>
#include <sstream>
#include <string>
#include <vector>

#include <gtest/gtest.h>
#include <lcm/lcm-cpp.hpp>
#include <nlohmann/json.hpp>

#include "monitor/monitor_node.hpp"
#include "runtime/auth.hpp"
#include "runtime/bus.hpp"
#include "runtime/channels.hpp"
#include "runtime/convert.hpp"
#include "runtime/event_loop.hpp"
#include "runtime/event_loop_test_support.hpp"

namespace {

namespace rt = lmf::runtime;
using namespace std::chrono_literals;
using lmf::testing::no_signals;

lmf::agent_status_t agent_status(int robot_id, std::int64_t utime, float max_ms) {
  lmf::agent_status_t s{};
  s.utime = utime;
  s.robot_id = robot_id;
  s.joined = robot_id == 0;
  s.scans = 10 * (utime / 1'000'000 + 1);
  s.local_map_segments = 7 + robot_id;
  s.maps_shipped = 3;
  s.maps_acknowledged = 2;
  s.scan_time_p50_ms = 1.5f;
  s.scan_time_p99_ms = 0.8f * max_ms;
  s.scan_time_max_ms = max_ms;
  s.window_scans = 1;
  s.covariance_ok = true;
  s.global_pose.x = 1.0 + robot_id;
  s.global_pose.y = -2.0;
  s.global_pose.phi = 0.25;
  s.mission_done = false;
  s.num_reject_reasons = 1;
  s.reject_reasons = {"decode_failed"};
  s.reject_counts = {2};
  return s;
}

lmf::server_status_t server_status(std::int64_t fusions) {
  lmf::server_status_t s{};
  s.utime = 5;
  s.num_robots_joined = 2;
  s.num_segments = 42;
  s.num_submaps = 6;
  s.num_graph_edges = 9;
  s.fusions = fusions;
  s.last_fusion_ms = 3.25f;
  s.mean_fusion_ms = 2.5f;
  s.queue_length = 1;
  s.covariance_ok = true;
  s.min_eigenvalue = 1e-7f;
  s.num_reject_reasons = 2;
  s.reject_reasons = {"stale_sequence", "unknown_robot"};
  s.reject_counts = {3, 1};
  return s;
}

lmf::global_map_t global_map() {
  lmf::global_map_t m{};
  m.utime = 7;
  m.fusion_count = 4;
  m.num_submaps = 3;
  m.num_graph_edges = 2;
  m.endpoints = {{0.f, 0.f, 5.f, 0.f}, {5.f, 0.f, 5.f, 4.f}, {5.f, 4.f, 0.f, 4.f}};
  m.num_segments = 3;
  return m;
}

// What the monitor's state takes: the message as runtime/convert decodes it.
template <class Msg>
auto decoded(const Msg& msg) {
  auto value = rt::from_message(msg);
  EXPECT_TRUE(value.ok()) << value.rejection().describe();
  return value.value();
}

std::vector<nlohmann::json> parse_lines(const std::string& text) {
  std::vector<nlohmann::json> out;
  std::istringstream in(text);
  for (std::string line; std::getline(in, line);) {
    EXPECT_NO_THROW(out.push_back(nlohmann::json::parse(line))) << line;
  }
  return out;
}

std::string read_file(const std::filesystem::path& file) {
  std::ifstream in(file);
  std::stringstream s;
  s << in.rdbuf();
  return s.str();
}

TEST(MonitorNode, LiveJsonLinesParseAndCarryTheStatus) {
  rt::Bus bus("memq://");
  rt::EventLoop loop(bus, no_signals());
  const rt::Channels channels;
  lmf::monitor::MonitorOptions options;
  options.json = true;
  options.refresh = 50ms;
  std::ostringstream out;
  lmf::monitor::MonitorNode node(bus, loop, channels, options, out);

  lmf::agent_status_t not_finite = agent_status(0, 1'000'000, 12.0f);
  not_finite.scan_time_p99_ms = std::numeric_limits<float>::quiet_NaN();  // refused and counted
  bus.publish(channels.agent_status(), not_finite);
  bus.publish(channels.agent_status(), agent_status(0, 1'000'000, 12.0f));
  bus.publish(channels.agent_status(), agent_status(1, 1'000'000, 20.0f));
  bus.publish(channels.server_status(), server_status(11));
  bus.publish(channels.global_map(), global_map());
  bus.publish_raw(channels.server_status(), {1, 2, 3});  // garbage: counted, not shown
  loop.run_for(180ms);

  const auto lines = parse_lines(out.str());
  ASSERT_GE(lines.size(), 2u);
  const nlohmann::json& j = lines.back();
  ASSERT_EQ(j["robots"].size(), 2u);
  EXPECT_EQ(j["robots"][0]["robot_id"], 0);
  EXPECT_TRUE(j["robots"][0]["joined"]);
  EXPECT_DOUBLE_EQ(j["robots"][0]["scan_p99_ms"].get<double>(), static_cast<double>(0.8f * 12.0f));
  EXPECT_DOUBLE_EQ(j["robots"][1]["scan_max_ms"].get<double>(), 20.0);
  EXPECT_EQ(j["robots"][1]["local_map_segments"], 8);
  EXPECT_EQ(j["robots"][1]["maps_shipped"], 3);
  EXPECT_EQ(j["robots"][1]["maps_acknowledged"], 2);
  EXPECT_EQ(j["robots"][1]["rejects"], 2);
  EXPECT_DOUBLE_EQ(j["robots"][1]["global_pose"][0].get<double>(), 2.0);
  EXPECT_EQ(j["server"]["segments"], 42);
  EXPECT_EQ(j["server"]["submaps"], 6);
  EXPECT_EQ(j["server"]["graph_edges"], 9);
  EXPECT_EQ(j["server"]["fusions"], 11);
  EXPECT_DOUBLE_EQ(j["server"]["last_fusion_ms"].get<double>(), 3.25);
  EXPECT_EQ(j["server"]["queue_length"], 1);
  EXPECT_TRUE(j["server"]["covariance_ok"]);
  EXPECT_EQ(j["server"]["rejects"]["stale_sequence"], 3);
  EXPECT_EQ(j["global_map"]["segments"], 3);
  EXPECT_EQ(j["rejected"]["decode_failed"], 1);
  EXPECT_EQ(j["rejected"]["non_finite"], 1);
  EXPECT_EQ(j["messages"], 6);
}

// Fig. 8's x axis is mission time: a status window is placed at the log time of
// the robot's last acknowledged scan, not at the (wall-clock) time of the status.
TEST(MonitorState, TimingIsPlacedInMissionTime) {
  lmf::monitor::MonitorState state;
  const std::int64_t log_t0 = 1'060'000'000'000'000;  // the log's clock (2003)
  const std::int64_t wall_t0 = 1'764'000'000'000'000;  // the agent's clock now
  for (int k = 0; k < 5; ++k) {
    lmf::scan_ack_t ack{};
    ack.robot_id = 0;
    ack.seq = k;
    ack.utime = log_t0 + k * 10'000'000;  // scans 10 s apart in the log ...
    state.on_scan_ack(decoded(ack), wall_t0 + k * 100'000);
    // ... replayed 0.1 s apart: each status after an ack, with sub-millisecond scans
    state.on_agent_status(decoded(agent_status(0, wall_t0 + k * 100'000 + 50'000, 0.25f)), wall_t0 + k * 100'000 + 50'000);
  }
  EXPECT_TRUE(state.timing_in_mission_time());
  const auto series = state.timing_series();
  ASSERT_EQ(series.at(0).size(), 5u);
  for (int k = 0; k < 5; ++k) EXPECT_NEAR(series.at(0)[static_cast<std::size_t>(k)].time_s, 10.0 * k, 1e-9);

  const auto file = std::filesystem::path(::testing::TempDir()) / "lmf_monitor_timing.svg";
  state.write_timing_svg(file);
  const std::string svg = read_file(file);
  std::filesystem::remove(file);
  EXPECT_NE(svg.find("mission time (s"), std::string::npos);
  EXPECT_NE(svg.find("log scale"), std::string::npos);
  EXPECT_NE(svg.find(">0.01<"), std::string::npos);  // the lowest decade is labelled
  EXPECT_NE(svg.find(">0.1<"), std::string::npos);
  EXPECT_NE(svg.find("200 ms"), std::string::npos);
  EXPECT_NE(svg.find("id=\"legend\""), std::string::npos);

  // A robot that acknowledged no scan: its status times, and the axis says so.
  state.on_agent_status(decoded(agent_status(1, wall_t0, 0.5f)), wall_t0);
  EXPECT_FALSE(state.timing_in_mission_time());
}

TEST(MonitorNode, TableShowsRobotsAndServer) {
  const rt::Channels channels;
  std::ostringstream out;
  lmf::monitor::MonitorNode node(channels, {}, out);
  const auto handle = [&](const std::string& channel, const auto& msg) {
    const auto bytes = rt::encode_message(msg);
    node.handle(channel, bytes.data(), bytes.size(), 1'000'000);
  };
  handle(channels.agent_status(), agent_status(0, 1'000'000, 12.0f));
  handle(channels.agent_status(), agent_status(2, 1'000'000, 30.0f));
  handle(channels.server_status(), server_status(11));
  lmf::scan_ack_t ack{};
  ack.robot_id = 5;
  ack.seq = 17;
  handle(channels.scan_ack(), ack);
  node.refresh(2'000'000);
  const std::string table = out.str();
  EXPECT_NE(table.find("ROBOT"), std::string::npos);
  EXPECT_NE(table.find("SERVER"), std::string::npos);
  EXPECT_NE(table.find("segments 42"), std::string::npos);
  EXPECT_NE(table.find("fusions 11"), std::string::npos);
  EXPECT_NE(table.find("stale_sequence=3"), std::string::npos);
  EXPECT_NE(table.find("3/2"), std::string::npos) << "shipped/acked";
  EXPECT_NE(table.find("last scan 17"), std::string::npos) << "robot heard only through scan acks";
  EXPECT_EQ(table.find("\x1b["), std::string::npos) << "no terminal codes unless redrawing in place";
}

TEST(MonitorNode, ReadsAnLcmLoggerFile) {
  const auto dir = std::filesystem::path(::testing::TempDir()) / "lmf_monitor_log";
  std::filesystem::create_directories(dir);
  const auto log_path = dir / "mission.lcmlog";
  const rt::Channels channels;
  {
    lcm::LogFile log(log_path.string(), "w");
    ASSERT_TRUE(log.good());
    std::int64_t eventnum = 0;
    const auto write = [&](std::int64_t t, const std::string& channel, const auto& msg) {
      auto bytes = rt::encode_message(msg);
      lcm::LogEvent e;
      e.eventnum = eventnum++;
      e.timestamp = t;
      e.channel = channel;
      e.datalen = static_cast<int32_t>(bytes.size());
      e.data = bytes.data();
      ASSERT_EQ(log.writeEvent(&e), 0);
    };
    const std::int64_t t0 = 1'700'000'000'000'000;
    // 3.5 s of a mission: statuses every 200 ms, the server every 500 ms.
    for (int k = 0; k < 18; ++k) {
      const std::int64_t t = t0 + k * 200'000;
      write(t, channels.agent_status(), agent_status(0, t, 10.0f + static_cast<float>(k)));
      write(t + 1000, channels.agent_status(), agent_status(1, t, k == 9 ? 250.0f : 5.0f));
      if (k % 5 == 0) write(t + 2000, channels.server_status(), server_status(k));
      lmf::scan_ack_t ack{};
      ack.utime = t;
      ack.robot_id = 2;  // robot 2 sends no status: timing from its scan acks
      ack.seq = k;
      write(t + 3000, channels.scan_ack(), ack);
    }
    write(t0 + 3'600'000, channels.global_map(), global_map());
    write(t0 + 3'600'000, "OTHER_CHANNEL", global_map());
  }

  lmf::monitor::MonitorOptions options;
  options.json = true;
  options.refresh = 1000ms;
  options.map_svg = dir / "map.svg";
  options.timing_svg = dir / "timing.svg";
  std::ostringstream out;
  lmf::monitor::MonitorNode node(channels, options, out);
  EXPECT_EQ(node.replay_log(log_path), 18 * 3 + 4 + 2);

  const auto lines = parse_lines(out.str());
  ASSERT_EQ(lines.size(), 4u) << "refreshes at +1, +2, +3 s of log time and one at the end";
  EXPECT_EQ(lines.front()["server"]["fusions"], 0);
  const nlohmann::json& last = lines.back();
  EXPECT_EQ(last["server"]["fusions"], 15);
  EXPECT_EQ(last["global_map"]["segments"], 3);
  EXPECT_EQ(last["robots"].size(), 3u);
  EXPECT_EQ(last["robots"][2]["scan_acks"], 18);
  EXPECT_FALSE(last["robots"][2]["have_status"]);
  EXPECT_EQ(last["messages"], 18 * 3 + 4 + 2);

  const auto series = node.state().timing_series();
  ASSERT_EQ(series.size(), 3u);
  EXPECT_EQ(series.at(0).size(), 18u);
  EXPECT_EQ(series.at(2).size(), 17u);  // gaps between consecutive acks
  EXPECT_NEAR(series.at(2).front().value_ms, 200.0, 1e-9);
  EXPECT_NEAR(series.at(0).back().time_s, 3.4, 1e-9);

  const std::string timing = read_file(dir / "timing.svg");
  EXPECT_EQ(timing.rfind("<svg", 0), 0u);
  EXPECT_NE(timing.find("200 ms"), std::string::npos);
  EXPECT_NE(timing.find("robot 1"), std::string::npos);
  const std::string map = read_file(dir / "map.svg");
  EXPECT_EQ(map.rfind("<svg", 0), 0u);
  EXPECT_NE(map.find("<line"), std::string::npos);

  std::ostringstream table_out;
  lmf::monitor::MonitorNode table_node(channels, {}, table_out);
  table_node.replay_log(log_path);
  EXPECT_NE(table_out.str().find("fusions 15"), std::string::npos);

#ifdef LMF_MONITOR_EXE
  // The binary on the same file: JSON lines on stdout that parse.
  const std::string command = std::string(LMF_MONITOR_EXE) + " --log " + log_path.string() + " --json 2>/dev/null";
  FILE* pipe = popen(command.c_str(), "r");
  ASSERT_NE(pipe, nullptr);
  std::string output;
  char buffer[4096];
  while (std::fgets(buffer, sizeof buffer, pipe) != nullptr) output += buffer;
  EXPECT_EQ(pclose(pipe), 0);
  const auto exe_lines = parse_lines(output);
  ASSERT_EQ(exe_lines.size(), 4u);
  EXPECT_EQ(exe_lines.back()["server"]["fusions"], 15);
  EXPECT_NE(std::system((std::string(LMF_MONITOR_EXE) + " --log /nonexistent.log 2>/dev/null").c_str()), 0);
#endif
}

// A capture of a system running with --keys: with the monitor's keys only
// correctly signed, fresh, allowed messages count; without keys every message
// is read (its trailer stripped unchecked).
TEST(MonitorNode, ChecksTheSignaturesOfACaptureWithKeys) {
  namespace auth = rt::auth;
  const auto dir = std::filesystem::path(::testing::TempDir()) / "lmf_monitor_signed_log";
  std::filesystem::create_directories(dir);
  const auto log_path = dir / "signed.lcmlog";
  const rt::Channels channels;
  const auto files = auth::make_system_keys({0, 1});
  const auto key_of = [&](const std::string& principal) { return *files.at(principal).find(principal); };
  auth::Signer robot0(auth::robot_principal(0), key_of(auth::robot_principal(0)), 1);
  auth::Signer robot1(auth::robot_principal(1), key_of(auth::robot_principal(1)), 1);
  {
    lcm::LogFile log(log_path.string(), "w");
    ASSERT_TRUE(log.good());
    std::int64_t eventnum = 0;
    const auto write = [&](const std::string& channel, const std::vector<std::uint8_t>& bytes) {
      lcm::LogEvent e;
      e.eventnum = eventnum;
      e.timestamp = 1'700'000'000'000'000 + 100'000 * eventnum;
      ++eventnum;
      e.channel = channel;
      e.datalen = static_cast<int32_t>(bytes.size());
      e.data = const_cast<std::uint8_t*>(bytes.data());
      ASSERT_EQ(log.writeEvent(&e), 0);
    };
    const auto signed_by = [&](auth::Signer& signer, const std::string& channel, const auto& msg) {
      const std::vector<std::uint8_t> payload = rt::encode_message(msg);
      std::vector<std::uint8_t> out;
      signer.sign(channel, payload, out);
      return out;
    };
    const std::vector<std::uint8_t> good = signed_by(robot0, channels.agent_status(), agent_status(0, 1, 5.0f));
    write(channels.agent_status(), good);
    write(channels.agent_status(), signed_by(robot1, channels.agent_status(), agent_status(1, 2, 5.0f)));
    write(channels.agent_status(), good);  // replayed
    std::vector<std::uint8_t> tampered = signed_by(robot0, channels.agent_status(), agent_status(0, 3, 5.0f));
    tampered[10] ^= 0x01;
    write(channels.agent_status(), tampered);
    write(channels.agent_status(), rt::encode_message(agent_status(1, 4, 5.0f)));  // unsigned
    // A robot may not speak for the server.
    write(channels.server_status(), signed_by(robot1, channels.server_status(), server_status(7)));
    // LCM's own self test, outside the system's channels: counted, not checked.
    write("LCM_SELF_TEST", std::vector<std::uint8_t>{'l', 'c', 'm'});
  }

  lmf::monitor::MonitorOptions options;
  options.json = true;
  const auto monitor_keys = auth::Config{"monitor", std::make_shared<const auth::KeyRing>(files.at("monitor"))};
  std::ostringstream checked_out;
  lmf::monitor::MonitorNode checked(channels, options, checked_out);
  EXPECT_EQ(checked.replay_log(log_path, monitor_keys), 7);
  EXPECT_EQ(checked.log_rejections().total(), 4);
  EXPECT_EQ(parse_lines(checked_out.str()).back()["messages"], 3);
  EXPECT_TRUE(parse_lines(checked_out.str()).back()["server"].is_null()) << "the forged server status was skipped";

  std::ostringstream unchecked_out;
  lmf::monitor::MonitorNode unchecked(channels, options, unchecked_out);
  EXPECT_EQ(unchecked.replay_log(log_path), 7);
  EXPECT_EQ(unchecked.log_rejections().total(), 0);
  EXPECT_EQ(parse_lines(unchecked_out.str()).back()["messages"], 7);
  EXPECT_EQ(parse_lines(unchecked_out.str()).back()["server"]["fusions"], 7);
}

}  // namespace
