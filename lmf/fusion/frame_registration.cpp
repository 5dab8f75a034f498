#include "lmf/fusion/frame_registration.hpp"

#include <algorithm>
#include <cmath>
#include <stdexcept>

#include <Eigen/Eigenvalues>
#include <Eigen/Geometry>

#include "lmf/scan/correlative_search.hpp"

namespace lmf::fusion {

void FrameRegistrationConfig::validate() const {
  const auto require = [](bool ok, const char* what) {
    if (!ok) throw std::invalid_argument(std::string("FrameRegistrationConfig: ") + what);
  };
  require(std::isfinite(window_m) && window_m >= 0.0, "window_m must be finite and >= 0");
  require(std::isfinite(window_rad) && window_rad >= 0.0, "window_rad must be finite and >= 0");
  require(std::isfinite(resolution_m) && resolution_m > 0.0, "resolution_m must be finite and > 0");
  require(LikelihoodField::levels_for(window_m, resolution_m) <= LikelihoodField::kMaxLevels,
          "window_m must be at most 63 resolution_m (the search's pyramid holds 2^7 cells per axis): "
          "narrow window_m or coarsen resolution_m");
  require(std::isfinite(min_score) && min_score > 0.0 && min_score < 1.0, "min_score must be in (0, 1)");
  require(std::isfinite(ambiguity_ratio) && ambiguity_ratio > 0.0 && ambiguity_ratio <= 1.0,
          "ambiguity_ratio must be in (0, 1]");
  require(std::isfinite(min_constraint) && min_constraint >= 0.0 && min_constraint <= 1.0,
          "min_constraint must be in [0, 1]");
  require(own_recent_maps >= 0, "own_recent_maps must be >= 0");
}

namespace {

// Bounds on the search's work, far above any real local map's needs (a
// hostile one, e.g. a wall 100 km from its frame, took 20 s under ASan): at
// most kMaxLocalPoints sampled points (the spacing widens beyond 2 r: 820 m of
// walls at the default 5 cm), and at most 2 kMaxHalfRotations + 1 headings
// (the step coarsens once the farthest point is beyond kMaxHalfRotations r /
// window_rad: 128 m at the defaults). The coarser step is reported
// (angular_step_rad), so the fusion widens the registration's covariance.
constexpr double kMaxLocalPoints = 8192;
constexpr double kMaxHalfRotations = 256;

double mean_likelihood(const LikelihoodField& field, const std::vector<Eigen::Vector2d>& points, const Pose2& x) {
  const Eigen::Matrix2d R = Eigen::Rotation2Dd(x.phi).toRotationMatrix();
  const Eigen::Vector2d t(x.x, x.y);
  double sum = 0.0;
  for (const Eigen::Vector2d& p : points) sum += field.likelihood(t + R * p);
  return points.empty() ? 0.0 : sum / static_cast<double>(points.size());
}

}  // namespace

std::vector<SampledPoint> sample_segments(const std::vector<RegistrationSegment>& segments, double spacing) {
  std::vector<SampledPoint> out;
  for (const RegistrationSegment& s : segments) {
    const Eigen::Vector2d c(s.location.x, s.location.y);
    const Eigen::Vector2d u(std::cos(s.location.phi), std::sin(s.location.phi));
    const int steps = std::max(1, static_cast<int>(std::ceil(s.length_m / spacing)));
    for (int i = 0; i <= steps; ++i) {
      const double t = -0.5 * s.length_m + s.length_m * i / steps;
      out.push_back({c + t * u, Eigen::Vector2d(-u.y(), u.x())});
    }
  }
  return out;
}

Eigen::Matrix3d mean_point_information(const std::vector<SampledPoint>& points) {
  Eigen::Matrix3d information = Eigen::Matrix3d::Zero();
  for (const SampledPoint& s : points) {
    const Eigen::Vector3d J(s.n.x(), s.n.y(), s.n.dot(Eigen::Vector2d(-s.p.y(), s.p.x())));
    information += J * J.transpose();
  }
  return points.empty() ? information : Eigen::Matrix3d(information / static_cast<double>(points.size()));
}

std::optional<FrameRegistration> register_frame(const std::vector<RegistrationSegment>& local,
                                                const std::vector<RegistrationSegment>& global,
                                                const Pose2& x_WL, const FrameRegistrationConfig& config) {
  const double r = config.resolution_m;
  double local_length = 0.0;
  for (const RegistrationSegment& s : local) local_length += s.length_m;
  const std::vector<SampledPoint> local_points = sample_segments(local, std::max(2.0 * r, local_length / kMaxLocalPoints));
  if (local_points.empty() || global.empty()) return std::nullopt;
  std::vector<Eigen::Vector2d> points;
  points.reserve(local_points.size());
  double farthest = 0.0;
  for (const SampledPoint& s : local_points) {
    points.push_back(s.p);
    farthest = std::max(farthest, s.p.norm());
  }
  const Eigen::Matrix3d information = mean_point_information(local_points);

  // The field covers where the local points can land within the window.
  const Eigen::Matrix2d R = Eigen::Rotation2Dd(x_WL.phi).toRotationMatrix();
  Eigen::AlignedBox2d reach;
  for (const Eigen::Vector2d& p : points) reach.extend(Eigen::Vector2d(x_WL.x, x_WL.y) + R * p);
  const double margin = config.window_m + farthest * std::sin(config.window_rad) + 4.0 * r;
  reach.min().array() -= margin;
  reach.max().array() += margin;
  std::vector<Eigen::Vector2d> reference;
  for (const SampledPoint& s : sample_segments(global, r)) {
    if (reach.contains(s.p)) reference.push_back(s.p);
  }
  if (reference.empty()) return std::nullopt;
  Eigen::AlignedBox2d region;
  for (const Eigen::Vector2d& p : reference) region.extend(p);
  region.min().array() -= 4.0 * r;
  region.max().array() += 4.0 * r;
  region = region.intersection(reach);

  const LikelihoodField field(reference, region, r, 2.0 * r, LikelihoodField::levels_for(config.window_m, r));
  CorrelativeWindow window;
  window.linear_m = config.window_m;
  window.angular_rad = config.window_rad;
  window.angular_step_rad = std::max(std::min(0.05, r / std::max(farthest, r)), config.window_rad / kMaxHalfRotations);
  const std::optional<CorrelativeResult> search =
      correlative_search(field, points, x_WL, window, config.min_score, config.ambiguity_ratio);
  if (!search) return std::nullopt;

  FrameRegistration out;
  out.x_WL = search->best.x;
  out.score = search->best.score;
  out.prior_score = mean_likelihood(field, points, x_WL);
  out.angular_step_rad = window.angular_step_rad;
  const Eigen::SelfAdjointEigenSolver<Eigen::Matrix2d> translation(information.topLeftCorner<2, 2>());
  out.degenerate = translation.eigenvalues()(0) < config.min_constraint;
  // Distinct: the points move more than two cells (RMS, across their walls).
  const double separation2 = 4.0 * r * r;
  const auto offset = [](const Pose2& a, const Pose2& b) {
    const Pose2 d = between(a, b);
    return Eigen::Vector3d(d.x, d.y, wrap_angle(d.phi));
  };
  const auto spread2 = [&](const Eigen::Vector3d& d) { return d.dot(information * d); };
  // The contenders distinct from the best; when they all lie along one
  // direction u (what is left of each after removing its u part is not
  // distinct), the walls fix the frame but for u: a corridor with a few doors.
  std::vector<Eigen::Vector3d> rivals;
  for (const CorrelativeMatch& other : search->contenders) {
    const Eigen::Vector3d d = offset(out.x_WL, other.x);
    if (spread2(d) > separation2) rivals.push_back(d);
  }
  const auto across = [&](const Eigen::Vector3d& d, const Eigen::Vector3d& u) {
    return Eigen::Vector3d(d - u * (u.dot(information * d) / u.dot(information * u)));
  };
  if (!rivals.empty()) {
    const Eigen::Vector3d u = *std::max_element(rivals.begin(), rivals.end(), [&](const auto& a, const auto& b) {
      return spread2(a) < spread2(b);
    });
    out.unresolved = u.normalized();
    for (const Eigen::Vector3d& d : rivals) {
      if (spread2(across(d, u)) > separation2) out.ambiguous = true;
    }
  }
  Eigen::Vector3d from_prior = offset(out.x_WL, x_WL);
  if (out.unresolved) from_prior = across(from_prior, *out.unresolved);
  if (out.prior_score >= config.ambiguity_ratio * out.score && spread2(from_prior) > separation2) out.ambiguous = true;
  if (out.ambiguous) out.unresolved.reset();
  return out;
}

}  // namespace lmf::fusion
