// The player, two agents and a fake fusion server (GlobalMap behind the LCM
// protocol) wired on ONE memq:// bus, replaying a short simulated mission:
// lockstep equals lmf-offline, resends and simulated loss still fuse every
// local map exactly once, the player resends unacknowledged scans, --rate mode.
#include <chrono>
#include <cstdint>
#include <iostream>
#include <memory>
#include <sstream>
#include <string>
#include <vector>

#include <gtest/gtest.h>

#include "lmf/mission/mission_inputs.hpp"
#include "lmf/mission/offline_mission.hpp"
#include "log_player/player_node.hpp"
#include "player_test_support.hpp"
#include "robot_agent/agent_node.hpp"
#include "runtime/bus.hpp"
#include "runtime/event_loop.hpp"

namespace {

using namespace std::chrono_literals;
namespace rt = lmf::runtime;
using lmf::log_player::PlayerNode;
using lmf::log_player::PlayerOptions;
using lmf::robot_agent::AgentNode;
using lmf::robot_agent::AgentOptions;
using lmf::testing::FakeServer;
using lmf::testing::run_until;

// The shared inputs: a 60 s two-robot simulated mission, as the player loads it.
class PlayerMission : public ::testing::Test {
 protected:
  static void SetUpTestSuite() {
    dir_ = std::make_unique<lmf::testing::TempDir>("lmf-player-test");
    config_ = std::make_unique<lmf::mission::MissionConfig>(lmf::testing::short_mission_config());
    inputs_ =
        std::make_unique<lmf::mission::MissionInputs>(lmf::testing::load_short_sim_mission(dir_->path(), *config_));
  }
  static void TearDownTestSuite() {
    inputs_.reset();
    config_.reset();
    dir_.reset();
  }

  // Everything on one bus and one loop; the player stops nothing.
  struct System {
    rt::Bus bus{"memq://"};
    rt::EventLoop loop{bus, rt::EventLoopOptions{false}};
    std::unique_ptr<FakeServer> server;
    std::vector<std::unique_ptr<AgentNode>> agents;
    std::unique_ptr<PlayerNode> player;

    bool all_done() const {
      if (!player->finished()) return false;
      for (const auto& a : agents) {
        if (!a->mission_done()) return false;
      }
      return true;
    }
  };

  static std::unique_ptr<System> make_system(const PlayerOptions& player_options, double drop = 0.0,
                                             bool with_agents = true) {
    auto system = std::make_unique<System>();
    system->server = std::make_unique<FakeServer>(system->bus, config_->global_map, rt::Channels());
    if (with_agents) {
      for (const auto& robot : inputs_->robots) {
        system->agents.push_back(std::make_unique<AgentNode>(system->bus, system->loop,
                                                             agent_options(robot.robot_id, drop)));
      }
    }
    system->player = std::make_unique<PlayerNode>(system->bus, system->loop, *inputs_, player_options);
    return system;
  }

  static AgentOptions agent_options(int robot_id, double drop = 0.0) {
    AgentOptions options;
    options.robot_id = robot_id;
    options.local_map = config_->local_map;
    options.resend_interval = 30ms;
    options.drop_local_maps = drop;
    options.drop_seed = 11 + static_cast<std::uint64_t>(robot_id);
    return options;
  }

  static PlayerOptions lockstep_options() {
    PlayerOptions options;
    options.lockstep = true;
    options.ack_timeout = 1000ms;
    options.mission_end_interval = 20ms;
    options.mission_end_repeats = 3;
    return options;
  }

