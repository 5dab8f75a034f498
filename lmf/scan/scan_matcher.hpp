// Scan-to-scan matching that refines one odometry increment (an addition to the
// paper's local map, DESIGN §4.1 step 1): point-to-line ICP of the current scan
// against the previous one, solved as a maximum a posteriori estimate with the
// odometry increment as prior, so directions the scans do not constrain (along
// a corridor) keep the odometry's estimate and uncertainty.
//
// Notation (all in the robot = sensor frame):
//   A  the reference (previous) scan, points a_j with unit normals n_j;
//   B  the current scan, points b_i;
//   u  the increment x_AB (pose of B seen from A), û its odometry estimate with
//      perturbation p_u (u = û ⊕ p_u, p_u ~ N(0, Q)), as LocalMap::predict uses.
// The laser term is Λ = s Σ_i w_i J_iᵀ J_i / σ² (J_i the Jacobian of the
// point-to-line distance e_i = n_jᵀ (x ⊙ b_i − a_j) with respect to δ in
// x ⊕ δ, w_i Huber weights, correspondences j(i) re-found by projection onto
// A's beams each iteration), scaled by s to at most `max_independent_points`
// effective points: neighbouring points' errors are correlated and the segment
// observations use the same points again, so the raw count would make it
// overconfident. Λ⁻¹ is then widened by a model noise C_m (walls are not
// perfect lines, the scans not instantaneous), Λ' = (Λ⁻¹ + C_m)⁻¹ = (I + Λ C_m)⁻¹ Λ,
// which stays defined where Λ is singular (a corridor). Gauss–Newton on
// x ← x ⊕ δ then solves the maximum a posteriori problem of that laser term and
// the prior r(x) = between(û, x) ~ N(0, Q); the result's covariance is
// (Λ' + J_rᵀ Q⁻¹ J_r)⁻¹ at the optimum. The correspondence gate starts at
// first_gate_m and halves each time the estimate settles, down to last_gate_m.
//
// Pure functions, thread-safe.
#pragma once

#include <cstddef>
#include <optional>
#include <vector>

#include <Eigen/Core>

#include "lmf/geometry/pose2.hpp"
#include "lmf/scan/laser_scan.hpp"

namespace lmf {

struct ScanMatcherConfig {
  // On by default (LocalMap::process_scan); the paper's agent uses odometry alone.
  bool enabled = true;
  // Readings outside [min_range_m, max_range_m] (and "no return" readings) are not used.
  double min_range_m = 0.05;
  double max_range_m = 30.0;
  double no_return_margin_m = 0.1;  // a reading >= scan.max_range_m - this is "no return"
  // A reference point gets a normal from its beam neighbours within this
  // distance (m) when they lie on a line (smallest / largest scatter eigenvalue
  // below max_normal_flatness); points without one are not used.
  double normal_radius_m = 0.5;
  double max_normal_flatness = 0.1;
  // Correspondence gate (m): from first (coarse, odometry-sized errors), halved
  // each time the estimate settles, down to last.
  double first_gate_m = 1.0;
  double last_gate_m = 0.25;
  int max_iterations = 30;
  // Fewer matched points than this: no estimate (odometry alone).
  int min_correspondences = 30;
  // Std of one point's distance to its line (m), and the Huber threshold in units of it.
  double point_sigma_m = 0.03;
  double huber_k = 2.0;
  // The laser information is scaled to at most this many independent points ...
  double max_independent_points = 20.0;
  // ... and its covariance widened by this model noise: std of x and y (m), of
  // the angle (rad), and of the angle per radian turned (a scan taken while
  // turning is skewed by the turn during the sweep), in quadrature.
  // (The turn term made the matched increments' NEES on the real logs more
  // consistent but their angles and the missions' ATE worse: off by default.)
  double model_noise_m = 0.01;
  double model_noise_rad = 0.003;
  double model_noise_per_rad = 0.0;
  // The estimate is rejected (odometry alone) when its Mahalanobis distance to
  // the odometry increment, r(x)ᵀ Q⁻¹ r(x), exceeds chi2inv(1 - prior_alpha, 3).
  double prior_alpha = 1e-4;

  // Throws std::invalid_argument naming the first invalid field and its value.
  void validate() const;
};

// Scan A prepared for matching: its usable points with their normals, in beam order.
struct ReferenceScan {
  double angle_min_rad = 0.0;
  double angle_increment_rad = 0.0;
  std::vector<int> point_of_beam;     // beam -> index into points, -1 when unusable
  std::vector<Eigen::Vector2d> points;
  std::vector<Eigen::Vector2d> normals;
  std::vector<double> ranges_m;

  static ReferenceScan from(const LaserScan& scan, const ScanMatcherConfig& config);
};

// The usable points of scan B (m, robot frame).
std::vector<Eigen::Vector2d> scan_points(const LaserScan& scan, const ScanMatcherConfig& config);

struct ScanMatch {
  Pose2 x_AB;                    // the refined increment
  Eigen::Matrix3d covariance;    // of its perturbation p (x_true = x_AB ⊕ p)
  int correspondences = 0;       // matched points at the last iteration
  int iterations = 0;
  double rms_m = 0.0;            // RMS point-to-line distance of the matched points
  double prior_distance2 = 0.0;  // r(x)ᵀ Q⁻¹ r(x) at the estimate
};

// Matches B against A starting from the odometry increment û with covariance Q
// (of p_u, positive definite). std::nullopt when there are too few
// correspondences or the estimate fails the prior test: the caller keeps û, Q.
// Throws std::invalid_argument for an invalid config, non-finite û or a Q that
// is not symmetric positive definite.
std::optional<ScanMatch> match_scans(const ReferenceScan& A, const std::vector<Eigen::Vector2d>& B,
                                     const Pose2& u_hat, const Eigen::Matrix3d& Q, const ScanMatcherConfig& config);

// Jacobians of the two residual kinds with respect to δ in x ⊕ δ, at δ = 0
// (exposed for the finite-difference tests):
// e = nᵀ (x ⊙ b − a), a 1 x 3 row;
Eigen::RowVector3d point_to_line_jacobian(const Pose2& x, const Eigen::Vector2d& b, const Eigen::Vector2d& n);
// r = between(û, x) as (x, y, φ), 3 x 3.
Eigen::Matrix3d prior_residual_jacobian(const Pose2& u_hat, const Pose2& x);

}  // namespace lmf
