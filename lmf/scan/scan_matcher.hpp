// Scan matching that estimates one odometry increment (an addition to the
// paper's local map, docs/design.md §4.1 and §10): the current scan B against a
// reference A, the union of the last few scans expressed in the newest one's
// frame (scan_history.hpp), in two stages:
//  1. a correlative search (correlative_search.hpp) over a window of poses
//     around the odometry increment, as wide as odometry errors physically get
//     (glitches of several degrees, slip and scale errors of tens of cm), so a
//     wrong odometry increment no longer starts the refinement outside its basin;
//  2. point-to-line Gauss–Newton from the best pose of the window, a maximum a
//     posteriori estimate with the odometry increment as prior, so directions
//     the laser does not constrain (along a corridor) keep the odometry's
//     estimate and uncertainty.
// The match is refused (std::nullopt: the caller keeps the odometry) when the
// scan overlaps the reference too little, or when the window holds a second
// peak nearly as good as the best and distinct from it in the directions the
// laser constrains (an ambiguous scene). It is NOT refused for disagreeing
// with the odometry prior: a wrong prior is what the window is for.
//
// Notation (all in the robot = sensor frame):
//   A  the reference, points a_j with unit normals n_j;
//   B  the current scan, points b_i;
//   u  the increment x_AB (pose of B seen from A), û its odometry estimate with
//      perturbation p_u (u = û ⊕ p_u, p_u ~ N(0, Q)), as LocalMap::predict uses.
// The laser term is Λ = s Σ_i w_i J_iᵀ J_i / σ² (J_i the Jacobian of the
// point-to-line distance e_i = n_jᵀ (x ⊙ b_i − a_j) with respect to δ in
// x ⊕ δ, w_i Huber weights, correspondences j(i) the nearest reference point
// within a gate, re-found each iteration), scaled by s to the effective number
// of independent points: N (1 − ρ)/(1 + ρ) for residuals with lag-1
// correlation ρ along the scan (`residual_correlation`), and at most
// `max_independent_points` (the segment observations use the same points
// again), so that the raw count does not make it overconfident. Λ⁻¹ is then
// widened by a model noise C_m (walls are not perfect lines, the scans not
// instantaneous),
// Λ' = (Λ⁻¹ + C_m)⁻¹ = (I + Λ C_m)⁻¹ Λ, which stays defined where Λ is singular
// (a corridor). Gauss–Newton on x ← x ⊕ δ then solves the maximum a posteriori
// problem of that laser term and the prior r(x) = between(û, x) ~ N(0, Q); the
// result's covariance is (Λ'_r + J_rᵀ Q⁻¹ J_r)⁻¹ at the optimum, Λ'_r the same
// laser term with each point at its own σ_i (range_noise_per_m; Λ' where that
// is 0). The
// correspondence gate starts at first_gate_m and halves each time the estimate
// settles, down to last_gate_m.
//
// Pure functions, thread-safe.
#pragma once

#include <cstddef>
#include <optional>
#include <vector>

