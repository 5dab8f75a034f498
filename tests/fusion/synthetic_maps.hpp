// Synthetic local maps for the fusion tests and benchmark: true walls in W, a
// robot's true local frame and final pose, and a LocalMapSnapshot with a
// covariance of realistic structure (segments correlated with the robot), with
// estimates either exact or drawn from that covariance.
#pragma once

#include <cmath>
#include <cstdint>
#include <random>
#include <vector>

#include <Eigen/Cholesky>
#include <Eigen/Core>

#include "lmf/geometry/pose2.hpp"
#include "lmf/local_map/local_map_snapshot.hpp"

namespace lmf::fusion::synthetic {

struct Wall {
  Pose2 x_WS;  // midpoint frame, x along the wall
  double length_m = 1.0;
};

struct Noise {
  double robot_xy_m = 0.05;
  double robot_phi_rad = 0.01;
  double lateral_m = 0.01;
  double angle_rad = 0.005;
  double coupling = 0.5;  // how much segments inherit of the robot's heading error
};

// Covariance (3 + 2k) of a local map: A Aᵀ with A = [[robot, 0], [coupling, own]].
inline Eigen::MatrixXd local_covariance(std::size_t k, const Noise& n) {
  const auto dim = static_cast<Eigen::Index>(3 + 2 * k);
  Eigen::MatrixXd A = Eigen::MatrixXd::Zero(dim, dim);
  A(0, 0) = n.robot_xy_m;
  A(1, 1) = n.robot_xy_m;
  A(2, 2) = n.robot_phi_rad;
  for (std::size_t j = 0; j < k; ++j) {
    const auto r = static_cast<Eigen::Index>(3 + 2 * j);
    A(r, r) = n.lateral_m;
    A(r + 1, r + 1) = n.angle_rad;
    A(r + 1, 2) = n.coupling * n.robot_phi_rad;
    A(r, 1) = 0.3 * n.coupling * n.robot_xy_m;
  }
  return A * A.transpose();
}

// A snapshot of `walls` (true poses in W) seen from the true local frame x_WL,
// with true final robot pose x_LR. With `rng`, the estimates carry an error
// drawn from the covariance (consistent); without, they are exact.
inline LocalMapSnapshot make_snapshot(int robot_id, std::int64_t seq, const Pose2& x_WL, const Pose2& x_LR,
                                      const std::vector<Wall>& walls, const Noise& noise = {},
                                      std::mt19937* rng = nullptr) {
  LocalMapSnapshot s;
  s.robot_id = robot_id;
  s.seq = seq;
  s.first_utime = seq * 1000000;
  s.last_utime = s.first_utime + 900000;
  s.covariance = local_covariance(walls.size(), noise);
  Eigen::VectorXd e = Eigen::VectorXd::Zero(s.covariance.rows());
  if (rng != nullptr) {
    std::normal_distribution<double> normal(0.0, 1.0);
    Eigen::VectorXd z(e.size());
    for (Eigen::Index i = 0; i < z.size(); ++i) z(i) = normal(*rng);
    const Eigen::LLT<Eigen::MatrixXd> llt(s.covariance);
    e = llt.matrixL() * z;
  }
  // x = x_true ⊕ Bᵀ(-e) so that x_true = x̂ ⊕ Bᵀ e to first order.
  s.x_LR = compose(x_LR, Pose2(-e(0), -e(1), -e(2)));
  for (std::size_t j = 0; j < walls.size(); ++j) {
    const auto r = static_cast<Eigen::Index>(3 + 2 * j);
    SegmentEstimate seg;
    seg.location = compose(between(x_WL, walls[j].x_WS), Pose2(0.0, -e(r), -e(r + 1)));
    seg.length_m = walls[j].length_m;
    s.segments.push_back(seg);
  }
  s.scan_poses.push_back({s.first_utime, Pose2()});
  s.scan_poses.push_back({s.last_utime, s.x_LR});
  return s;
}

// A rectangular room of `w` x `h` metres centred at (cx, cy), walls facing inwards
// (direction counter-clockwise), each wall split in `pieces` collinear segments
// separated by gaps of `gap_m`.
inline std::vector<Wall> room(double cx, double cy, double w, double h, int pieces = 1, double gap_m = 0.4) {
  std::vector<Wall> out;
  const double half_w = 0.5 * w;
  const double half_h = 0.5 * h;
  const Pose2 sides[4] = {Pose2(cx, cy - half_h, 0.0), Pose2(cx + half_w, cy, M_PI / 2),
                          Pose2(cx, cy + half_h, M_PI), Pose2(cx - half_w, cy, -M_PI / 2)};
  const double lengths[4] = {w, h, w, h};
  for (int s = 0; s < 4; ++s) {
    const double piece = (lengths[s] - (pieces - 1) * gap_m) / pieces;
    for (int p = 0; p < pieces; ++p) {
      const double offset = -0.5 * lengths[s] + 0.5 * piece + p * (piece + gap_m);
      out.push_back({compose(sides[s], Pose2(offset, 0.0, 0.0)), piece});
    }
  }
  return out;
}

}  // namespace lmf::fusion::synthetic
