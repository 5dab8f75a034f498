// Helpers of the tests that drive lmf-server's node over memq://: local maps
// of robots in a 10 x 6 m room, sightings, their LCM messages, the node's
// rejection counts, and a fixture that records the node's local-map acks.
#pragma once

#include <chrono>
#include <cstddef>
#include <cstdint>
#include <functional>
#include <string>
#include <tuple>
#include <utility>
#include <vector>

#include <Eigen/Core>
#include <gtest/gtest.h>

#include "fusion_server/server_node.hpp"
#include "lmf/geometry/pose2.hpp"
#include "lmf/local_map/local_map_snapshot.hpp"
#include "runtime/bus.hpp"
#include "runtime/channels.hpp"
#include "runtime/convert.hpp"
#include "runtime/event_loop.hpp"
#include "runtime/event_loop_test_support.hpp"

namespace lmf::testing {

// The walls of a 10 x 6 m room (the four sides, facing inwards, then five
// short inner walls) as (x_WS, length), x along each wall.
inline const std::vector<std::pair<Pose2, double>>& room_walls() {
  static const double pi = 3.14159265358979323846;
  static const std::vector<std::pair<Pose2, double>> walls = {
      {Pose2(4.0, -3.0, 0.0), 10.0},   {Pose2(9.0, 0.0, pi / 2), 6.0},  {Pose2(4.0, 3.0, pi), 10.0},
      {Pose2(-1.0, 0.0, -pi / 2), 6.0}, {Pose2(2.0, -1.5, pi / 2), 1.0}, {Pose2(6.0, 1.5, -pi / 2), 1.0},
      {Pose2(3.0, 1.0, 0.0), 0.8},      {Pose2(5.0, -1.0, pi), 0.8},     {Pose2(7.0, 2.0, pi / 2), 0.5}};
  return walls;
}

// Local map `seq` of a robot whose local frames advance by `step` from x_WL0,
// seeing the first `walls` walls of room_walls() exactly; a PSD covariance
// with the segments sharing the robot's heading error; scan poses at start and end.
inline LocalMapSnapshot room_local_map(int robot_id, std::int64_t seq, std::size_t walls = 5,
                                       const Pose2& x_WL0 = Pose2(), const Pose2& step = Pose2(1.0, 0.0, 0.0)) {
  Pose2 x_WL = x_WL0;
  for (std::int64_t k = 0; k < seq; ++k) x_WL = compose(x_WL, step);
  LocalMapSnapshot s;
  s.robot_id = robot_id;
  s.seq = seq;
  s.first_utime = 1'000'000 + seq * 1'000'000;
  s.last_utime = s.first_utime + 800'000;
  s.x_LR = step;
  const auto& room = room_walls();
  for (std::size_t i = 0; i < walls; ++i) s.segments.push_back({between(x_WL, room.at(i).first), room.at(i).second});
  const auto n = static_cast<Eigen::Index>(3 + 2 * walls);
  s.covariance = Eigen::MatrixXd::Zero(n, n);
  s.covariance.diagonal().head(3) << 1e-3, 1e-3, 1e-4;
  for (Eigen::Index i = 3; i < n; i += 2) {
    s.covariance(i, i) = 1e-4;
    s.covariance(i + 1, i + 1) = 1e-5;
    s.covariance(i + 1, 2) = s.covariance(2, i + 1) = 0.5e-5;  // segments share the robot's heading error
  }
  s.scan_poses = {{s.first_utime, Pose2()}, {s.last_utime, step}};
  return s;
}

// Robot `observed` seen 2 m ahead by robot `observer` at `utime`.
inline fusion::RobotSighting make_sighting(int observer, int observed, std::int64_t utime,
                                           std::int64_t observed_seq = 0) {
  fusion::RobotSighting s;
  s.utime = utime;
  s.observer_id = observer;
  s.observed_id = observed;
  s.x_AB = Pose2(2.0, 0.5, 0.1);
  s.cov_AB = Eigen::Vector3d(0.0025, 0.0025, 0.0004).asDiagonal();
  s.observer_seq = 0;
  s.x_LA = Pose2(0.2, 0.0, 0.0);
  s.cov_LA = Eigen::Matrix3d::Identity() * 1e-4;
  s.observed_seq = observed_seq;
  s.x_LB = Pose2();
  s.cov_LB = Eigen::Matrix3d::Zero();
  return s;
}

// The LCM message of a valid local map (a failed conversion fails the test).
inline local_map_t to_msg(const LocalMapSnapshot& s) {
  auto msg = runtime::to_message(s);
  EXPECT_TRUE(msg.ok()) << (msg.ok() ? "" : msg.rejection().describe());
  return msg.value();
}

// The LCM message of a valid sighting (a failed conversion fails the test).
inline sighting_t to_msg(const fusion::RobotSighting& s) {
  auto msg = runtime::to_message(s);
  EXPECT_TRUE(msg.ok()) << (msg.ok() ? "" : msg.rejection().describe());
  return msg.value();
}

// How many messages the node rejected for `reason`.
inline std::int64_t reject_count(const server::ServerNode& node, const std::string& reason) {
  for (const auto& [name, count] : node.reject_counts()) {
    if (name == reason) return count;
  }
  return 0;
}

// How many messages the node rejected, for any reason.
inline std::int64_t reject_total(const server::ServerNode& node) {
  std::int64_t n = 0;
  for (const auto& [name, count] : node.reject_counts()) n += count;
  return n;
}

// A memq:// bus and a loop (no signal handling) for a ServerNode, recording
// every local-map ack it sends as (robot, seq, status).
class ServerNodeFixture : public ::testing::Test {
 protected:
  using Status = runtime::LocalMapAck::Status;

  ServerNodeFixture() : bus_("memq://"), loop_(bus_, no_signals()) {
    bus_.subscribe_message<local_map_ack_t>(
        channels_.local_map_ack(), [this](const std::string&, const local_map_ack_t& ack) {
          acks_.emplace_back(ack.robot_id, ack.seq, static_cast<Status>(ack.status));
        });
  }

  // Runs the loop until `done` or a timeout (bounded test time).
  bool run_until(const std::function<bool()>& done, std::chrono::milliseconds timeout = std::chrono::seconds(5)) {
    const auto end = std::chrono::steady_clock::now() + timeout;
    while (!done()) {
      if (std::chrono::steady_clock::now() > end) return false;
      loop_.run_for(std::chrono::milliseconds(5));
    }
    return true;
  }

  // Runs until the worker is idle and every posted result was handled.
  void settle(server::ServerNode& node) {
    ASSERT_TRUE(run_until([&] { return !node.worker_busy(); }));
    loop_.run_for(std::chrono::milliseconds(20));
  }

  // Index in arrival order of the first such ack (the count of acks if none).
  std::size_t first_ack(int robot, std::int64_t seq, Status status) const {
    for (std::size_t i = 0; i < acks_.size(); ++i) {
      const auto& [r, s, st] = acks_[i];
      if (r == robot && s == seq && st == status) return i;
    }
    return acks_.size();
  }
  // How often (robot, seq) was acked with `status`.
  int count_acks(int robot, std::int64_t seq, Status status) const {
    int n = 0;
    for (const auto& [r, s, st] : acks_) n += (r == robot && s == seq && st == status) ? 1 : 0;
    return n;
  }

  runtime::Channels channels_;
  runtime::Bus bus_;
  runtime::EventLoop loop_;
  std::vector<std::tuple<int, std::int64_t, Status>> acks_;
};

}  // namespace lmf::testing
