#include "lmf/scan/scan_matcher.hpp"

#include <algorithm>
#include <cmath>
#include <numbers>
#include <optional>
#include <stdexcept>
#include <string>
#include <unordered_set>
#include <vector>

#include <Eigen/Cholesky>
#include <Eigen/Eigenvalues>
#include <Eigen/LU>

#include "lmf/common/config_check.hpp"
#include "lmf/scan/correlative_search.hpp"
#include "lmf/scan/foreground_objects.hpp"
#include "lmf/spmap/ekf.hpp"

namespace lmf {
namespace {

// (M + Mᵀ) / 2: information and covariance matrices stay exactly symmetric.
Eigen::Matrix3d symmetrised(const Eigen::Matrix3d& M) { return 0.5 * (M + M.transpose()); }

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

// Indices of the points kept when only the first one in each square cell of
// `cell_m` is kept.
std::vector<std::size_t> thinned(const std::vector<Eigen::Vector2d>& points, double cell_m) {
  std::unordered_set<std::uint64_t> occupied;
  occupied.reserve(points.size());
  std::vector<std::size_t> kept;
  kept.reserve(points.size());
  constexpr double kFar = 1e9;
  for (std::size_t i = 0; i < points.size(); ++i) {
    if (!points[i].allFinite()) continue;
    const auto ix = static_cast<std::int64_t>(std::floor(std::clamp(points[i].x() / cell_m, -kFar, kFar)));
    const auto iy = static_cast<std::int64_t>(std::floor(std::clamp(points[i].y() / cell_m, -kFar, kFar)));
    const std::uint64_t key = (static_cast<std::uint64_t>(ix) << 32U) ^ (static_cast<std::uint64_t>(iy) & 0xffffffffULL);
    if (occupied.insert(key).second) kept.push_back(i);
  }
  return kept;
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
  require(std::isfinite(search_window_m) && search_window_m >= 0.0 && search_window_m <= 5.0, "search_window_m",
          search_window_m, "finite and in [0, 5]");
  require(std::isfinite(search_window_rad) && search_window_rad >= 0.0 && search_window_rad <= std::numbers::pi,
          "search_window_rad", search_window_rad, "in [0, pi]");
  require(std::isfinite(search_resolution_m) && search_resolution_m >= 0.01, "search_resolution_m",
          search_resolution_m, "finite and >= 0.01");
  require(search_window_m / search_resolution_m <= 60.0, "search_window_m", search_window_m,
          "at most 60 search_resolution_m");
  require(min_overlap >= 0.0 && min_overlap < 1.0, "min_overlap", min_overlap, "in [0, 1)");
  require(ambiguity_ratio > 0.0 && ambiguity_ratio <= 1.0, "ambiguity_ratio", ambiguity_ratio, "in (0, 1]");
  require(std::isfinite(max_object_extent_m) && max_object_extent_m >= 0.0, "max_object_extent_m",
          max_object_extent_m, "finite and >= 0");
  require(std::isfinite(object_range_jump_m) && object_range_jump_m > 0.0, "object_range_jump_m",
          object_range_jump_m, "finite and > 0");
  require(object_consistency_alpha > 0.0 && object_consistency_alpha < 1.0, "object_consistency_alpha",
          object_consistency_alpha, "in (0, 1)");
  require(history_scans >= 1, "history_scans", history_scans, ">= 1");
  require(std::isfinite(keyframe_distance_m) && keyframe_distance_m >= 0.0, "keyframe_distance_m",
          keyframe_distance_m, "finite and >= 0");
  require(std::isfinite(keyframe_angle_rad) && keyframe_angle_rad >= 0.0, "keyframe_angle_rad", keyframe_angle_rad,
          "finite and >= 0");
  require(std::isfinite(reference_voxel_m) && reference_voxel_m > 0.0, "reference_voxel_m", reference_voxel_m,
          "finite and > 0");
  require(prior_alpha > 0.0 && prior_alpha < 1.0, "prior_alpha", prior_alpha, "in (0, 1)");
  require(std::isfinite(last_gate_m) && last_gate_m > 0.0, "last_gate_m", last_gate_m, "finite and > 0");
  require(std::isfinite(first_gate_m) && first_gate_m >= last_gate_m, "first_gate_m", first_gate_m,
          "finite and >= last_gate_m");
  require(max_iterations >= 1, "max_iterations", max_iterations, ">= 1");
  require(min_correspondences >= 3, "min_correspondences", min_correspondences, ">= 3");
  require(std::isfinite(point_sigma_m) && point_sigma_m > 0.0, "point_sigma_m", point_sigma_m, "finite and > 0");
  require(std::isfinite(range_noise_per_m) && range_noise_per_m >= 0.0, "range_noise_per_m", range_noise_per_m,
          "finite and >= 0");
  require(std::isfinite(huber_k) && huber_k > 0.0, "huber_k", huber_k, "finite and > 0");
  require(std::isfinite(max_independent_points) && max_independent_points > 0.0, "max_independent_points",
          max_independent_points, "finite and > 0");
  require(std::isfinite(model_noise_m) && model_noise_m >= 0.0, "model_noise_m", model_noise_m, "finite and >= 0");
  require(std::isfinite(model_noise_rad) && model_noise_rad >= 0.0, "model_noise_rad", model_noise_rad,
          "finite and >= 0");
}

OrientedPoints oriented_points(const LaserScan& scan, const ScanMatcherConfig& config) {
  config.validate();
  const std::size_t n = scan.ranges_m.size();
  std::vector<Eigen::Vector2d> beam_points(n);
  std::vector<bool> valid(n, false);
  for (std::size_t i = 0; i < n; ++i) {
    valid[i] = usable_range(scan, i, config);
    if (valid[i]) beam_points[i] = scan.beam_point(i);
  }
  OrientedPoints out;
  constexpr std::size_t kMaxNeighbourBeams = 10;
  for (std::size_t i = 0; i < n; ++i) {
    if (!valid[i]) continue;
    // Neighbours in beam order, contiguous and within the radius of point i:
    // normal_radius_m, or where the beams are farther apart, two beam steps
    // at this range on a surface up to 37° from facing the sensor
    // (2 r Δθ / cos 37° = 2.5 r Δθ), so a sparse laser's far walls have the
    // four points a normal needs.
    const double radius =
        std::max(config.normal_radius_m, 2.5 * scan.ranges_m[i] * std::abs(scan.angle_increment_rad));
    std::size_t lo = i;
    std::size_t hi = i;
    while (lo > 0 && i - lo < kMaxNeighbourBeams && valid[lo - 1] &&
           (beam_points[lo - 1] - beam_points[i]).norm() <= radius) {
      --lo;
    }
    while (hi + 1 < n && hi - i < kMaxNeighbourBeams && valid[hi + 1] &&
           (beam_points[hi + 1] - beam_points[i]).norm() <= radius) {
      ++hi;
    }
    if (hi - lo + 1 < 4) {
      out.unoriented.push_back(beam_points[i]);
      continue;
    }
    Eigen::Vector2d mean = Eigen::Vector2d::Zero();
    for (std::size_t k = lo; k <= hi; ++k) mean += beam_points[k];
    mean /= static_cast<double>(hi - lo + 1);
    Eigen::Matrix2d scatter = Eigen::Matrix2d::Zero();
    for (std::size_t k = lo; k <= hi; ++k) scatter += (beam_points[k] - mean) * (beam_points[k] - mean).transpose();
    const Eigen::SelfAdjointEigenSolver<Eigen::Matrix2d> es(scatter);
    if (!(es.eigenvalues()(0) <= config.max_normal_flatness * es.eigenvalues()(1))) {
      out.unoriented.push_back(beam_points[i]);
      continue;
    }
    Eigen::Vector2d normal = es.eigenvectors().col(0);
    if (normal.dot(beam_points[i]) > 0.0) normal = -normal;  // towards the sensor
    out.points.push_back(beam_points[i]);
    out.normals.push_back(normal);
  }
  return out;
}

ReferenceScan ReferenceScan::from(const LaserScan& scan, const ScanMatcherConfig& config) {
  return from_points(oriented_points(scan, config), config);
}

ReferenceScan ReferenceScan::from_points(const OrientedPoints& given, const ScanMatcherConfig& config) {
  config.validate();
  if (given.points.size() != given.normals.size()) {
    throw std::invalid_argument("ReferenceScan::from_points: as many normals as points needed");
  }
  ReferenceScan A;
  const std::vector<std::size_t> kept = thinned(given.points, config.reference_voxel_m);
  A.points_.reserve(kept.size());
  A.normals_.reserve(kept.size());
  for (const std::size_t i : kept) {
    A.points_.push_back(given.points[i]);
    A.normals_.push_back(given.normals[i]);
    A.bounds_.extend(given.points[i]);
  }
  for (const std::size_t i : thinned(given.unoriented, config.reference_voxel_m)) {
    A.unoriented_.push_back(given.unoriented[i]);
    A.bounds_.extend(given.unoriented[i]);
  }
  if (A.points_.empty()) return A;
  // Counting sort of the points into cells of last_gate_m.
  A.cell_m_ = config.last_gate_m;
  const Eigen::Vector2d size = A.bounds_.sizes() / A.cell_m_;
  A.width_ = static_cast<int>(std::floor(size.x())) + 1;
  A.height_ = static_cast<int>(std::floor(size.y())) + 1;
  const auto cells = static_cast<std::size_t>(A.width_) * static_cast<std::size_t>(A.height_);
  std::vector<int> cell_of(A.points_.size());
  A.cell_start_.assign(cells + 1, 0);
  for (std::size_t i = 0; i < A.points_.size(); ++i) {
    const Eigen::Vector2d c = (A.points_[i] - A.bounds_.min()) / A.cell_m_;
    const int ix = std::min(A.width_ - 1, static_cast<int>(c.x()));
    const int iy = std::min(A.height_ - 1, static_cast<int>(c.y()));
    cell_of[i] = iy * A.width_ + ix;
    ++A.cell_start_[static_cast<std::size_t>(cell_of[i]) + 1];
  }
  for (std::size_t c = 0; c < cells; ++c) A.cell_start_[c + 1] += A.cell_start_[c];
  A.cell_points_.resize(A.points_.size());
  std::vector<int> fill(A.cell_start_.begin(), A.cell_start_.end() - 1);
  for (std::size_t i = 0; i < A.points_.size(); ++i) {
    A.cell_points_[static_cast<std::size_t>(fill[static_cast<std::size_t>(cell_of[i])]++)] = static_cast<int>(i);
  }
  return A;
}

int ReferenceScan::nearest(const Eigen::Vector2d& q, double gate) const {
  if (points_.empty() || !q.allFinite()) return -1;
  const Eigen::Vector2d lo = (q - bounds_.min()).array() - gate;
  const Eigen::Vector2d hi = (q - bounds_.min()).array() + gate;
  if (hi.x() < 0.0 || hi.y() < 0.0 || lo.x() > width_ * cell_m_ || lo.y() > height_ * cell_m_) return -1;
  const int x0 = std::max(0, static_cast<int>(std::floor(lo.x() / cell_m_)));
  const int y0 = std::max(0, static_cast<int>(std::floor(lo.y() / cell_m_)));
  const int x1 = std::min(width_ - 1, static_cast<int>(std::floor(hi.x() / cell_m_)));
  const int y1 = std::min(height_ - 1, static_cast<int>(std::floor(hi.y() / cell_m_)));
  int best = -1;
  double best_d2 = gate * gate;
  for (int iy = y0; iy <= y1; ++iy) {
    for (int ix = x0; ix <= x1; ++ix) {
      const auto c = static_cast<std::size_t>(iy * width_ + ix);
      for (int k = cell_start_[c]; k < cell_start_[c + 1]; ++k) {
        const int j = cell_points_[static_cast<std::size_t>(k)];
        const double d2 = (points_[static_cast<std::size_t>(j)] - q).squaredNorm();
        if (d2 < best_d2) {
          best_d2 = d2;
          best = j;
        }
      }
    }
  }
  return best;
}
Eigen::Matrix3d search_window_covariance(const ScanMatcherConfig& config) {
  const double sigma_xy = config.search_window_m / 3.0;
  const double sigma_phi = config.search_window_rad / 3.0;
  return Eigen::Vector3d(sigma_xy * sigma_xy, sigma_xy * sigma_xy, sigma_phi * sigma_phi).asDiagonal();
}

std::vector<Eigen::Vector2d> scan_points(const LaserScan& scan, const ScanMatcherConfig& config) {
  std::vector<Eigen::Vector2d> points;
  points.reserve(scan.ranges_m.size());
  for (std::size_t i = 0; i < scan.ranges_m.size(); ++i) {
    if (usable_range(scan, i, config)) points.push_back(scan.beam_point(i));
  }
  return points;
}

ScanPoints scan_points_by_kind(const LaserScan& scan, const ScanMatcherConfig& config) {
  config.validate();
  std::vector<bool> usable(scan.ranges_m.size());
  for (std::size_t i = 0; i < usable.size(); ++i) usable[i] = usable_range(scan, i, config);
  const std::vector<bool> object =
      small_foreground_objects(scan, usable, config.max_object_extent_m, config.object_range_jump_m);
  ScanPoints out;
  out.all.reserve(usable.size());
  out.structure.reserve(usable.size());
  for (std::size_t i = 0; i < usable.size(); ++i) {
    if (!usable[i]) continue;
    out.all.push_back(scan.beam_point(i));
    if (!object[i]) out.structure.push_back(scan.beam_point(i));
  }
  return out;
}

Eigen::RowVector3d point_to_line_jacobian(const Pose2& x, const Eigen::Vector2d& b, const Eigen::Vector2d& n) {
  return point_to_line_row(rotation(x.phi), b, n);
}

Eigen::Matrix3d prior_residual_jacobian(const Pose2& u_hat, const Pose2& x) {
  // between(û, x ⊕ δ) = between(û, x) ⊕ δ.
  return J2compose(between(u_hat, x), Pose2());
}

namespace {

struct Refinement {
  ScanMatch match;
  // Σ_i J_iᵀ J_i / N over the matched points: the mean squared displacement of
  // the points across their surfaces for a perturbation δ is δᵀ M δ.
  Eigen::Matrix3d mean_point_information = Eigen::Matrix3d::Zero();
};

Eigen::Matrix3d checked_inverse_of_prior(const Pose2& u_hat, const Eigen::Matrix3d& Q) {
  if (!std::isfinite(u_hat.x) || !std::isfinite(u_hat.y) || !std::isfinite(u_hat.phi)) {
    throw std::invalid_argument("match_scans: non-finite odometry increment");
  }
  const Eigen::LLT<Eigen::Matrix3d> Q_llt(Q);
  if (!Q.allFinite() || !Q.isApprox(Q.transpose(), 1e-9) || Q_llt.info() != Eigen::Success) {
    throw std::invalid_argument("match_scans: the odometry covariance Q must be symmetric positive definite");
  }
  return Q_llt.solve(Eigen::Matrix3d::Identity());
}

// Stage 2: Gauss–Newton of the maximum a posteriori problem from x0.
std::optional<Refinement> refine(const ReferenceScan& A, const std::vector<Eigen::Vector2d>& B, const Pose2& x0,
                                 const Pose2& u_hat, const Eigen::Matrix3d& Q_inv, const ScanMatcherConfig& config) {
  const double sigma2 = config.point_sigma_m * config.point_sigma_m;
  const double huber = config.huber_k * config.point_sigma_m;
  const Eigen::Matrix3d C_m =
      Eigen::Vector3d(config.model_noise_m * config.model_noise_m, config.model_noise_m * config.model_noise_m,
                      config.model_noise_rad * config.model_noise_rad)
          .asDiagonal();

  const double prior_k2 = spmap::chi2_threshold(3, config.prior_alpha);
  Refinement out;
  Pose2 x = x0;
  Eigen::Matrix3d H = Eigen::Matrix3d::Zero();
  Eigen::Matrix3d H_covariance = Eigen::Matrix3d::Zero();  // H with the calibrated laser term
  double gate = config.first_gate_m;
  const double range_noise2 = config.range_noise_per_m * config.range_noise_per_m;
  constexpr int kIterationsPerGate = 5;
  int iterations_at_gate = 0;
  for (int it = 0; it < config.max_iterations; ++it) {
    Eigen::Matrix3d A_laser = Eigen::Matrix3d::Zero();
    // A_laser with each point at its own σ_i (range_noise_per_m): σ² / σ_i² J_iᵀ J_i.
    Eigen::Matrix3d A_laser_at_range = Eigen::Matrix3d::Zero();
    Eigen::Matrix3d A_unweighted = Eigen::Matrix3d::Zero();
    Eigen::Vector3d g_laser = Eigen::Vector3d::Zero();
    int matched = 0;
    double sum_e2 = 0.0;
    double sum_we2 = 0.0;
    // Lag-1 products of the Huber-clipped residuals of neighbouring points (B
    // is in beam order), for their correlation ρ along the scan.
    double sum_c2 = 0.0;
    double sum_lag = 0.0;
    int lag_pairs = 0;
    std::optional<double> previous_clipped;
    const Eigen::Matrix2d R = rotation(x.phi);
    const Eigen::Vector2d t(x.x, x.y);
    for (const Eigen::Vector2d& b : B) {
      const Eigen::Vector2d q = t + R * b;  // x ⊙ b: b in A's frame
      const int j = A.nearest(q, gate);
      if (j < 0) {
        previous_clipped.reset();
        continue;
      }
      const Eigen::Vector2d& n = A.normals()[static_cast<std::size_t>(j)];
      const double e = n.dot(q - A.points()[static_cast<std::size_t>(j)]);
      const double clipped = std::clamp(e, -huber, huber);
      sum_c2 += clipped * clipped;
      if (previous_clipped) {
        sum_lag += clipped * *previous_clipped;
        ++lag_pairs;
      }
      previous_clipped = clipped;
      const Eigen::RowVector3d J = point_to_line_row(R, b, n);
      const double w = std::abs(e) <= huber ? 1.0 : huber / std::abs(e);
      const Eigen::Matrix3d JtJ = J.transpose() * J;
      A_laser.noalias() += w * JtJ;
      A_laser_at_range.noalias() += w / (1.0 + range_noise2 * b.squaredNorm() / sigma2) * JtJ;
      A_unweighted += JtJ;
      g_laser.noalias() += w * e * J.transpose();
      sum_e2 += e * e;
      sum_we2 += w * e * e;
      ++matched;
    }
    out.match.correspondences = matched;
    out.match.iterations = it + 1;
    if (matched < config.min_correspondences) return std::nullopt;
    out.match.rms_m = std::sqrt(sum_e2 / matched);
    out.mean_point_information = A_unweighted / matched;
    // Λ at most max_independent_points effective points, then widened by C_m:
    // Λ' = (I + Λ C_m)⁻¹ Λ, and the gradient of the widened term (I + Λ C_m)⁻¹ g.
    // Correlated residuals (AR(1) along the scan) count as N (1 − ρ) / (1 + ρ)
    // independent points; ρ is their lag-1 covariance over the variance the
    // point error is taken to have (σ², or their own when larger), so residuals
    // well inside σ (a clean scan) leave the count as it is.
    const double point_variance = std::max(sigma2, sum_c2 / matched);
    const double rho = config.residual_correlation && lag_pairs > 0
                           ? std::clamp(sum_lag / lag_pairs / point_variance, 0.0, 0.99)
                           : 0.0;
    const double independent_points = std::min(config.max_independent_points, matched * (1.0 - rho) / (1.0 + rho));
    const double laser_weight = independent_points / matched / sigma2;
    const Eigen::Matrix3d Lambda = laser_weight * A_laser;
    const Eigen::Matrix3d widen = (Eigen::Matrix3d::Identity() + Lambda * C_m).inverse();
    const Eigen::Matrix3d Lambda_widened = symmetrised(widen * Lambda);
    out.match.laser_information = Lambda_widened;
    // The covariance's laser term: each point at its own σ_i (range_noise_per_m),
    // and σ² the larger of point_sigma_m² and the residuals' own (Huber-weighted)
    // variance (residual_sigma); widened by C_m as Λ'.
    const double residual_sigma2 = config.residual_sigma && matched > 3 ? sum_we2 / (matched - 3) : 0.0;
    const double calibration = sigma2 / std::max(sigma2, residual_sigma2);
    const Eigen::Matrix3d Lambda_at_range = calibration * laser_weight * A_laser_at_range;
    const Eigen::Matrix3d Lambda_calibrated =
        symmetrised((Eigen::Matrix3d::Identity() + Lambda_at_range * C_m).inverse() * Lambda_at_range);
    const Pose2 r_pose = between(u_hat, x);
    const Eigen::Vector3d r(r_pose.x, r_pose.y, wrap_angle(r_pose.phi));
    const Eigen::Matrix3d J_r = prior_residual_jacobian(u_hat, x);
    const double d2 = r.dot(Q_inv * r);
    const double w_prior = d2 <= prior_k2 ? 1.0 : std::sqrt(prior_k2 / d2);
    out.match.prior_weight = w_prior;
    const Eigen::Matrix3d prior_information = w_prior * J_r.transpose() * Q_inv * J_r;
    H = Lambda_widened + prior_information;
    H_covariance = Lambda_calibrated + prior_information;
    const Eigen::Vector3d gradient = widen * (laser_weight * g_laser) + w_prior * J_r.transpose() * Q_inv * r;
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
  out.match.prior_residual = Eigen::Vector3d(r_pose.x, r_pose.y, wrap_angle(r_pose.phi));
  out.match.prior_distance2 = out.match.prior_residual.dot(Q_inv * out.match.prior_residual);
  const Eigen::LLT<Eigen::Matrix3d> H_llt(H_covariance);
  if (H_llt.info() != Eigen::Success) return std::nullopt;
  out.match.x_AB = x;
  out.match.search_pose = x0;
  out.match.covariance = symmetrised(H_llt.solve(Eigen::Matrix3d::Identity()));
  out.match.static_x_AB = out.match.x_AB;
  out.match.static_laser_information = out.match.laser_information;
  return out;
}

// The window of the search for the points B around û (all in metres and radians).
CorrelativeWindow search_window(const std::vector<Eigen::Vector2d>& points, const ScanMatcherConfig& config) {
  // The angular step moves a point at the 90th-percentile range by one cell
  // (points farther move more, but are few: the coarse pose only has to land
  // inside the refinement's basin).
  std::vector<double> ranges;
  ranges.reserve(points.size());
  for (const Eigen::Vector2d& p : points) ranges.push_back(p.norm());
  const auto at = ranges.begin() + static_cast<std::ptrdiff_t>(0.9 * static_cast<double>(ranges.size() - 1));
  std::nth_element(ranges.begin(), at, ranges.end());
  // Capped at 10 m: beyond, the step would shrink below 0.01 rad, which
  // still moves points at 20 m by only 0.2 m, inside the first gate.
  const double range = std::clamp(*at, 1.0, 10.0);
  return {config.search_window_m, config.search_window_rad, config.search_resolution_m / range};
}

// The reference points and, for each, two samples along its line (the tangent
// of its normal) at ± half_length_m (the field's σ: between two samples of a
// wall's points up to 2 σ apart, no place is more than σ/2 from one): the likelihood
// field then stands for the walls, not for where the beams happened to hit
// them. Without them, walls seen by a sparse laser (1° between beams: 9 cm
// apart at 5 m, 17 cm at 10 m) score between their points as if they were
// missing, and a scan that moved far (little overlap left) fails min_overlap
// at the right pose.
std::vector<Eigen::Vector2d> points_along_lines(const ReferenceScan& A, double half_length_m) {
  std::vector<Eigen::Vector2d> out;
  out.reserve(3 * A.size());
  for (std::size_t i = 0; i < A.size(); ++i) {
    const Eigen::Vector2d& p = A.points()[i];
    const Eigen::Vector2d t(-A.normals()[i].y(), A.normals()[i].x());
    out.push_back(p);
    for (const double s : {-1.0, 1.0}) out.push_back(p + s * half_length_m * t);
  }
  return out;
}

// B thinned to one point per cell_m square (the first given wins).
std::vector<Eigen::Vector2d> thinned_points(const std::vector<Eigen::Vector2d>& B, double cell_m) {
  std::vector<Eigen::Vector2d> out;
  for (const std::size_t i : thinned(B, cell_m)) out.push_back(B[i]);
  return out;
}

// The search's likelihood field of A (cells and σ of search_resolution_m, with
// `levels` levels), over where the points can land from any of the poses
// `centres` moved by up to ± linear_m and turned by up to ± angular_rad, and
// where A has points; std::nullopt where the two do not meet.
std::optional<LikelihoodField> search_field(const ReferenceScan& A, const std::vector<Eigen::Vector2d>& points,
                                            const std::vector<Pose2>& centres, double linear_m, double angular_rad,
                                            int levels, const ScanMatcherConfig& config) {
  const double resolution = config.search_resolution_m;
  Eigen::AlignedBox2d reach;
  double farthest = 0.0;
  for (const Pose2& c : centres) {
    const Eigen::Matrix2d R = rotation(c.phi);
    for (const Eigen::Vector2d& b : points) {
      reach.extend(Eigen::Vector2d(c.x, c.y) + R * b);
      farthest = std::max(farthest, b.norm());
    }
  }
  // A turn by θ carries a point at range ρ sideways by ρ sin θ. Its full
  // displacement, 2 ρ sin(θ / 2), is larger: by 0.002 ρ at the default window
  // (0.25 rad), 0.05 ρ at the escalated one (0.75 rad); points that land
  // beyond the field read 0. Not widened: the field's cells are anchored at
  // its region's corner, so a wider region requantises every score
  // (docs/results.md, "The search escalates").
  const double margin =
      linear_m + farthest * std::sin(std::min(angular_rad, std::numbers::pi / 2.0)) + 2.0 * resolution;
  reach.min().array() -= margin;
  reach.max().array() += margin;
  Eigen::AlignedBox2d reference_bounds = A.bounds();
  reference_bounds.min().array() -= 2.0 * resolution;
  reference_bounds.max().array() += 2.0 * resolution;
  const Eigen::AlignedBox2d region = reach.intersection(reference_bounds);
  if (region.isEmpty()) return std::nullopt;
  std::vector<Eigen::Vector2d> field_points = config.field_along_lines ? points_along_lines(A, resolution) : A.points();
  field_points.insert(field_points.end(), A.unoriented_points().begin(), A.unoriented_points().end());
  return LikelihoodField(field_points, region, resolution, resolution, levels);
}

}  // namespace

std::optional<ScanMatch> refine_match(const ReferenceScan& A, const std::vector<Eigen::Vector2d>& B,
                                      const Pose2& x0, const Pose2& u_hat, const Eigen::Matrix3d& Q,
                                      const ScanMatcherConfig& config) {
  config.validate();
  const Eigen::Matrix3d Q_inv = checked_inverse_of_prior(u_hat, Q);
  std::optional<Refinement> r = refine(A, B, x0, u_hat, Q_inv, config);
  if (!r) return std::nullopt;
  return r->match;
}

std::optional<ScanMatch> match_scans(const ReferenceScan& A, const std::vector<Eigen::Vector2d>& B,
                                     const Pose2& u_hat, const Eigen::Matrix3d& Q, const ScanMatcherConfig& config) {
  config.validate();
  const Eigen::Matrix3d Q_inv = checked_inverse_of_prior(u_hat, Q);
  if (static_cast<int>(B.size()) < config.min_correspondences || A.size() < 3) return std::nullopt;

  // Stage 1: the correlative search, on B thinned to one point per cell.
  const double resolution = config.search_resolution_m;
  const std::vector<Eigen::Vector2d> search_points = thinned_points(B, resolution);
  if (search_points.empty()) return std::nullopt;  // none finite
  const CorrelativeWindow window = search_window(search_points, config);
  // Enough levels that one top-level block spans the window's translations.
  const std::optional<LikelihoodField> field =
      search_field(A, search_points, {u_hat}, window.linear_m, window.angular_rad,
                   LikelihoodField::levels_for(window.linear_m, resolution), config);
  if (!field) return std::nullopt;
  const std::optional<CorrelativeResult> search =
      correlative_search(*field, search_points, u_hat, window, config.min_overlap, config.ambiguity_ratio);
  if (!search) return std::nullopt;
  const CorrelativeMatch* best = &search->best;

  // Stage 2: the refinement from the search's best pose.
  std::optional<Refinement> refined = refine(A, B, best->x, u_hat, Q_inv, config);
  if (!refined) return std::nullopt;

  // Ambiguity: another pose of the window nearly as good, whose points lie
  // more than two cells (RMS, across their surfaces) from the best's. Poses
  // that differ only in directions the scene does not constrain (along a
  // corridor) are the same peak: the prior decides those.
  const Eigen::Matrix3d M = refined->mean_point_information;
  const double separation2 = 4.0 * resolution * resolution;
  for (const CorrelativeMatch& other : search->contenders) {
    const Pose2 d = between(best->x, other.x);
    const Eigen::Vector3d delta(d.x, d.y, wrap_angle(d.phi));
    if (delta.dot(M * delta) > separation2) return std::nullopt;
  }
  refined->match.search_score = best->score;
  refined->match.search_pose = best->x;
  refined->match.search_at_window_edge = on_window_edge(best->x, u_hat, window, resolution);
  return refined->match;
}

std::optional<ScanMatch> match_scans(const ReferenceScan& A, const ScanPoints& B, const Pose2& u_hat,
                                     const Eigen::Matrix3d& Q, const ScanMatcherConfig& config) {
  std::optional<ScanMatch> with_objects = match_scans(A, B.all, u_hat, Q, config);
  if (B.structure.size() == B.all.size()) return with_objects;
  // Without the objects: from the full match's pose (the MAP problem is the
  // same but for the objects' points, so its optimum is near), or searched
  // afresh when the objects made the full match fail.
  std::optional<ScanMatch> structure =
      with_objects ? refine_match(A, B.structure, with_objects->x_AB, u_hat, Q, config)
                   : match_scans(A, B.structure, u_hat, Q, config);
  if (!structure) {
    // The objects are most of what there is: nothing to tell them apart from.
    return with_objects;
  }
  structure->static_x_AB = structure->x_AB;
  structure->static_laser_information = structure->laser_information;
  if (!with_objects) {
    structure->objects_moving = true;
    return structure;
  }
  // Do the objects agree with the rest of the scene? The full estimate seen
  // from the structure's, against the structure's covariance (a conservative
  // stand-in for that of the difference, Σ_structure − Σ_all).
  if (differs_beyond(*structure, with_objects->x_AB, config.object_consistency_alpha)) {
    structure->objects_moving = true;
    structure->search_score = with_objects->search_score;
    structure->search_pose = with_objects->search_pose;
    structure->search_at_window_edge = with_objects->search_at_window_edge;
    return structure;
  }
  with_objects->static_x_AB = structure->x_AB;
  with_objects->static_laser_information = structure->laser_information;
  return with_objects;
}

std::vector<double> explained_shares(const ReferenceScan& A, const std::vector<Eigen::Vector2d>& B,
                                     const std::vector<Pose2>& poses, const ScanMatcherConfig& config) {
  config.validate();
  std::vector<double> shares(poses.size(), 0.0);
  const std::vector<Eigen::Vector2d> points = thinned_points(B, config.search_resolution_m);
  if (points.empty() || A.size() < 3) return shares;
  const std::optional<LikelihoodField> field = search_field(A, points, poses, 0.0, 0.0, 1, config);
  if (!field) return shares;
  for (std::size_t k = 0; k < poses.size(); ++k) {
    const Eigen::Matrix2d R = rotation(poses[k].phi);
    const Eigen::Vector2d t(poses[k].x, poses[k].y);
    double sum = 0.0;
    for (const Eigen::Vector2d& b : points) sum += field->likelihood(t + R * b);
    shares[k] = sum / static_cast<double>(points.size());
  }
  return shares;
}

bool differs_beyond(const ScanMatch& match, const Pose2& other, double alpha) {
  const Pose2 d = between(match.x_AB, other);
  const Eigen::Vector3d delta(d.x, d.y, wrap_angle(d.phi));
  const Eigen::LDLT<Eigen::Matrix3d> ldlt(match.covariance);
  const double d2 = delta.dot(ldlt.solve(delta));
  return ldlt.info() == Eigen::Success && std::isfinite(d2) && d2 > spmap::chi2_threshold(3, alpha);
}

}  // namespace lmf
