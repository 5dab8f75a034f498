#include "lmf/scan/scan_matcher.hpp"

#include <algorithm>
#include <cmath>
#include <stdexcept>
#include <string>

#include <Eigen/Cholesky>
#include <Eigen/Eigenvalues>
#include <Eigen/LU>

#include "lmf/common/config_check.hpp"
#include "lmf/spmap/ekf.hpp"

namespace lmf {
namespace {

bool usable_range(const LaserScan& scan, std::size_t i, const ScanMatcherConfig& c) {
  const double r = scan.ranges_m[i];
  const double no_return = scan.max_range_m - c.no_return_margin_m;
  return std::isfinite(r) && r >= c.min_range_m && r <= c.max_range_m && (scan.max_range_m <= 0.0 || r < no_return);
}

Eigen::Matrix2d rotation(double phi) {
  const double c = std::cos(phi);
  const double s = std::sin(phi);
  Eigen::Matrix2d R;
  R << c, -s, s, c;
  return R;
}

// ∂e/∂δ for e = nᵀ (x ⊕ δ ⊙ b − a) at δ = 0, with R = R(x.phi):
// x ⊕ δ ⊙ b = t + R δ_xy + R(φ + δφ) b, so ∂/∂δ_xy = R, ∂/∂δφ = R (−b_y, b_x).
Eigen::RowVector3d point_to_line_row(const Eigen::Matrix2d& R, const Eigen::Vector2d& b, const Eigen::Vector2d& n) {
  const Eigen::RowVector2d nR = n.transpose() * R;
  return {nR(0), nR(1), nR.dot(Eigen::Vector2d(-b.y(), b.x()))};
}

// The nearest reference point with a normal to q (in A's frame) among the
// beams around q's bearing, within `gate` (m); -1 when none.
int correspondence(const ReferenceScan& A, const Eigen::Vector2d& q, double gate) {
  const auto beams = static_cast<long>(A.point_of_beam.size());
  if (beams == 0 || A.angle_increment_rad == 0.0) return -1;
  const double range = q.norm();
  const double bearing = std::atan2(q.y(), q.x());
  const double index = (bearing - A.angle_min_rad) / A.angle_increment_rad;
  if (!(std::abs(index) < 4.0 * static_cast<double>(beams))) return -1;  // far outside the scan (or NaN)
  const long centre = std::lround(index);
  const double arc = std::max(range * std::abs(A.angle_increment_rad), 1e-3);
  const long half_width = std::clamp(static_cast<long>(std::ceil(gate / arc)), 1L, 20L);
  int best = -1;
  double best_d2 = gate * gate;
  auto visit = [&](long k) {
    const int j = A.point_of_beam[static_cast<std::size_t>(k)];
    if (j < 0) return;
    const double d2 = (A.points[static_cast<std::size_t>(j)] - q).squaredNorm();
    if (d2 < best_d2) {
      best_d2 = d2;
      best = j;
    }
  };
  if (centre >= 0 && centre < beams) visit(centre);
  // Outwards from the bearing: a point o beams away (o - 0.5 beams in angle) is at least
  // range · sin(o · increment) from q, so stop once that exceeds the best.
  for (long o = 1; o <= half_width; ++o) {
    const double bound = range * std::sin(std::min(1.5, (static_cast<double>(o) - 0.5) * std::abs(A.angle_increment_rad)));
    if (bound * bound >= best_d2) break;
    if (centre - o >= 0 && centre - o < beams) visit(centre - o);
    if (centre + o >= 0 && centre + o < beams) visit(centre + o);
  }
  return best;
}

}  // namespace

void ScanMatcherConfig::validate() const {
  const ConfigCheck require("ScanMatcherConfig");
  require(std::isfinite(min_range_m) && min_range_m >= 0.0, "min_range_m", min_range_m, "finite and >= 0");
  require(std::isfinite(max_range_m) && max_range_m > min_range_m, "max_range_m", max_range_m,
          "finite and > min_range_m");
  require(std::isfinite(no_return_margin_m) && no_return_margin_m >= 0.0, "no_return_margin_m", no_return_margin_m,
          "finite and >= 0");
  require(std::isfinite(normal_radius_m) && normal_radius_m > 0.0, "normal_radius_m", normal_radius_m,
          "finite and > 0");
  require(max_normal_flatness > 0.0 && max_normal_flatness <= 1.0, "max_normal_flatness", max_normal_flatness,
          "in (0, 1]");
  require(std::isfinite(last_gate_m) && last_gate_m > 0.0, "last_gate_m", last_gate_m, "finite and > 0");
  require(std::isfinite(first_gate_m) && first_gate_m >= last_gate_m, "first_gate_m", first_gate_m,
          "finite and >= last_gate_m");
  require(max_iterations >= 1, "max_iterations", max_iterations, ">= 1");
  require(min_correspondences >= 3, "min_correspondences", min_correspondences, ">= 3");
  require(std::isfinite(point_sigma_m) && point_sigma_m > 0.0, "point_sigma_m", point_sigma_m, "finite and > 0");
  require(std::isfinite(huber_k) && huber_k > 0.0, "huber_k", huber_k, "finite and > 0");
  require(std::isfinite(max_independent_points) && max_independent_points > 0.0, "max_independent_points",
          max_independent_points, "finite and > 0");
  require(std::isfinite(model_noise_m) && model_noise_m >= 0.0, "model_noise_m", model_noise_m, "finite and >= 0");
  require(std::isfinite(model_noise_rad) && model_noise_rad >= 0.0, "model_noise_rad", model_noise_rad,
          "finite and >= 0");
  require(std::isfinite(model_noise_per_rad) && model_noise_per_rad >= 0.0, "model_noise_per_rad",
          model_noise_per_rad, "finite and >= 0");
  require(prior_alpha > 0.0 && prior_alpha < 1.0, "prior_alpha", prior_alpha, "in (0, 1)");
}

ReferenceScan ReferenceScan::from(const LaserScan& scan, const ScanMatcherConfig& config) {
  config.validate();
  ReferenceScan A;
  A.angle_min_rad = scan.angle_min_rad;
  A.angle_increment_rad = scan.angle_increment_rad;
  const std::size_t n = scan.ranges_m.size();
  std::vector<Eigen::Vector2d> beam_points(n);
  std::vector<bool> valid(n, false);
  for (std::size_t i = 0; i < n; ++i) {
    valid[i] = usable_range(scan, i, config);
    if (valid[i]) beam_points[i] = scan.beam_point(i);
  }
  A.point_of_beam.assign(n, -1);
  constexpr std::size_t kMaxNeighbourBeams = 10;
  for (std::size_t i = 0; i < n; ++i) {
    if (!valid[i]) continue;
    // Neighbours in beam order, contiguous and within normal_radius_m of point i.
    std::size_t lo = i;
    std::size_t hi = i;
    while (lo > 0 && i - lo < kMaxNeighbourBeams && valid[lo - 1] &&
           (beam_points[lo - 1] - beam_points[i]).norm() <= config.normal_radius_m) {
      --lo;
    }
    while (hi + 1 < n && hi - i < kMaxNeighbourBeams && valid[hi + 1] &&
           (beam_points[hi + 1] - beam_points[i]).norm() <= config.normal_radius_m) {
      ++hi;
    }
    if (hi - lo + 1 < 4) continue;
    Eigen::Vector2d mean = Eigen::Vector2d::Zero();
    for (std::size_t k = lo; k <= hi; ++k) mean += beam_points[k];
    mean /= static_cast<double>(hi - lo + 1);
    Eigen::Matrix2d scatter = Eigen::Matrix2d::Zero();
    for (std::size_t k = lo; k <= hi; ++k) scatter += (beam_points[k] - mean) * (beam_points[k] - mean).transpose();
    const Eigen::SelfAdjointEigenSolver<Eigen::Matrix2d> es(scatter);
    if (!(es.eigenvalues()(0) <= config.max_normal_flatness * es.eigenvalues()(1))) continue;
    Eigen::Vector2d normal = es.eigenvectors().col(0);
    if (normal.dot(beam_points[i]) > 0.0) normal = -normal;  // towards the sensor
    A.point_of_beam[i] = static_cast<int>(A.points.size());
    A.points.push_back(beam_points[i]);
    A.normals.push_back(normal);
  }
  return A;
}

std::vector<Eigen::Vector2d> scan_points(const LaserScan& scan, const ScanMatcherConfig& config) {
  std::vector<Eigen::Vector2d> points;
  points.reserve(scan.ranges_m.size());
  for (std::size_t i = 0; i < scan.ranges_m.size(); ++i) {
    if (usable_range(scan, i, config)) points.push_back(scan.beam_point(i));
  }
  return points;
}

Eigen::RowVector3d point_to_line_jacobian(const Pose2& x, const Eigen::Vector2d& b, const Eigen::Vector2d& n) {
  return point_to_line_row(rotation(x.phi), b, n);
}

Eigen::Matrix3d prior_residual_jacobian(const Pose2& u_hat, const Pose2& x) {
  // between(û, x ⊕ δ) = between(û, x) ⊕ δ.
  return J2compose(between(u_hat, x), Pose2());
}

std::optional<ScanMatch> match_scans(const ReferenceScan& A, const std::vector<Eigen::Vector2d>& B,
                                     const Pose2& u_hat, const Eigen::Matrix3d& Q, const ScanMatcherConfig& config) {
  config.validate();
  if (!std::isfinite(u_hat.x) || !std::isfinite(u_hat.y) || !std::isfinite(u_hat.phi)) {
    throw std::invalid_argument("match_scans: non-finite odometry increment");
  }
  const Eigen::LLT<Eigen::Matrix3d> Q_llt(Q);
  if (!Q.allFinite() || !Q.isApprox(Q.transpose(), 1e-9) || Q_llt.info() != Eigen::Success) {
    throw std::invalid_argument("match_scans: the odometry covariance Q must be symmetric positive definite");
  }
  const Eigen::Matrix3d Q_inv = Q_llt.solve(Eigen::Matrix3d::Identity());
  const double sigma2 = config.point_sigma_m * config.point_sigma_m;
  const double huber = config.huber_k * config.point_sigma_m;
  const double turn_noise = config.model_noise_per_rad * std::abs(u_hat.phi);
  const Eigen::Matrix3d C_m =
      Eigen::Vector3d(config.model_noise_m * config.model_noise_m, config.model_noise_m * config.model_noise_m,
                      config.model_noise_rad * config.model_noise_rad + turn_noise * turn_noise)
          .asDiagonal();

  ScanMatch out;
  Pose2 x = u_hat;
  Eigen::Matrix3d H = Eigen::Matrix3d::Zero();
  double gate = config.first_gate_m;
  constexpr int kIterationsPerGate = 5;
  int iterations_at_gate = 0;
  for (int it = 0; it < config.max_iterations; ++it) {
    Eigen::Matrix3d A_laser = Eigen::Matrix3d::Zero();
    Eigen::Vector3d g_laser = Eigen::Vector3d::Zero();
    int matched = 0;
    double sum_e2 = 0.0;
    const Eigen::Matrix2d R = rotation(x.phi);
    const Eigen::Vector2d t(x.x, x.y);
    for (const Eigen::Vector2d& b : B) {
      const Eigen::Vector2d q = t + R * b;  // x ⊙ b: b in A's frame
      const int j = correspondence(A, q, gate);
      if (j < 0) continue;
      const Eigen::Vector2d& n = A.normals[static_cast<std::size_t>(j)];
      const double e = n.dot(q - A.points[static_cast<std::size_t>(j)]);
      const Eigen::RowVector3d J = point_to_line_row(R, b, n);
      const double w = std::abs(e) <= huber ? 1.0 : huber / std::abs(e);
      A_laser.noalias() += w * J.transpose() * J;
      g_laser.noalias() += w * e * J.transpose();
      sum_e2 += e * e;
      ++matched;
    }
    out.correspondences = matched;
    out.iterations = it + 1;
    if (matched < config.min_correspondences) return std::nullopt;
    out.rms_m = std::sqrt(sum_e2 / matched);
    // Λ at most max_independent_points effective points, then widened by C_m:
    // Λ' = (I + Λ C_m)⁻¹ Λ, and the gradient of the widened term (I + Λ C_m)⁻¹ g.
    const double laser_weight = std::min(1.0, config.max_independent_points / matched) / sigma2;
    const Eigen::Matrix3d Lambda = laser_weight * A_laser;
    const Eigen::Matrix3d widen = (Eigen::Matrix3d::Identity() + Lambda * C_m).inverse();
    Eigen::Matrix3d Lambda_widened = widen * Lambda;
    Lambda_widened = (0.5 * (Lambda_widened + Lambda_widened.transpose())).eval();
    const Pose2 r_pose = between(u_hat, x);
    const Eigen::Vector3d r(r_pose.x, r_pose.y, wrap_angle(r_pose.phi));
    const Eigen::Matrix3d J_r = prior_residual_jacobian(u_hat, x);
    H = Lambda_widened + J_r.transpose() * Q_inv * J_r;
    const Eigen::Vector3d gradient = widen * (laser_weight * g_laser) + J_r.transpose() * Q_inv * r;
    const Eigen::Vector3d delta = -H.ldlt().solve(gradient);
    if (!delta.allFinite()) return std::nullopt;
    x = compose(x, Pose2(delta(0), delta(1), delta(2)));
    // Settled: a step below 1 mm and 0.1 mrad, a tenth of the match's own
    // precision, or kIterationsPerGate steps at this gate (correspondences that
    // flip between neighbours keep small steps going without improving anything).
    ++iterations_at_gate;
    const bool settled = (delta.head<2>().norm() < 1e-3 && std::abs(delta(2)) < 1e-4) ||
                         iterations_at_gate >= kIterationsPerGate;
    if (settled) {
      if (gate <= config.last_gate_m) break;
      gate = std::max(config.last_gate_m, 0.5 * gate);
      iterations_at_gate = 0;
    }
  }
  const Pose2 r_pose = between(u_hat, x);
  const Eigen::Vector3d r(r_pose.x, r_pose.y, wrap_angle(r_pose.phi));
  out.prior_distance2 = r.dot(Q_inv * r);
  if (!(out.prior_distance2 <= spmap::chi2_threshold(3, config.prior_alpha))) return std::nullopt;
  const Eigen::LLT<Eigen::Matrix3d> H_llt(H);
  if (H_llt.info() != Eigen::Success) return std::nullopt;
  out.x_AB = x;
  out.covariance = H_llt.solve(Eigen::Matrix3d::Identity());
  out.covariance = (0.5 * (out.covariance + out.covariance.transpose())).eval();
  return out;
}

}  // namespace lmf