  // Every local map every agent shipped was fused exactly once and acked.
  static void expect_every_map_fused_once(const System& s) {
    std::int64_t shipped = 0;
    for (const auto& agent : s.agents) {
      const auto& c = agent->counters();
      EXPECT_TRUE(agent->mission_done()) << "robot " << agent->robot_id();
      EXPECT_EQ(c.maps_acknowledged, c.maps_shipped) << "robot " << agent->robot_id();
      EXPECT_EQ(c.ship_failures, 0);
      EXPECT_EQ(agent->rejects().total(), 0);
      for (std::int64_t seq = 0; seq < c.maps_shipped; ++seq) {
        const auto it = s.server->fused().find({agent->robot_id(), seq});
        ASSERT_NE(it, s.server->fused().end()) << "robot " << agent->robot_id() << " map " << seq << " not fused";
        EXPECT_EQ(it->second, 1) << "robot " << agent->robot_id() << " map " << seq;
      }
      shipped += c.maps_shipped;
    }
    EXPECT_EQ(static_cast<std::int64_t>(s.server->fused().size()), shipped) << "no other map was fused";
    EXPECT_EQ(s.server->fusions(), shipped);
    EXPECT_EQ(s.server->map().queued_count(), 0);
    EXPECT_EQ(s.server->rejected(), 0);
  }

