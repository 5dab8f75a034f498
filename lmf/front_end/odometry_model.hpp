// The robot's odometry error model, learned online from the disagreement
// between the odometry and the scan matcher (beyond the paper; docs/design.md §10).
//
// The paper predicts with a known odometry noise proportional to the motion. A
// real robot's wheel odometry has systematic errors (wheel radius and wheelbase
// scale, unequal wheels), slip, heading noise that does not vanish when driving
// straight and occasional glitches; and every robot is different. So the agent
// estimates its own model while it runs and predicts with it; the configuration
// gives only the starting prior.
//
// Model. For an odometry increment û = (x, y, φ) with d = |(x, y)|:
//   systematic:  ū = (k_t x, k_t y, k_r φ + b d)      (corrected(û))
//   random:      u_true = ū ⊕ p_u,  p_u ~ N(0, Q(û)), Q diagonal (covariance(û)):
//     σ_x² = x_step² + x_per_m² d²
//     σ_y² = y_step² + y_per_m² d²
//     σ_φ² = φ_step² + φ_per_m² d² + φ_per_rad² φ² + c_φ |φ| d
//   (c_φ makes the paper's σ_φ = a|φ| + b d, squared, a special case.)
//
// Learning. Each scan match gives the MAP increment x under the prior (ū, Q) and
// the laser's own information Λ (possibly singular: a corridor says nothing
// along its axis). With e = x ⊖ ū (tangent vector), the laser-only estimate z
// satisfies g := Λ z = (Λ + Q⁻¹) e, a quantity that does not depend on the
// prior; the learner keeps (û, θ̂, g, Λ) of the last memory_increments matches
// and re-estimates the model from all of them with the current model, as an
// EM / iteratively reweighted least squares sweep after each new match (older
// matches stay in the systematic part's normal equations as they were when
// they left the memory):
//  * for the current model, e = (Λ + Q⁻¹)⁻¹ g' (g' = g shifted to the current
//    systematic correction) and the innovation information is W z = Q⁻¹ e with
//    W = (Λ⁻¹ + Q)⁻¹, so nothing needs Λ⁻¹;
//  * robustness: a Student-t weight ρ = (ν + 3) / (ν + NIS), with the innovation
//    NIS = zᵀ W z = eᵀ Q⁻¹ e + (Q⁻¹e)ᵀ Λ⁺ (Q⁻¹e); a glitch of several degrees
//    gets a small weight and does not inflate the model for good;
//  * systematic part θ = (k_t − 1, k_r − 1, b): weighted least squares on
//    z ≈ A (θ − θ̂) with information ρ W (A = ∂(ū(θ) ⊖ ū(θ̂))/∂θ), with a
//    Gaussian prior on θ;
//  * random part: E[p_u p_uᵀ | z] = e eᵀ + (Λ + Q⁻¹)⁻¹ is the expected squared
//    noise (ρ-weighted, corrected so that Gaussian noise is estimated without
//    bias), regressed per axis on the regressors above with
//    Fisher-scoring weights 1/σ⁴ and non-negative coefficients, beside the
//    prior's variances counted as prior_increments samples. Directions the laser
//    does not constrain give back the current model: no change.
// Pure and deterministic; not thread-safe.
#pragma once

#include <cstddef>
#include <deque>
#include <string>
#include <vector>

#include <Eigen/Core>

#include "lmf/geometry/pose2.hpp"

namespace lmf {

struct OdometryErrorModel {
  // Systematic part (dimensionless scales; rad per m).
  double translation_scale = 1.0;
  double rotation_scale = 1.0;
  double heading_bias_rad_per_m = 0.0;
  // Random part: standard deviations per step (m, rad), per metre travelled
  // (m/m, rad/m), per radian turned (rad/rad), and the |φ| d cross term (rad²/(rad m)).
  double x_step_m = 0.0;
  double x_per_m = 0.0;
  double y_step_m = 0.0;
  double y_per_m = 0.0;
  double phi_step_rad = 0.0;
  double phi_per_m = 0.0;
  double phi_per_rad = 0.0;
  double phi_turn_distance = 0.0;

  // The paper's proportional model (LocalMapConfig step 1): σ_xy = ratio d ⊕ floor,
  // σ_φ = rotation_ratio |φ| + drift d ⊕ floor, no systematic error.
  static OdometryErrorModel proportional(double translation_ratio, double rotation_ratio, double drift_rad_per_m,
                                         double floor_m, double floor_rad);

  // ū: the increment with the systematic error removed.
  Pose2 corrected(const Pose2& u) const;
  // Q = Cov(p_u) around corrected(u): diagonal, positive where a floor is positive.
  Eigen::Matrix3d covariance(const Pose2& u) const;