#include <Eigen/Core>
#include <Eigen/Geometry>

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
  // Small objects in front of their surroundings (foreground_objects.hpp):
  // people and robots, which may move, are at most this wide (m; 0: none are
  // told apart) ...
  double max_object_extent_m = 0.8;
  // ... and stand out from what lies beside them by a range jump of at least this (m).
  double object_range_jump_m = 0.3;
  // The match with them is kept unless the match without them differs from
  // it beyond chi2inv(1 - object_consistency_alpha, 3): then they moved.
  double object_consistency_alpha = 0.01;
  // A reference point gets a normal from its beam neighbours within this
  // distance (m), or within 2.5 r Δθ where the beams are farther apart (two beam
  // steps at the point's range r, on a surface up to 37° from facing the
  // sensor), when they lie on a line (smallest / largest scatter eigenvalue
  // below max_normal_flatness); points without one still count in the search's
  // field, not in the refinement.
  double normal_radius_m = 0.5;
  double max_normal_flatness = 0.1;

  // The correlative search's window around the odometry increment: ± this
  // translation (m, each axis) and rotation (rad). Physical sizes, independent
  // of the odometry covariance (which may be wrong): wheel odometry's increment
  // errors per step are a few % of the step (scale), centimetres of slip, and
  // heading errors of a few degrees with glitches up to ~10° (a wheel slipping
  // on a threshold); the translation error of a half-metre step stays under a
  // decimetre. The window holds these with a margin of ~3.
  double search_window_m = 0.3;
  double search_window_rad = 0.25;
  // Cell size (m) of the likelihood field, also its kernel's sigma: a pose of the
  // window is off by at most half a cell, well inside the refinement's gates.
  // The angular step is the same arc at the scan's 90th-percentile range.
  double search_resolution_m = 0.1;
  // The best pose of the window must explain at least this share of the scan's
  // points (mean likelihood): less, and the scans barely overlap.
  double min_overlap = 0.25;
  // The search's likelihood field is drawn from all of the reference's usable
  // points, as the search scores all of the scan's (those without a normal as
  // they are: a sparse laser's far walls, corners, clutter), and from samples
  // along each oriented point's line (± search_resolution_m along the tangent of
  // its normal), so it stands for the walls rather than for where the beams
  // hit them: a sparse laser's walls (1° between beams: 17 cm apart at 10 m)
  // otherwise score between their points as if missing.
  bool field_along_lines = true;
  // Ambiguous when a second pose of the window, distinct from the best (points
  // moved by more than two cells across their surfaces, RMS), scores at least
  // this fraction of the best.
  double ambiguity_ratio = 0.9;

  // Reference history (scan_history.hpp): at most history_scans scans (the
  // newest always), an older one kept only when it lies at least
  // keyframe_distance_m or keyframe_angle_rad from the next newer one kept;
  // the union is thinned to one point per reference_voxel_m square.
  int history_scans = 4;
  double keyframe_distance_m = 0.2;
  double keyframe_angle_rad = 0.1;
  double reference_voxel_m = 0.05;

  // Correspondence gate (m) of the refinement: from first (the search's
  // residual error of half a cell and half an angular step, with margin),
  // halved each time the estimate settles, down to last.
  double first_gate_m = 0.5;
  double last_gate_m = 0.25;
  int max_iterations = 30;
  // Fewer matched points than this: no estimate (odometry alone).
  int min_correspondences = 30;
  // Std of one point's distance to its line (m), and the Huber threshold in units of it.
  double point_sigma_m = 0.03;
  // The match's covariance (what the local map's filter receives) takes
  // each point at σ_i² = point_sigma_m² + (range_noise_per_m r)², r its range,
  // as a laser's accuracy is stated (a constant, or a share of the range,
  // whichever is larger). The estimate, and the laser information the odometry
  // model learns with, keep point_sigma_m for every point (docs/results.md,
  // "The point noise grows with the range"). When range_noise_from_residuals
  // is set, the front end measures range_noise_per_m on the log itself from
  // the registrations' residuals (lmf/front_end/range_noise_estimate.hpp), and
  // this value holds until it has.
  double range_noise_per_m = 0.0;
  bool range_noise_from_residuals = true;
  double huber_k = 2.0;
  // When set, the match's covariance (what the local map's filter receives)
  // takes the laser term at σ² = max(point_sigma_m², Σ_i w_i e_i² / (N − 3)),
  // the match's own Huber-weighted residual variance where it is larger: a
  // scan whose walls fit worse than point_sigma_m (a noisier laser, a sparse
  // one at long range, clutter) reports a wider covariance. The estimate
  // itself, and the laser information the odometry model learns with, keep
  // point_sigma_m. Off by default (docs/results.md, "The match's covariance
  // from its residuals"). With range_noise_per_m as well, it scales every
  // σ_i² by the same factor, and a range-grown spread counts twice.
  bool residual_sigma = false;
  // When set, the matched points count as N (1 − ρ) / (1 + ρ) independent
  // ones (an AR(1) sequence along the scan), ρ ∈ [0, 0.99] the lag-1
  // covariance of the Huber-clipped residuals of neighbouring beams over the
  // point variance (point_sigma_m², or the residuals' own when larger): a
  // wall bent away from its line, or a reference point's line off, moves
  // many neighbouring residuals together, and they are then one
  // measurement, not many. White range noise, or residuals well inside
  // point_sigma_m, give ρ ≈ 0 and the count alone.
  bool residual_correlation = true;
  // The laser information counts at most this many independent points ...
  double max_independent_points = 20.0;
  // ... and its covariance widened by this model noise: std of x and y (m) and
  // of the angle (rad), in quadrature.
  double model_noise_m = 0.01;
  double model_noise_rad = 0.003;
  // The prior is robust (Huber on its Mahalanobis distance d): beyond
  // d² = chi2inv(1 - prior_alpha, 3) its information is scaled by
  // sqrt(chi2inv) / d, so an odometry increment the laser proves wrong pulls
  // the estimate less, and its covariance widens accordingly. Never a reason
  // to refuse the match.
  double prior_alpha = 0.01;

  // Throws std::invalid_argument naming the first invalid field and its value.
  void validate() const;
};