  static std::unique_ptr<lmf::testing::TempDir> dir_;
  static std::unique_ptr<lmf::mission::MissionConfig> config_;
  static std::unique_ptr<lmf::mission::MissionInputs> inputs_;
};

std::unique_ptr<lmf::testing::TempDir> PlayerMission::dir_;
std::unique_ptr<lmf::mission::MissionConfig> PlayerMission::config_;
std::unique_ptr<lmf::mission::MissionInputs> PlayerMission::inputs_;

TEST_F(PlayerMission, LockstepAcksEverythingAndEqualsOffline) {
  ASSERT_EQ(inputs_->robots.size(), 2u);
  ASSERT_FALSE(inputs_->sightings.empty()) << "robot 1 needs a sighting to join";
  PlayerOptions options = lockstep_options();
  options.min_ack_timeout = options.ack_timeout;  // a scan acked within 1 s is never resent
  auto s = make_system(options);
  s->player->start();
  ASSERT_TRUE(run_until(s->loop, [&] { return s->all_done(); }, 60s)) << s->player->summary();

  const auto& pc = s->player->counters();
  EXPECT_EQ(pc.scans_sent, pc.scans_total);
  EXPECT_EQ(pc.scans_acked, pc.scans_total);
  EXPECT_EQ(pc.scans_given_up, 0);
  EXPECT_EQ(pc.scan_resends, 0);
  EXPECT_EQ(pc.mission_end_sent, 3);
  EXPECT_EQ(pc.sightings_published + pc.sightings_skipped, pc.sightings_total);
  EXPECT_GT(pc.sightings_published, 0);
  EXPECT_EQ(pc.sightings_approximate, 0);
  EXPECT_EQ(pc.sightings_acked, pc.sightings_published);
  EXPECT_EQ(pc.sighting_resends, 0);
  EXPECT_EQ(s->server->sightings(), pc.sightings_published);
  EXPECT_EQ(s->player->rejects().total(), 0);
  for (const auto& agent : s->agents) {
    const auto& robot = inputs_->robots[static_cast<std::size_t>(agent->robot_id())];
    EXPECT_EQ(agent->counters().scans_processed, static_cast<std::int64_t>(robot.scans.size()));
    EXPECT_EQ(agent->counters().scans_duplicate, 0);
    EXPECT_GE(agent->counters().maps_shipped, 2);
  }
  expect_every_map_fused_once(*s);
  // The scan poses travelled: every scan belongs to exactly one fused local map.
  std::size_t poses = 0;
  for (const auto& [key, list] : s->server->scan_poses()) poses += list.size();
  EXPECT_EQ(static_cast<std::int64_t>(poses), pc.scans_total);

  // Lockstep with a FIFO server is lmf-offline over the same (wire-rounded) inputs.
  lmf::mission::OfflineMission offline(*config_, lmf::testing::as_sent(*inputs_));
  const lmf::mission::MissionResult expected = offline.run();
  EXPECT_EQ(s->server->fusions(), static_cast<std::int64_t>(expected.fusions.size()));
  for (const auto& r : expected.robots) {
    EXPECT_EQ(s->agents[static_cast<std::size_t>(r.robot_id)]->counters().maps_shipped,
              static_cast<std::int64_t>(r.local_maps_shipped));
    EXPECT_EQ(s->server->map().is_joined(r.robot_id), r.joined);
  }
  const auto counts = s->server->map().counts();
  const auto offline_counts = offline.global_map().counts();
  EXPECT_EQ(counts.segments, offline_counts.segments);
  EXPECT_EQ(counts.submaps, offline_counts.submaps);
  EXPECT_EQ(counts.robots_joined, offline_counts.robots_joined);
  // Same decisions, same counts, and the same frames: lmf-offline fuses what
  // local_map_t carries (float segment lengths) from scans at the precision
  // laser_scan_t carries them (at_message_precision).
  for (const auto& frame : offline.global_map().corrected_frames()) {
    const auto ours = s->server->map().corrected_frame(frame.robot_id);
    ASSERT_TRUE(ours.has_value());
    EXPECT_EQ(ours->map_seq, frame.map_seq);
    EXPECT_TRUE(lmf::is_near(ours->x_WL, frame.x_WL, 1e-9, 1e-9))
        << "robot " << frame.robot_id << ": " << ours->x_WL.x - frame.x_WL.x << " " << ours->x_WL.y - frame.x_WL.y
        << " " << ours->x_WL.phi - frame.x_WL.phi;
  }
  // The agents know where they are: x_WL of their current map ⊕ x_LR.
  for (const auto& agent : s->agents) {
    if (!s->server->map().is_joined(agent->robot_id())) continue;
    ASSERT_TRUE(agent->global_pose().has_value()) << "robot " << agent->robot_id();
    const auto frame = s->server->map().corrected_frame(agent->robot_id());
    EXPECT_TRUE(lmf::is_near(*agent->global_pose(), lmf::compose(frame->x_WL, agent->local_map().x_LR()), 1e-9,
                             1e-9));
  }
}

TEST_F(PlayerMission, ResendsWhenTheServerIgnoresTheFirstTransmission) {
  auto s = make_system(lockstep_options());
  s->server->ignore_first_transmissions(1);
  s->player->start();
  ASSERT_TRUE(run_until(s->loop, [&] { return s->all_done(); }, 60s)) << s->player->summary();
  EXPECT_EQ(s->player->counters().scans_acked, s->player->counters().scans_total);
  expect_every_map_fused_once(*s);
  for (const auto& agent : s->agents) {
    EXPECT_GE(agent->counters().map_resends, agent->counters().maps_shipped) << "robot " << agent->robot_id();
  }
  for (const auto& [key, n] : s->server->received()) EXPECT_GE(n, 2) << "map " << key.second;
}

// A sighting sent while the server could not take it (down, restarting) is
// resent until answered: robot 1 joins only through it.
TEST_F(PlayerMission, ResendsASightingUntilTheServerAnswers) {
  PlayerOptions options = lockstep_options();
  options.ack_timeout = 100ms;
  auto s = make_system(options);
  s->server->ignore_first_sighting_transmissions(2);
  s->player->start();
  ASSERT_TRUE(run_until(s->loop, [&] { return s->all_done(); }, 60s)) << s->player->summary();
  const auto& pc = s->player->counters();
  ASSERT_GT(pc.sightings_published, 0);
  EXPECT_EQ(pc.sightings_acked, pc.sightings_published);
  EXPECT_EQ(pc.sighting_resends, 2 * pc.sightings_published);
  EXPECT_EQ(pc.sightings_unanswered, 0);
  EXPECT_EQ(pc.mission_end_sent, options.mission_end_repeats);
  EXPECT_EQ(s->player->rejects().total(), 0);
  EXPECT_EQ(s->server->sightings(), pc.sightings_published) << "each applied once";
  for (const auto& [key, n] : s->server->sightings_received()) EXPECT_EQ(n, 3) << "sighting at " << std::get<0>(key);
  EXPECT_TRUE(s->server->map().is_joined(1));
  expect_every_map_fused_once(*s);
}

// Answers that come after the last scan: the mission end waits for them, then
// goes out once (mission_end_repeats sends), however the resend timer falls.
TEST_F(PlayerMission, TheMissionEndWaitsForTheLastSightingAnswer) {
  PlayerOptions options = lockstep_options();
  options.ack_timeout = 1500ms;  // longer than the replay (about 0.5 s here), so every answer comes after it
  auto s = make_system(options);
  s->server->ignore_first_sighting_transmissions(1);
  s->player->start();
  ASSERT_TRUE(run_until(s->loop, [&] { return s->all_done(); }, 60s)) << s->player->summary();
  s->loop.run_for(2 * options.ack_timeout);
  const auto& pc = s->player->counters();
  ASSERT_GT(pc.sightings_published, 0);
  EXPECT_EQ(pc.sightings_acked, pc.sightings_published);
  EXPECT_EQ(pc.sighting_resends, pc.sightings_published);
  EXPECT_EQ(pc.mission_end_sent, options.mission_end_repeats);
  EXPECT_TRUE(s->server->map().is_joined(1));
}

// Unanswered sightings are bounded by a queue, not by a send count: with room
// for one, publishing the next gives the oldest up; the last one still waits
// (and so does the mission end) while the server stays silent.
TEST_F(PlayerMission, AFullQueueOfUnansweredSightingsGivesUpTheOldest) {
  ASSERT_GE(inputs_->sightings.size(), 2u);
  PlayerOptions options = lockstep_options();
  options.ack_timeout = 5ms;
  options.max_pending_sightings = 1;
  auto s = make_system(options);
  s->server->ignore_first_sighting_transmissions(1'000'000);
  s->player->start();
  const auto published_all = [&] {
    const auto& c = s->player->counters();
    return c.sightings_published + c.sightings_skipped == static_cast<std::int64_t>(inputs_->sightings.size()) &&
           c.scans_acked == c.scans_total;
  };
  ASSERT_TRUE(run_until(s->loop, published_all, 60s)) << s->player->summary();
  s->loop.run_for(20 * options.ack_timeout);  // well beyond the old limit of 10 sends
  const auto& pc = s->player->counters();
  ASSERT_GE(pc.sightings_published, 2);
  EXPECT_EQ(pc.sightings_unanswered, pc.sightings_published - 1);
  EXPECT_EQ(pc.sightings_acked, 0);
  EXPECT_FALSE(s->player->finished()) << "the mission end waits for the last sighting's answer";
  EXPECT_EQ(pc.mission_end_sent, 0);
}

// With an end wait, the sightings still unanswered that long after the last
// scan are given up, and the mission ends.
TEST_F(PlayerMission, AfterTheEndWaitTheUnansweredSightingsAreGivenUpAndTheMissionEnds) {
  PlayerOptions options = lockstep_options();
  options.ack_timeout = 5ms;
  options.end_wait = 100ms;
  auto s = make_system(options);
  s->server->ignore_first_sighting_transmissions(1'000'000);
  s->player->start();
  ASSERT_TRUE(run_until(s->loop, [&] { return s->player->finished(); }, 60s)) << s->player->summary();
  const auto& pc = s->player->counters();
  ASSERT_GT(pc.sightings_published, 0);
  EXPECT_EQ(pc.sightings_unanswered, pc.sightings_published);
  EXPECT_GE(pc.sighting_resends, pc.sightings_published * (options.end_wait / options.ack_timeout) / 2);
  EXPECT_EQ(pc.sightings_acked, 0);
  EXPECT_EQ(pc.mission_end_sent, options.mission_end_repeats);
  EXPECT_EQ(s->server->sightings(), 0);
}

// A sighting is resent until the server answers, however long that takes (a
// server down for far more than --max-attempts x --ack-timeout-ms), with the
// default options otherwise.
TEST_F(PlayerMission, ASightingIsResentUntilAnsweredHoweverLong) {
  PlayerOptions options = lockstep_options();
  options.ack_timeout = 5ms;
  ASSERT_GT(options.max_attempts, 0);
  auto s = make_system(options);
  const int ignored = 6 * options.max_attempts;
  s->server->ignore_first_sighting_transmissions(ignored);
  s->player->start();
  ASSERT_TRUE(run_until(s->loop, [&] { return s->all_done(); }, 60s)) << s->player->summary();
  const auto& pc = s->player->counters();
  ASSERT_GT(pc.sightings_published, 0);
  EXPECT_EQ(pc.sightings_unanswered, 0);
  EXPECT_EQ(pc.sightings_acked, pc.sightings_published);
  EXPECT_GE(pc.sighting_resends, ignored * pc.sightings_published);
  for (const auto& [key, n] : s->server->sightings_received()) {
    EXPECT_GE(n, ignored + 1) << "sighting at " << std::get<0>(key);
  }
  EXPECT_EQ(s->server->sightings(), pc.sightings_published) << "each applied once";
  EXPECT_TRUE(s->server->map().is_joined(1));
  expect_every_map_fused_once(*s);
}

// A player stopped halfway and started again on the same log, from seq 0: the
// agents re-ack what they already processed with the answers they had then,
// so the new player is led through it, continues where the agents are, and
// the mission ends as an uninterrupted one (every scan processed once, every
// map fused once, the sightings' answers DUPLICATE or APPLIED).
TEST_F(PlayerMission, AgentsResynchroniseWhenThePlayerRestartsTheLog) {
  PlayerOptions options = lockstep_options();
  auto s = make_system(options);
  s->player->start();
  const std::int64_t total = s->player->counters().scans_total;
  ASSERT_TRUE(run_until(s->loop, [&] { return s->player->counters().scans_acked >= total / 2; }, 60s));
  const std::int64_t acked_before = s->player->counters().scans_acked;
  s->player.reset();
  s->player = std::make_unique<PlayerNode>(s->bus, s->loop, *inputs_, options);
  s->player->start();
  ASSERT_TRUE(run_until(s->loop, [&] { return s->all_done(); }, 60s)) << s->player->summary();

  const auto& pc = s->player->counters();
  EXPECT_EQ(pc.scans_acked, pc.scans_total);
  EXPECT_EQ(pc.scans_given_up, 0);
  EXPECT_EQ(pc.sightings_unanswered, 0);
  std::int64_t duplicates = 0;
  for (const auto& agent : s->agents) {
    const auto& robot = inputs_->robots[static_cast<std::size_t>(agent->robot_id())];
    EXPECT_EQ(agent->counters().scans_processed, static_cast<std::int64_t>(robot.scans.size()));
    duplicates += agent->counters().scans_duplicate;
  }
  EXPECT_GE(duplicates, acked_before) << "what was done is re-acked, not reprocessed";
  expect_every_map_fused_once(*s);
  EXPECT_TRUE(s->server->map().is_joined(1));
}

TEST_F(PlayerMission, DroppedLocalMapTransmissionsAreStillFusedExactlyOnce) {
  auto s = make_system(lockstep_options(), 0.1);
  s->player->start();
  ASSERT_TRUE(run_until(s->loop, [&] { return s->all_done(); }, 60s)) << s->player->summary();
  EXPECT_EQ(s->player->counters().scans_acked, s->player->counters().scans_total);
  expect_every_map_fused_once(*s);
  std::int64_t dropped = 0;
  for (const auto& agent : s->agents) dropped += agent->counters().map_transmissions_dropped;
  EXPECT_GT(dropped, 0) << "the simulated loss dropped nothing: pick another seed";
}

TEST_F(PlayerMission, LockstepUnderTwentyPercentScanLossEqualsTheLosslessRunAndKeepsItsPace) {
  // One in five scan transmissions (first sends and resends) never reaches
  // the bus. The resend wait follows the measured ack round trip (about a
  // millisecond on memq://), so each loss costs milliseconds, not the 1 s
  // ack_timeout: the replay stays within a few times the lossless one, and
  // since lockstep keeps the order, the map is the same.
  const auto timed_run = [](const PlayerOptions& options) {
    auto s = make_system(options);
    const auto start = std::chrono::steady_clock::now();
    s->player->start();
    EXPECT_TRUE(run_until(s->loop, [&] { return s->all_done(); }, 120s)) << s->player->summary();
    return std::pair{std::move(s), std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count()};
  };
  const auto [lossless, lossless_s] = timed_run(lockstep_options());
  PlayerOptions lossy_options = lockstep_options();
  lossy_options.drop_scans = 0.2;
  lossy_options.drop_seed = 5;
  const auto [lossy, lossy_s] = timed_run(lossy_options);

  const auto& pc = lossy->player->counters();
  EXPECT_GT(pc.scan_transmissions_dropped, pc.scans_total / 10);
  EXPECT_GE(pc.scan_resends, pc.scan_transmissions_dropped);  // every loss resent (and a slow ack may be)
  EXPECT_EQ(pc.scans_given_up, 0);
  EXPECT_EQ(pc.scans_acked, pc.scans_total);
  expect_every_map_fused_once(*lossy);
  EXPECT_EQ(lossy->server->fusions(), lossless->server->fusions());
  EXPECT_EQ(lossy->server->map().counts().segments, lossless->server->map().counts().segments);
  for (const auto& frame : lossless->server->map().corrected_frames()) {
    const auto ours = lossy->server->map().corrected_frame(frame.robot_id);
    ASSERT_TRUE(ours.has_value());
    EXPECT_EQ(ours->map_seq, frame.map_seq);
    EXPECT_TRUE(lmf::is_near(ours->x_WL, frame.x_WL, 1e-9, 1e-9)) << "robot " << frame.robot_id;
  }
  // The pace: a fixed 1 s wait per loss would take pc.scan_resends seconds more.
  std::cout << "lockstep: lossless " << lossless_s << " s, 20 % scan loss " << lossy_s << " s ("
            << pc.scan_transmissions_dropped << " of " << pc.scans_sent + pc.scan_resends << " sends lost)\n";
  EXPECT_LT(lossy_s, 3.0 * lossless_s + 1.0);
  EXPECT_LT(lossy_s, 0.5 * static_cast<double>(pc.scan_resends)) << "the losses waited about ack_timeout";
}

TEST_F(PlayerMission, PlayerResendsScansUntilALateAgentAcks) {
  PlayerOptions options = lockstep_options();
  options.ack_timeout = 40ms;
  auto s = make_system(options, 0.0, false);
  s->agents.push_back(std::make_unique<AgentNode>(s->bus, s->loop, agent_options(0)));
  s->player->start();
  // Robot 1's agent starts 200 ms late: its first scan is resent until then.
  s->loop.after(200ms, [&] { s->agents.push_back(std::make_unique<AgentNode>(s->bus, s->loop, agent_options(1))); });
  ASSERT_TRUE(run_until(s->loop, [&] { return s->all_done() && s->agents.size() == 2; }, 60s))
      << s->player->summary();
  const auto& pc = s->player->counters();
  EXPECT_GE(pc.scan_resends, 2);
  EXPECT_EQ(pc.scans_given_up, 0);
  EXPECT_EQ(pc.scans_acked, pc.scans_total);
  expect_every_map_fused_once(*s);
}

TEST_F(PlayerMission, LockstepGivesUpOnAScanAfterMaxAttempts) {
  PlayerOptions options = lockstep_options();
  options.ack_timeout = 5ms;
  options.max_attempts = 2;
  // Only robot 0 has an agent: each of robot 1's scans is sent twice, then skipped.
  auto s = make_system(options, 0.0, false);
  s->agents.push_back(std::make_unique<AgentNode>(s->bus, s->loop, agent_options(0)));
  s->player->start();
  ASSERT_TRUE(run_until(s->loop, [&] { return s->player->finished(); }, 60s)) << s->player->summary();
  const auto& pc = s->player->counters();
  const auto robot1_scans = static_cast<std::int64_t>(inputs_->robots[1].scans.size());
  EXPECT_EQ(pc.scans_given_up, robot1_scans);
  EXPECT_EQ(pc.scan_resends, robot1_scans);
  EXPECT_EQ(pc.scans_acked, pc.scans_total - robot1_scans);
  // Without robot 1's acks its sightings cannot be filled.
  EXPECT_EQ(pc.sightings_published, 0);
  EXPECT_EQ(pc.sightings_skipped, pc.sightings_total);
}

TEST_F(PlayerMission, RateModeReplaysAtLogTimeOverRate) {
  PlayerOptions options;
  options.rate = 30.0;  // 60 s of log in ~2 s
  options.ack_timeout = 500ms;
  options.mission_end_interval = 20ms;
  std::ostringstream progress;
  options.progress = PlayerOptions::Progress::kSteps;
  options.progress_stream = &progress;
  auto s = make_system(options);
  const auto start = std::chrono::steady_clock::now();
  s->player->start();
  ASSERT_TRUE(run_until(s->loop, [&] { return s->all_done(); }, 60s)) << s->player->summary();
  const double elapsed_s = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  const auto& robot0 = inputs_->robots[0].scans;
  const double log_s = static_cast<double>(robot0.back().utime - robot0.front().utime) * 1e-6;
  EXPECT_GE(elapsed_s, log_s / options.rate * 0.95);
  const auto& pc = s->player->counters();
  EXPECT_EQ(pc.scans_sent, pc.scans_total);
  EXPECT_EQ(pc.scans_acked, pc.scans_total) << "memq loses nothing";
  EXPECT_GT(pc.sightings_published, 0);
  expect_every_map_fused_once(*s);
  // A line per 10 % when the output is not a terminal.
  const std::string text = progress.str();
  EXPECT_NE(text.find("(100.0 %)"), std::string::npos) << text;
  EXPECT_GE(std::count(text.begin(), text.end(), '\n'), 10) << text;
  EXPECT_EQ(text.find('\r'), std::string::npos);
}

TEST(PlayerNodeOptions, AreValidated) {
  rt::Bus bus("memq://");
  rt::EventLoop loop(bus, rt::EventLoopOptions{false});
  lmf::mission::MissionInputs inputs;
  EXPECT_THROW(PlayerNode(bus, loop, inputs, PlayerOptions()), std::invalid_argument) << "no robots";
  inputs.robots.resize(2);
  inputs.robots[0].robot_id = 3;
  inputs.robots[1].robot_id = 3;
  EXPECT_THROW(PlayerNode(bus, loop, inputs, PlayerOptions()), std::invalid_argument) << "duplicate ids";
  inputs.robots[1].robot_id = 4;
  PlayerOptions bad;
  bad.rate = 0.0;
  EXPECT_THROW(PlayerNode(bus, loop, inputs, bad), std::invalid_argument);
  bad = PlayerOptions();
  bad.max_attempts = -1;
  EXPECT_THROW(PlayerNode(bus, loop, inputs, bad), std::invalid_argument) << "max_attempts < 0";
  bad = PlayerOptions();
  bad.max_pending_sightings = 0;
  EXPECT_THROW(PlayerNode(bus, loop, inputs, bad), std::invalid_argument) << "max_pending_sightings 0";
  bad = PlayerOptions();
  bad.end_wait = -1ms;
  EXPECT_THROW(PlayerNode(bus, loop, inputs, bad), std::invalid_argument) << "end_wait < 0";
  PlayerOptions limits;
  limits.max_attempts = 0;
  EXPECT_TRUE(limits.may_send_again(1000000)) << "0: no limit";
  limits.max_attempts = 3;
  EXPECT_TRUE(limits.may_send_again(2));
  EXPECT_FALSE(limits.may_send_again(3));
  bad = PlayerOptions();
  bad.progress = PlayerOptions::Progress::kLine;
  EXPECT_THROW(PlayerNode(bus, loop, inputs, bad), std::invalid_argument) << "progress without a stream";
  // Robots without scans: the replay ends at once with mission_end_t.
  // (Lockstep: first to each robot in turn, each given ack_timeout to report
  // mission_done; no agent runs here.)
  PlayerOptions quick;
  quick.lockstep = true;
  quick.mission_end_interval = 1ms;
  quick.ack_timeout = 20ms;
  PlayerNode empty(bus, loop, inputs, quick);
  int ends = 0;
  bus.subscribe(rt::Channels().mission_end(), [&](const std::string&, const void*, std::size_t) { ++ends; });
  empty.start();
  ASSERT_TRUE(run_until(loop, [&] { return empty.finished() && ends >= quick.mission_end_repeats; }, 5s));
  EXPECT_EQ(empty.counters().mission_end_sent, quick.mission_end_repeats);
  EXPECT_EQ(empty.counters().mission_end_waits_expired, static_cast<std::int64_t>(inputs.robots.size()));
}

}  // namespace
