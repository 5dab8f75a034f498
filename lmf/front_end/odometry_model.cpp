#include "lmf/front_end/odometry_model.hpp"

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdio>
#include <limits>
#include <iterator>
#include <stdexcept>
#include <vector>

#include <Eigen/Eigenvalues>
#include <Eigen/LU>

#include "lmf/common/config_check.hpp"

namespace lmf {
namespace {

// The systematic parameters by name: each one's value, and its distance from
// where it has no effect (a scale's from 1, the bias's from 0).
struct NamedParameter {
  const char* name;
  double value;
  double offset;
};
std::array<NamedParameter, 3> named_systematic_parameters(const OdometryErrorModel& m) {
  return {{{"translation_scale", m.translation_scale, std::abs(m.translation_scale - 1.0)},
           {"rotation_scale", m.rotation_scale, std::abs(m.rotation_scale - 1.0)},
           {"heading_bias_rad_per_m", m.heading_bias_rad_per_m, std::abs(m.heading_bias_rad_per_m)}}};
}

// The systematic parameters of `m` at the bounds `config` holds them within
// (a zero bound holds its parameter at 0: nothing is learned there to report).
std::vector<std::string> parameters_at_bounds(const OdometryErrorModel& m, const OdometryLearningConfig& config) {
  constexpr double kAt = 1.0 - 1e-9;
  const double bounds[] = {config.max_scale_error, config.max_scale_error, config.max_heading_bias_rad_per_m};
  std::vector<std::string> at;
  const std::array<NamedParameter, 3> parameters = named_systematic_parameters(m);
  for (std::size_t i = 0; i < parameters.size(); ++i) {
    if (bounds[i] > 0.0 && parameters[i].offset >= kAt * bounds[i]) at.emplace_back(parameters[i].name);
  }
  return at;
}

// The regressors of the three variances for an increment u (see the header).
struct Regressors {
  Eigen::Vector2d translation;  // [1, d²]
  Eigen::Vector4d heading;      // [1, d², φ², |φ| d]
};
Regressors regressors(const Pose2& u) {
  const double d = std::hypot(u.x, u.y);
  return {Eigen::Vector2d(1.0, d * d), Eigen::Vector4d(1.0, d * d, u.phi * u.phi, std::abs(u.phi) * d)};
}

Eigen::Vector2d x_coefficients(const OdometryErrorModel& m) {
  return {m.x_step_m * m.x_step_m, m.x_per_m * m.x_per_m};
}
Eigen::Vector2d y_coefficients(const OdometryErrorModel& m) {
  return {m.y_step_m * m.y_step_m, m.y_per_m * m.y_per_m};
}
Eigen::Vector4d phi_coefficients(const OdometryErrorModel& m) {
  return {m.phi_step_rad * m.phi_step_rad, m.phi_per_m * m.phi_per_m, m.phi_per_rad * m.phi_per_rad,
          m.phi_turn_distance};
}

// Λ⁺ of a symmetric positive semidefinite 3 x 3 (eigenvalues below 1e-12 of the largest dropped).
Eigen::Matrix3d pseudo_inverse(const Eigen::Matrix3d& A) {
  const Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> es(A);
  const Eigen::Vector3d& l = es.eigenvalues();
  const double cut = 1e-12 * std::max(l.cwiseAbs().maxCoeff(), std::numeric_limits<double>::min());
  Eigen::Vector3d inv = Eigen::Vector3d::Zero();
  for (int i = 0; i < 3; ++i) {
    if (l(i) > cut) inv(i) = 1.0 / l(i);
  }
  return es.eigenvectors() * inv.asDiagonal() * es.eigenvectors().transpose();
}

// E[(ν + 3) x / (ν + x)] / 3 for x ~ χ²(3), by Simpson's rule on [0, 80]
// (the density x^½ e^(−x/2) / (2^(3/2) Γ(3/2)) is negligible beyond).
double student_weight_factor(double nu) {
  constexpr int kIntervals = 4000;
  constexpr double kEnd = 80.0;
  const double h = kEnd / kIntervals;
  const double norm = 1.0 / (std::pow(2.0, 1.5) * std::tgamma(1.5));
  double sum = 0.0;
  for (int i = 0; i <= kIntervals; ++i) {
    const double x = i * h;
    const double f = norm * std::sqrt(x) * std::exp(-0.5 * x) * (nu + 3.0) * x / (nu + x);
    sum += f * (i == 0 || i == kIntervals ? 1.0 : (i % 2 == 1 ? 4.0 : 2.0));
  }
  return sum * h / 3.0 / 3.0;
}

}  // namespace

OdometryErrorModel OdometryErrorModel::proportional(double translation_ratio, double rotation_ratio,
                                                    double drift_rad_per_m, double floor_m, double floor_rad) {
  OdometryErrorModel m;
  m.x_step_m = floor_m;
  m.x_per_m = translation_ratio;
  m.y_step_m = floor_m;
  m.y_per_m = translation_ratio;
  m.phi_step_rad = floor_rad;
  m.phi_per_m = drift_rad_per_m;
  m.phi_per_rad = rotation_ratio;
  // (a|φ| + b d)² = a² φ² + b² d² + 2ab |φ| d.
  m.phi_turn_distance = 2.0 * rotation_ratio * drift_rad_per_m;
  return m;
}

Pose2 OdometryErrorModel::corrected(const Pose2& u) const {
  const double d = std::hypot(u.x, u.y);
  return {translation_scale * u.x, translation_scale * u.y,
          wrap_angle(rotation_scale * u.phi + heading_bias_rad_per_m * d)};
}

Eigen::Matrix3d OdometryErrorModel::covariance(const Pose2& u) const {
  const Regressors r = regressors(u);
  Eigen::Matrix3d Q = Eigen::Matrix3d::Zero();
  Q(0, 0) = r.translation.dot(x_coefficients(*this));
  Q(1, 1) = r.translation.dot(y_coefficients(*this));
  Q(2, 2) = r.heading.dot(phi_coefficients(*this));
  return Q;
}

Eigen::Vector3d OdometryErrorModel::systematic_parameters() const {
  return {translation_scale - 1.0, rotation_scale - 1.0, heading_bias_rad_per_m};
}

Eigen::Matrix3d OdometryErrorModel::systematic_jacobian(const Pose2& u) const {
  // ū(θ) = (k_t x, k_t y, k_r φ + b d): the translation's change seen from ū's
  // end pose (rotated by −φ̄), the heading's change directly.
  const double phi_bar = corrected(u).phi;
  const double c = std::cos(phi_bar);
  const double s = std::sin(phi_bar);
  Eigen::Matrix3d A = Eigen::Matrix3d::Zero();
  A(0, 0) = c * u.x + s * u.y;
  A(1, 0) = -s * u.x + c * u.y;
  A(2, 1) = u.phi;
  A(2, 2) = std::hypot(u.x, u.y);
  return A;
}

std::string describe_bounds(const OdometryErrorModel& m, const OdometryLearningStats& stats) {
  if (stats.at_bounds.empty()) return "";
  std::string names;
  for (const NamedParameter& p : named_systematic_parameters(m)) {
    if (std::find(stats.at_bounds.begin(), stats.at_bounds.end(), p.name) == stats.at_bounds.end()) continue;
    char value[64];
    std::snprintf(value, sizeof value, " (%.4f)", p.value);
    names += (names.empty() ? "" : ", ") + std::string(p.name) + value;
  }
  return "learned odometry at its physical bound: " + names +
         "; the scan matches disagree with the odometry beyond what wheels do (check the laser's range and "
         "no-return reading, and the scan-matching configuration)";
}

std::string describe(const OdometryErrorModel& m) {
  constexpr double kDeg = 180.0 / 3.14159265358979323846;
  char line[320];
  std::snprintf(line, sizeof line,
                "translation x%.4f, rotation x%.4f, heading bias %+.4f rad/m; sigma x %.3f m + %.3f m/m, "
                "y %.3f m + %.3f m/m, phi %.2f deg + %.2f deg/m + %.1f %%/rad (+ %.4f rad |phi| d cross term)",
                m.translation_scale, m.rotation_scale, m.heading_bias_rad_per_m, m.x_step_m, m.x_per_m, m.y_step_m,
                m.y_per_m, m.phi_step_rad * kDeg, m.phi_per_m * kDeg, 100.0 * m.phi_per_rad, m.phi_turn_distance);
  return line;
}

void OdometryLearningConfig::validate() const {
  const ConfigCheck require("OdometryLearningConfig");
  require(std::isfinite(prior_increments) && prior_increments > 0.0, "prior_increments", prior_increments,
          "finite and > 0");
  require(memory_increments >= 1, "memory_increments", memory_increments, ">= 1");
  require(sweeps_per_increment >= 1, "sweeps_per_increment", sweeps_per_increment, ">= 1");
  require(std::isfinite(student_dof) && student_dof > 0.0, "student_dof", student_dof, "finite and > 0");
  require(std::isfinite(scale_prior_std) && scale_prior_std > 0.0, "scale_prior_std", scale_prior_std,
          "finite and > 0");
  require(std::isfinite(heading_bias_prior_std_rad_per_m) && heading_bias_prior_std_rad_per_m > 0.0,
          "heading_bias_prior_std_rad_per_m", heading_bias_prior_std_rad_per_m, "finite and > 0");
  require(std::isfinite(max_scale_error) && max_scale_error > 0.0 && max_scale_error < 1.0, "max_scale_error",
          max_scale_error, "in (0, 1)");
  require(std::isfinite(max_heading_bias_rad_per_m) && max_heading_bias_rad_per_m >= 0.0,
          "max_heading_bias_rad_per_m", max_heading_bias_rad_per_m, "finite and >= 0");
}

Eigen::VectorXd non_negative_least_squares(const Eigen::MatrixXd& M, const Eigen::VectorXd& b) {
  const Eigen::Index n = b.size();
  if (M.rows() != n || M.cols() != n || n > 4) {
    throw std::invalid_argument("non_negative_least_squares: M must be n x n and b of size n <= 4");
  }
  Eigen::VectorXd best = Eigen::VectorXd::Zero(n);
  double best_cost = 0.0;  // the cost of c = 0
  for (unsigned mask = 1; mask < (1u << n); ++mask) {
    std::vector<Eigen::Index> free;
    for (Eigen::Index i = 0; i < n; ++i) {
      if (mask & (1u << i)) free.push_back(i);
    }
    const auto k = static_cast<Eigen::Index>(free.size());
    Eigen::MatrixXd Mf(k, k);
    Eigen::VectorXd bf(k);
    for (Eigen::Index i = 0; i < k; ++i) {
      bf(i) = b(free[static_cast<std::size_t>(i)]);
      for (Eigen::Index j = 0; j < k; ++j) Mf(i, j) = M(free[static_cast<std::size_t>(i)], free[static_cast<std::size_t>(j)]);
    }
    const Eigen::FullPivLU<Eigen::MatrixXd> lu(Mf);
    if (!lu.isInvertible()) continue;
    const Eigen::VectorXd cf = lu.solve(bf);
    if (!cf.allFinite() || (cf.array() < 0.0).any()) continue;
    Eigen::VectorXd c = Eigen::VectorXd::Zero(n);
    for (Eigen::Index i = 0; i < k; ++i) c(free[static_cast<std::size_t>(i)]) = cf(i);
    const double cost = 0.5 * c.dot(M * c) - b.dot(c);
    if (cost < best_cost) {
      best_cost = cost;
      best = c;
    }
  }
  return best;
}

OdometryModelLearner::OdometryModelLearner(const OdometryErrorModel& prior, const OdometryLearningConfig& config)
    : prior_(prior), config_(config), model_(prior) {
  config_.validate();
  const double values[] = {prior.translation_scale, prior.rotation_scale, prior.heading_bias_rad_per_m,
                           prior.x_step_m, prior.x_per_m, prior.y_step_m, prior.y_per_m, prior.phi_step_rad,
                           prior.phi_per_m, prior.phi_per_rad, prior.phi_turn_distance};
  for (std::size_t i = 0; i < std::size(values); ++i) {
    if (!std::isfinite(values[i]) || (i >= 3 && values[i] < 0.0)) {
      throw std::invalid_argument("OdometryModelLearner: the prior model must be finite with non-negative noise terms");
    }
  }
  gaussian_weight_factor_ = student_weight_factor(config_.student_dof);
}

double OdometryModelLearner::observe(const Pose2& u, const Pose2& x_match, const Eigen::Matrix3d& laser_information) {
  if (!finite(u) || !finite(x_match) || !laser_information.allFinite()) return 0.0;
  const Eigen::Matrix3d Q = model_.covariance(u);
  if (!(Q.diagonal().array() > 0.0).all()) return 0.0;  // no floor and no motion: nothing to learn from
  const Eigen::Matrix3d Lambda = 0.5 * (laser_information + laser_information.transpose());
  const Pose2 e_pose = between(model_.corrected(u), x_match);
  const Eigen::Vector3d e(e_pose.x, e_pose.y, wrap_angle(e_pose.phi));
  const Eigen::Matrix3d Q_inv = Q.diagonal().cwiseInverse().asDiagonal();

  Sample sample;
  const Regressors r = regressors(u);
  sample.translation_regressors = r.translation;
  sample.heading_regressors = r.heading;
  sample.prior_variance = prior_.covariance(u).diagonal();
  sample.A = model_.systematic_jacobian(u);
  sample.theta = model_.systematic_parameters();
  sample.g = (Lambda + Q_inv) * e;
  sample.Lambda = Lambda;
  sample.Lambda_pinv = pseudo_inverse(Lambda);
  // The weight this increment gets from the model it was matched with (stats).
  const Eigen::Vector3d v = Q_inv * e;
  const double nis = e.dot(v) + v.dot(sample.Lambda_pinv * v);
  const double rho = std::min(1.0, (config_.student_dof + 3.0) / (config_.student_dof + nis));

  samples_.push_back(sample);
  while (samples_.size() > config_.memory_increments) {
    const Expectation retired = expectation(samples_.front());
    retired_normal_ += retired.normal;
    retired_vector_ += retired.vector;
    samples_.pop_front();
  }
  for (std::size_t k = 0; k < config_.sweeps_per_increment; ++k) model_ = sweep();

  ++stats_.increments;
  if (rho < 0.5) ++stats_.downweighted;
  stats_.last_weight = rho;
  stats_.at_bounds = parameters_at_bounds(model_, config_);
  return rho;
}

OdometryModelLearner::Expectation OdometryModelLearner::expectation(const Sample& s) const {
  const Eigen::Vector3d theta_hat = model_.systematic_parameters();
  const Eigen::Vector3d q(s.translation_regressors.dot(x_coefficients(model_)),
                          s.translation_regressors.dot(y_coefficients(model_)),
                          s.heading_regressors.dot(phi_coefficients(model_)));
  Expectation out;
  out.q_inv = q.cwiseInverse();
  const Eigen::Matrix3d& A = s.A;
  // E-step under the current model: the laser term moved to the current ū.
  const Eigen::Vector3d g = s.g - s.Lambda * (A * (theta_hat - s.theta));
  Eigen::Matrix3d information = s.Lambda;
  information.diagonal() += out.q_inv;
  const Eigen::Matrix3d posterior = information.inverse();
  const Eigen::Vector3d e = posterior * g;
  const Eigen::Vector3d v = out.q_inv.cwiseProduct(e);  // = W z
  const double nu = config_.student_dof;
  const double nis = e.dot(v) + v.dot(s.Lambda_pinv * v);
  const double rho = (nu + 3.0) / (nu + nis);
  const Eigen::Matrix3d W = s.Lambda - s.Lambda * posterior * s.Lambda;  // (Λ⁻¹ + Q)⁻¹ by Woodbury
  // Systematic part: z ≈ A (θ − θ̂) with information ρ W, i.e. W z = v.
  const Eigen::Matrix3d WA = W * A;
  out.normal = rho * A.transpose() * WA;
  out.vector = rho * A.transpose() * (v + WA * theta_hat);
  // Random part: the expected squared noise beside the prior's variance.
  out.expected_noise = (rho / gaussian_weight_factor_) * e.cwiseAbs2() + posterior.diagonal();
  return out;
}

OdometryErrorModel OdometryModelLearner::sweep() const {
  const double prior_weight = config_.prior_increments / static_cast<double>(samples_.size());
  Eigen::Matrix3d sys_normal = retired_normal_;
  Eigen::Vector3d sys_vector = retired_vector_;
  Eigen::Matrix2d x_normal = Eigen::Matrix2d::Zero();
  Eigen::Vector2d x_vector = Eigen::Vector2d::Zero();
  Eigen::Matrix2d y_normal = Eigen::Matrix2d::Zero();
  Eigen::Vector2d y_vector = Eigen::Vector2d::Zero();
  Eigen::Matrix4d phi_normal = Eigen::Matrix4d::Zero();
  Eigen::Vector4d phi_vector = Eigen::Vector4d::Zero();
  for (const Sample& s : samples_) {
    const Expectation x = expectation(s);
    sys_normal += x.normal;
    sys_vector += x.vector;
    const Eigen::Vector3d& expected = x.expected_noise;
    const Eigen::Vector3d w = x.q_inv.cwiseAbs2();  // 1/σ⁴
    x_normal.noalias() += ((1.0 + prior_weight) * w(0)) * s.translation_regressors * s.translation_regressors.transpose();
    x_vector.noalias() += (w(0) * (expected(0) + prior_weight * s.prior_variance(0))) * s.translation_regressors;
    y_normal.noalias() += ((1.0 + prior_weight) * w(1)) * s.translation_regressors * s.translation_regressors.transpose();
    y_vector.noalias() += (w(1) * (expected(1) + prior_weight * s.prior_variance(1))) * s.translation_regressors;
    phi_normal.noalias() += ((1.0 + prior_weight) * w(2)) * s.heading_regressors * s.heading_regressors.transpose();
    phi_vector.noalias() += (w(2) * (expected(2) + prior_weight * s.prior_variance(2))) * s.heading_regressors;
  }
  const Eigen::Vector3d prior_information(1.0 / (config_.scale_prior_std * config_.scale_prior_std),
                                          1.0 / (config_.scale_prior_std * config_.scale_prior_std),
                                          1.0 / (config_.heading_bias_prior_std_rad_per_m *
                                                 config_.heading_bias_prior_std_rad_per_m));
  const Eigen::Matrix3d N = sys_normal + Eigen::Matrix3d(prior_information.asDiagonal());
  const Eigen::Vector3d theta = N.ldlt().solve(sys_vector + prior_information.cwiseProduct(prior_.systematic_parameters()));
  const Eigen::VectorXd cx = non_negative_least_squares(x_normal, x_vector);
  const Eigen::VectorXd cy = non_negative_least_squares(y_normal, y_vector);
  const Eigen::VectorXd cphi = non_negative_least_squares(phi_normal, phi_vector);

  // The prior's per-step terms are floors: Q stays positive definite.
  OdometryErrorModel next;
  const double max_error = config_.max_scale_error;
  next.translation_scale = 1.0 + std::clamp(theta(0), -max_error, max_error);
  next.rotation_scale = 1.0 + std::clamp(theta(1), -max_error, max_error);
  const double max_bias = config_.max_heading_bias_rad_per_m;
  next.heading_bias_rad_per_m =
      theta.allFinite() ? std::clamp(theta(2), -max_bias, max_bias) : model_.heading_bias_rad_per_m;
  next.x_step_m = std::max(prior_.x_step_m, std::sqrt(cx(0)));
  next.x_per_m = std::sqrt(cx(1));
  next.y_step_m = std::max(prior_.y_step_m, std::sqrt(cy(0)));
  next.y_per_m = std::sqrt(cy(1));
  next.phi_step_rad = std::max(prior_.phi_step_rad, std::sqrt(cphi(0)));
  next.phi_per_m = std::sqrt(cphi(1));
  next.phi_per_rad = std::sqrt(cphi(2));
  next.phi_turn_distance = cphi(3);
  return next;
}

}  // namespace lmf