// What the search window stands for: it is sized to hold what the motion can
// do between two scans at 3σ, so σ = search_window_m / 3 in x and y and
// search_window_rad / 3 in heading; the diagonal covariance of those.
Eigen::Matrix3d search_window_covariance(const ScanMatcherConfig& config);

// Points of a scan with unit normals facing the sensor, in the scan's frame:
// those usable points whose beam neighbours (normal_radius_m, max_normal_flatness)
// lie on a line; and the other usable points (corners, clutter, walls seen at
// grazing incidence), which have no line to be
// matched against but still show where the scan saw something.
struct OrientedPoints {
  std::vector<Eigen::Vector2d> points;
  std::vector<Eigen::Vector2d> normals;
  std::vector<Eigen::Vector2d> unoriented;
};
OrientedPoints oriented_points(const LaserScan& scan, const ScanMatcherConfig& config);

// The reference A prepared for matching: points with normals in A's frame,
// thinned to one per reference_voxel_m square (the first given wins), and
// indexed by square cells of last_gate_m for nearest-point queries.
class ReferenceScan {
 public:
  ReferenceScan() = default;
  // One scan.
  static ReferenceScan from(const LaserScan& scan, const ScanMatcherConfig& config);
  // Any set of oriented points (the union of a history). Throws
  // std::invalid_argument when the sizes differ.
  static ReferenceScan from_points(const OrientedPoints& points, const ScanMatcherConfig& config);

  const std::vector<Eigen::Vector2d>& points() const { return points_; }
  const std::vector<Eigen::Vector2d>& normals() const { return normals_; }
  // The usable points without a normal (thinned alike): the correlative
  // search's likelihood field is drawn from them as well, since it scores all
  // of the current scan's points, not only those on lines.
  const std::vector<Eigen::Vector2d>& unoriented_points() const { return unoriented_; }
  std::size_t size() const { return points_.size(); }
  const Eigen::AlignedBox2d& bounds() const { return bounds_; }
  // The index of the reference point nearest to q within `gate` (m), -1 when none.
  int nearest(const Eigen::Vector2d& q, double gate) const;

 private:
  std::vector<Eigen::Vector2d> points_;
  std::vector<Eigen::Vector2d> normals_;
  std::vector<Eigen::Vector2d> unoriented_;
  Eigen::AlignedBox2d bounds_;
  // Cells of cell_m_ from bounds_.min(): cell c holds cell_points_[cell_start_[c] .. cell_start_[c + 1]).
  double cell_m_ = 1.0;
  int width_ = 0;
  int height_ = 0;
  std::vector<int> cell_start_;
  std::vector<int> cell_points_;
};

// The usable points of scan B (m, robot frame).
std::vector<Eigen::Vector2d> scan_points(const LaserScan& scan, const ScanMatcherConfig& config);

// The same, and those of them not on small foreground objects (max_object_extent_m).
struct ScanPoints {
  std::vector<Eigen::Vector2d> all;
  std::vector<Eigen::Vector2d> structure;
};
ScanPoints scan_points_by_kind(const LaserScan& scan, const ScanMatcherConfig& config);

