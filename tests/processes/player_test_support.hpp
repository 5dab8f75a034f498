// Helpers of the agent/player process tests: a simulated mission on disk, a
// fake fusion server (GlobalMap behind the LCM protocol, fusing in arrival
// order on the loop thread), a probe of what agents publish, and running an
// event loop until a condition holds.
#pragma once

#include <chrono>
#include <cstdint>
#include <filesystem>
#include <functional>
#include <map>
#include <set>
#include <string>
#include <utility>
#include <vector>

#include <gtest/gtest.h>

#include "lmf/fusion/global_map.hpp"
#include "lmf/mission/mission_inputs.hpp"
#include "lmf/mission/offline_mission.hpp"
#include "lmf/sim/mission.hpp"
#include "lmf/sim/mission_writer.hpp"
#include "runtime/bus.hpp"
#include "runtime/channels.hpp"
#include "runtime/convert.hpp"
#include "runtime/event_loop.hpp"

namespace lmf::testing {

// Runs `loop` until `done()` (checked every 5 ms) or `timeout`; true if done.
inline bool run_until(runtime::EventLoop& loop, const std::function<bool()>& done,
                      std::chrono::milliseconds timeout) {
  if (done()) return true;
  const int timer = loop.every(std::chrono::milliseconds(5), [&] {
    if (done()) loop.stop();
  });
  loop.run_for(timeout);
  loop.cancel(timer);
  return done();
}

// A fresh folder under the system temp dir, removed with the object.
class TempDir {
 public:
  explicit TempDir(const std::string& name) {
    path_ = std::filesystem::temp_directory_path() /
            (name + "-" + std::to_string(::testing::UnitTest::GetInstance()->random_seed()) + "-" +
             std::to_string(std::chrono::steady_clock::now().time_since_epoch().count()));
    std::filesystem::create_directories(path_);
  }
  ~TempDir() {
    std::error_code ignored;
    std::filesystem::remove_all(path_, ignored);
  }
  TempDir(const TempDir&) = delete;
  TempDir& operator=(const TempDir&) = delete;
  const std::filesystem::path& path() const { return path_; }

 private:
  std::filesystem::path path_;
};

// A short two-robot simulated mission written as lmf-sim does.
inline void write_sim_mission(const std::filesystem::path& dir, double duration_s, std::uint64_t seed = 3,
                              int num_robots = 2) {
  sim::MissionConfig config;
  config.seed = seed;
  config.num_robots = num_robots;
  config.duration_s = duration_s;
  sim::write_mission(sim::simulate_mission(config), dir);
}

// The mission config of the one-process mission tests: several local maps in a short mission.
inline mission::MissionConfig short_mission_config() {
  mission::MissionConfig config;
  config.local_map.ship_distance_m = 4.0;
  return config;
}

// A 60 s two-robot simulated mission written to `dir` and loaded as the player loads it.
inline mission::MissionInputs load_short_sim_mission(const std::filesystem::path& dir,
                                                     const mission::MissionConfig& config) {
  write_sim_mission(dir, 60.0, 3, 2);
  return mission::load_sim_folder(dir, config.sighting_noise);
}

// Robot 0's scans of a short (40 s, one robot) simulated mission, loaded once.
inline const std::vector<LaserScan>& sim_scans() {
  static const std::vector<LaserScan> scans = [] {
    TempDir dir("lmf-agent-scans");
    write_sim_mission(dir.path(), 40.0, 5, 1);
    return mission::load_sim_folder(dir.path(), {}).robots.front().scans;
  }();
  return scans;
}

// A memq:// bus and loop with a probe that decodes what agents publish: scan
// acks and local maps.
struct AgentProbe {
  runtime::Bus bus{"memq://"};
  runtime::EventLoop loop{bus, runtime::EventLoopOptions{false}};
  runtime::Channels channels;
  std::vector<runtime::ScanAck> acks;
  std::vector<LocalMapSnapshot> maps;                 // every transmission received
  std::map<std::int64_t, LocalMapSnapshot> by_seq;  // the latest of each map

  AgentProbe() {
    bus.subscribe(channels.scan_ack(), [this](const std::string&, const void* d, std::size_t n) {
      auto ack = runtime::decode<runtime::ScanAck>(d, n);
      ASSERT_TRUE(ack.ok()) << ack.rejection().describe();
      acks.push_back(ack.value());
    });
    bus.subscribe(channels.local_map(), [this](const std::string&, const void* d, std::size_t n) {
      auto map = runtime::decode<LocalMapSnapshot>(d, n);
      ASSERT_TRUE(map.ok()) << map.rejection().describe();
      maps.push_back(map.value());
      by_seq[map.value().seq] = map.value();
    });
  }
  AgentProbe(const AgentProbe&) = delete;
  AgentProbe& operator=(const AgentProbe&) = delete;