  // θ = (k_t − 1, k_r − 1, b).
  Eigen::Vector3d systematic_parameters() const;
  // A = ∂(ū(θ) ⊖ ū(θ̂))/∂θ at this model's θ̂ (ū = corrected(u)): how the
  // corrected increment, seen from its own end, moves with θ.
  Eigen::Matrix3d systematic_jacobian(const Pose2& u) const;
};

struct OdometryLearningConfig {
  // Learn the model online (on by default); off: the prior is used as configured.
  bool enabled = true;
  // The prior counts as this many increments (the first ~10 m of driving at 0.5 m per scan).
  double prior_increments = 20.0;
  // Each sweep re-weighs the last this many matched increments (a bound on a
  // scan's work: a sweep is O(memory_increments)). The noise model is estimated
  // from them; the systematic part (scales, heading bias), a constant of the
  // robot, keeps every older increment too, with the terms it had when it
  // left the memory.
  std::size_t memory_increments = 300;
  // EM sweeps over them after each new match.
  std::size_t sweeps_per_increment = 1;
  // Degrees of freedom of the Student-t weights (smaller: more robust to glitches).
  double student_dof = 4.0;
  // Prior standard deviations of the systematic part: scale errors (1) and heading bias (rad/m).
  double scale_prior_std = 0.1;
  double heading_bias_prior_std_rad_per_m = 0.05;
  // The learned scales stay within 1 ± max_scale_error.
  double max_scale_error = 0.3;
  // The learned heading bias stays within ± this (rad/m). Physics: unequal
  // wheel diameters make a differential drive believe it curves when it drives
  // straight, b = (E_d − 1) / wheelbase; uncalibrated tyres keep E_d within
  // 1.01 (Borenstein & Feng 1996 report 1.002–1.005), and an indoor mapping
  // robot's wheelbase is at least 0.3 m: |b| <= 0.01 / 0.3 = 0.033 rad/m (1.9°/m).
  // A larger learned value is the matcher's error, not the robot's.
  double max_heading_bias_rad_per_m = 0.035;

  // Throws std::invalid_argument naming the first invalid field and its value.
  void validate() const;
};

// What the learner has seen, for status messages and reports.
struct OdometryLearningStats {
  std::size_t increments = 0;     // scan-matched increments used
  std::size_t downweighted = 0;   // of those, with a robust weight below 1/2 when they came (glitches)
  double last_weight = 1.0;       // the robust weight of the last one
  // The systematic parameters held at their physical bounds after the last
  // sweep ("translation_scale", "rotation_scale", "heading_bias_rad_per_m"):
  // the matches disagree with the odometry beyond what wheels do. A laser
  // read wrongly (its no-return readings taken for returns) or a matcher that
  // misjudges its scenes does that; a robot's wheels do not.
  std::vector<std::string> at_bounds;
};

// "" when no learned parameter is at its bound; otherwise one line for people
// naming them, their values and what to check.
std::string describe_bounds(const OdometryErrorModel& model, const OdometryLearningStats& stats);

class OdometryModelLearner {
 public:
  // Throws std::invalid_argument for an invalid config or a prior with a
  // non-finite or negative value.
  OdometryModelLearner(const OdometryErrorModel& prior, const OdometryLearningConfig& config);

  // The current model: the prior until the first observe().
  const OdometryErrorModel& model() const { return model_; }
  const OdometryLearningStats& stats() const { return stats_; }

  // One scan-matched increment: û the raw odometry increment, x the match
  // refined from the prior (model().corrected(û), model().covariance(û)) — the
  // model as it was before this call — and Λ the laser's information about x
  // (symmetric positive semidefinite, of the perturbation x_true = x ⊕ p).
  // Returns the sample's robust weight in (0, 1]. Non-finite input is ignored
  // (returns 0, model unchanged).
  double observe(const Pose2& u, const Pose2& x_match, const Eigen::Matrix3d& laser_information);

 private:
  // One scan-matched increment, kept in prior-independent form.
  struct Sample {
    Eigen::Vector2d translation_regressors;  // [1, d²]
    Eigen::Vector4d heading_regressors;      // [1, d², φ², |φ| d]
    Eigen::Vector3d prior_variance;          // diagonal of the prior's Q
    Eigen::Matrix3d A;                       // systematic_jacobian when it was matched
    Eigen::Vector3d theta;                   // systematic part θ̂ when it was matched
    Eigen::Vector3d g;                       // Λ z, z the laser-only increment relative to ū(θ̂)
    Eigen::Matrix3d Lambda;                  // laser information
    Eigen::Matrix3d Lambda_pinv;
  };
  // What one sample says under the current model (the E-step): its terms of
  // the systematic fit's normal equations, N θ = r, and its expected squared
  // noise per axis for the noise regressions.
  struct Expectation {
    Eigen::Matrix3d normal;           // ρ Aᵀ W A
    Eigen::Vector3d vector;           // ρ Aᵀ (W z + W A θ̂)
    Eigen::Vector3d expected_noise;   // ρ-corrected E[p²] per axis
    Eigen::Vector3d q_inv;            // 1 / Q's diagonal under the current model
  };
  Expectation expectation(const Sample& s) const;
  // One EM sweep over the samples from the current model; returns the new model.
  OdometryErrorModel sweep() const;

  OdometryErrorModel prior_;
  OdometryLearningConfig config_;
  OdometryErrorModel model_;
  OdometryLearningStats stats_;
  // E[ρ χ²]/3 for Gaussian noise (χ² of 3 dof): the Student-t weights shrink the
  // expected squared noise of an inlier by this factor, which the M-step undoes.
  double gaussian_weight_factor_ = 1.0;
  std::deque<Sample> samples_;  // the last memory_increments, oldest first
  // The systematic part is a constant of the robot: the increments that left
  // the memory stay in its normal equations with the terms they had then.
  Eigen::Matrix3d retired_normal_ = Eigen::Matrix3d::Zero();
  Eigen::Vector3d retired_vector_ = Eigen::Vector3d::Zero();
};

// One line for people: "translation ×0.995, rotation ×0.951, heading bias
// -0.0014 rad/m; σ x 0.010 m + 0.05 m/m, y ..., φ 0.50° + 1.2°/m + 5.0 %/rad".
std::string describe(const OdometryErrorModel& model);

// min ½ cᵀ M c − bᵀ c subject to c >= 0, for M symmetric positive
// semidefinite of size <= 4, by trying every active set (exposed for tests).
Eigen::VectorXd non_negative_least_squares(const Eigen::MatrixXd& M, const Eigen::VectorXd& b);

}  // namespace lmf