struct ScanMatch {
  Pose2 x_AB;                    // the refined increment
  // Of its perturbation p (x_true = x_AB ⊕ p): (Λ'_r + J_rᵀ Q⁻¹ J_r)⁻¹, Λ'_r the
  // laser term with each point at its σ_i (range_noise_per_m), and at the
  // residuals' σ when larger than point_sigma_m (residual_sigma).
  Eigen::Matrix3d covariance;
  // The laser's own information about p at the optimum at point_sigma_m, Λ'
  // (widened by the model noise; singular where the scene does not constrain
  // a direction): the weight of the laser in x_AB.
  // With the prior residual below, an odometry error model can compare the
  // odometry with the laser in the directions the laser constrains.
  Eigen::Matrix3d laser_information;
  // r = between(û, x_AB) as (x, y, φ): where the match puts the truth relative
  // to the odometry increment, in û's frame (the perturbation p_u of û).
  Eigen::Vector3d prior_residual = Eigen::Vector3d::Zero();
  double prior_distance2 = 0.0;  // rᵀ Q⁻¹ r (reported; not a reason to refuse)
  double prior_weight = 1.0;     // the robust prior's weight on Q⁻¹ (config.prior_alpha)
  int correspondences = 0;       // matched points at the last iteration
  int iterations = 0;
  double rms_m = 0.0;            // RMS point-to-line distance of the matched points
  double search_score = 0.0;     // the correlative search's best score (mean likelihood, [0, 1])
  Pose2 search_pose;             // ... and its pose
  // The search's best pose lies on the outermost ring of its window
  // (on_window_edge): the motion may have done more than the window holds.
  bool search_at_window_edge = false;
  // The overload on ScanPoints only: the small foreground objects disagreed
  // with the rest of the scene (or made the match fail), so this match is
  // without them.
  bool objects_moving = false;
  // The increment and laser information from the static structure alone
  // (without small foreground objects; x_AB and laser_information when the
  // scan has none). An object that moves along with the robot biases x_AB a
  // little, scan after scan, below what one comparison can tell: the odometry
  // error model learns from these instead, or the bias would become its scale.
  Pose2 static_x_AB;
  Eigen::Matrix3d static_laser_information = Eigen::Matrix3d::Zero();
};

// Matches B against A with the odometry increment û and covariance Q (of p_u,
// positive definite) as prior: the correlative search around û, then the
// refinement. std::nullopt when the overlap is too small, the best pose is
// ambiguous, or there are too few correspondences: the caller keeps û, Q.
// Throws std::invalid_argument for an invalid config, non-finite û or a Q that
// is not symmetric positive definite.
std::optional<ScanMatch> match_scans(const ReferenceScan& A, const std::vector<Eigen::Vector2d>& B,
                                     const Pose2& u_hat, const Eigen::Matrix3d& Q, const ScanMatcherConfig& config);

// The same, robust to objects that move: B.all matched as above; when B has
// small foreground objects, the match without them (B.structure) is tried as
// well and returned instead when the two differ beyond
// chi2inv(1 - object_consistency_alpha, 3) in the covariance of the match
// without them, or when only it succeeds (objects_moving is then set). A robot
// following another down a corridor sees its body at a constant distance
// ahead: matched, the body says "standing still" where the walls say nothing.
std::optional<ScanMatch> match_scans(const ReferenceScan& A, const ScanPoints& B, const Pose2& u_hat,
                                     const Eigen::Matrix3d& Q, const ScanMatcherConfig& config);

// Whether two increments differ beyond chi2inv(1 - alpha, 3): the offset of
// `other` seen from `match`, in match's covariance (false where it is not
// positive definite enough to tell).
bool differs_beyond(const ScanMatch& match, const Pose2& other, double alpha);

// The share of B's points each of `poses` explains: their mean likelihood on
// one likelihood field of A, built as the correlative search's (cells and σ of
// search_resolution_m, B thinned to one point per cell), so poses found by
// different searches compare on one footing. Its cells are anchored at its own
// region's corner, so a pose may score a little differently from what a search
// over another region gave it. 0 where B or A is empty.
// Throws std::invalid_argument for an invalid config.
std::vector<double> explained_shares(const ReferenceScan& A, const std::vector<Eigen::Vector2d>& B,
                                     const std::vector<Pose2>& poses, const ScanMatcherConfig& config);

// The refinement alone (stage 2, from the start pose x0 instead of the search's
// best): for tests that compare it with the full match. std::nullopt on too few
// correspondences or a failed solve.
std::optional<ScanMatch> refine_match(const ReferenceScan& A, const std::vector<Eigen::Vector2d>& B,
                                      const Pose2& x0, const Pose2& u_hat, const Eigen::Matrix3d& Q,
                                      const ScanMatcherConfig& config);

// Jacobians of the two residual kinds with respect to δ in x ⊕ δ, at δ = 0
// (exposed for the finite-difference tests):
// e = nᵀ (x ⊙ b − a), a 1 x 3 row;
Eigen::RowVector3d point_to_line_jacobian(const Pose2& x, const Eigen::Vector2d& b, const Eigen::Vector2d& n);
// r = between(û, x) as (x, y, φ), 3 x 3.
Eigen::Matrix3d prior_residual_jacobian(const Pose2& u_hat, const Pose2& x);

}  // namespace lmf