  // Delivers what is pending, then what handling it published.
  void drain() {
    loop.poll();
    loop.poll();
  }
};

// What the wire does to a scan (ranges and angles become float), so an
// offline run on these inputs sees exactly what the agents see.
inline mission::MissionInputs as_sent(mission::MissionInputs inputs) {
  for (mission::RobotLog& log : inputs.robots) {
    for (LaserScan& scan : log.scans) scan = at_message_precision(scan);
  }
  return inputs;
}

// The server side of the protocol, minimal: fuses every local map and
// sighting as it arrives, acks FUSED / DUPLICATE / QUEUED, publishes
// corrected frames after each fusion. Robot `first_robot` joins with L = W.
class FakeServer {
 public:
  FakeServer(runtime::Bus& bus, const fusion::GlobalMapConfig& config, runtime::Channels channels,
             int first_robot = 0)
      : bus_(bus), channels_(std::move(channels)), map_(config) {
    record(map_.join_robot(first_robot, Pose2()));
    subscriptions_.push_back(bus_.subscribe(channels_.local_map(), [this](const std::string&, const void* d,
                                                                         std::size_t n) { on_local_map(d, n); }));
    subscriptions_.push_back(bus_.subscribe(channels_.sighting(), [this](const std::string&, const void* d,
                                                                        std::size_t n) { on_sighting(d, n); }));
  }
  ~FakeServer() {
    for (const int id : subscriptions_) bus_.unsubscribe(id);
  }

  // Ignore the first `n` transmissions of every local map (to exercise resends).
  void ignore_first_transmissions(int n) { ignore_first_ = n; }
  // The same for every sighting.
  void ignore_first_sighting_transmissions(int n) { ignore_first_sightings_ = n; }

  const fusion::GlobalMap& map() const { return map_; }
  // How often each (robot, seq) was fused (must be once) and received.
  const std::map<std::pair<int, std::int64_t>, int>& fused() const { return fused_; }
  const std::map<std::pair<int, std::int64_t>, int>& received() const { return received_; }
  std::int64_t fusions() const { return fusions_; }
  std::int64_t sightings() const { return sightings_; }  // given to the map (each at most once)
  // How often each sighting (utime, observer, observed) was received.
  const std::map<std::tuple<std::int64_t, int, int>, int>& sightings_received() const { return sightings_received_; }
  std::int64_t rejected() const { return rejected_; }
  std::int64_t duplicates() const { return duplicates_; }
  // Scan poses of every fused local map, by (robot, seq).
  const std::map<std::pair<int, std::int64_t>, std::vector<ScanPose>>& scan_poses() const { return scan_poses_; }

 private:
  void on_local_map(const void* data, std::size_t size) {
    auto snapshot = runtime::decode<LocalMapSnapshot>(data, size);
    if (!snapshot) {
      ++rejected_;
      return;
    }
    const LocalMapSnapshot& s = snapshot.value();
    const auto key = std::make_pair(s.robot_id, s.seq);
    if (++received_[key] <= ignore_first_) return;
    runtime::LocalMapAck ack{0, s.robot_id, s.seq, runtime::LocalMapAck::Status::kDuplicate};
    if (!map_.has_fused(s.robot_id, s.seq) && !map_.is_queued(s.robot_id, s.seq)) {
      scan_poses_[key] = s.scan_poses;
      record(map_.fuse(s));
      ack.status = map_.has_fused(s.robot_id, s.seq) ? runtime::LocalMapAck::Status::kFused
                                                      : runtime::LocalMapAck::Status::kQueued;
    } else {
      ++duplicates_;
    }
    bus_.publish(channels_.local_map_ack(), runtime::to_message(ack));
  }

  void on_sighting(const void* data, std::size_t size) {
    auto sighting = runtime::decode<fusion::RobotSighting>(data, size);
    if (!sighting) {
      ++rejected_;
      return;
    }
    const fusion::RobotSighting& s = sighting.value();
    const int received = ++sightings_received_[{s.utime, s.observer_id, s.observed_id}];
    if (received <= ignore_first_sightings_) return;
    runtime::SightingAck ack{s.utime, s.observer_id, s.observed_id, runtime::SightingAck::Status::kApplied};
    if (received > ignore_first_sightings_ + 1) {
      ack.status = runtime::SightingAck::Status::kDuplicate;
      bus_.publish(channels_.sighting_ack(), runtime::to_message(ack));
      return;
    }
    ++sightings_;
    record(map_.add_sighting(s).fused);
    bus_.publish(channels_.sighting_ack(), runtime::to_message(ack));
  }

  void record(const std::vector<fusion::FusionReport>& reports) {
    for (const fusion::FusionReport& report : reports) ++fused_[{report.robot_id, report.seq}];
    fusions_ += static_cast<std::int64_t>(reports.size());
    runtime::CorrectedFrames frames;
    frames.fusion_count = fusions_;
    frames.frames = map_.corrected_frames();
    auto msg = runtime::to_message(frames);
    if (msg) bus_.publish(channels_.corrected_frames(), msg.value());
  }

  runtime::Bus& bus_;
  runtime::Channels channels_;
  fusion::GlobalMap map_;
  int ignore_first_ = 0;
  int ignore_first_sightings_ = 0;
  std::map<std::tuple<std::int64_t, int, int>, int> sightings_received_;
  std::map<std::pair<int, std::int64_t>, int> fused_;
  std::map<std::pair<int, std::int64_t>, int> received_;
  std::map<std::pair<int, std::int64_t>, std::vector<ScanPose>> scan_poses_;
  std::int64_t fusions_ = 0;
  std::int64_t sightings_ = 0;
  std::int64_t rejected_ = 0;
  std::int64_t duplicates_ = 0;
  std::vector<int> subscriptions_;
};

}  // namespace lmf::testing
