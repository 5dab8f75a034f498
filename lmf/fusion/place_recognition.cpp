#include "lmf/fusion/place_recognition.hpp"

#include <algorithm>
#include <cmath>
#include <numbers>
#include <optional>
#include <stdexcept>
#include <string>

#include <Eigen/Eigenvalues>
#include <Eigen/Geometry>

#include "lmf/fusion/wall_directions.hpp"
#include "lmf/scan/correlative_search.hpp"

namespace lmf::fusion {

void PlaceRecognitionConfig::validate() const {
  const auto require = [](bool ok, const char* what) {
    if (!ok) throw std::invalid_argument(std::string("PlaceRecognitionConfig: ") + what);
  };
  require(std::isfinite(resolution_m) && resolution_m >= 0.01, "resolution_m must be finite and >= 0.01");
  require(std::isfinite(min_score) && min_score > 0.0 && min_score < 1.0, "min_score must be in (0, 1)");
  require(max_candidates >= 1 && max_candidates <= 64, "max_candidates must be in [1, 64]");
}

const char* to_string(PlaceOutcome outcome) {
  switch (outcome) {
    case PlaceOutcome::kPlaced: return "placed";
    case PlaceOutcome::kNotFound: return "not_found";
    case PlaceOutcome::kAmbiguous: return "ambiguous";
    case PlaceOutcome::kDegenerate: return "degenerate";
  }
  return "unknown";
}

namespace {

// Bounds on the global search's work for any input: at most kMaxLocalPoints
// sampled local points (the spacing widens beyond resolution_m past 800 m of
// walls at 0.4 m) and at most kMaxRotations headings (the step coarsens for a
// local map reaching beyond kMaxRotations r / 2π: 260 m at 0.4 m).
constexpr double kMaxLocalPoints = 2048;
constexpr double kMaxRotations = 4096;

// A point placed half a cell and half an angular step off its true pose lies
// up to one cell (the field's σ) from its wall, where its likelihood is
// exp(−1/2) of the peak's: the search grid's score of a place may be that much
// below its refined score. The global search keeps what may still refine to
// min_score. Its contenders are the peaks within ambiguity_ratio of the best's
// grid score: a rival that loses more to the grid than the best does can be
// missed (the looser ratio kGridLoss · ambiguity_ratio made the search about
// twice as slow, docs/results.md).
const double kGridLoss = std::exp(-0.5);

Eigen::Vector3d offset(const Pose2& a, const Pose2& b) {
  const Pose2 d = between(a, b);
  return {d.x, d.y, wrap_angle(d.phi)};
}

}  // namespace

PlaceRecognition recognise_place(const std::vector<RegistrationSegment>& local,
                                 const std::vector<RegistrationSegment>& global,
                                 const FrameRegistrationConfig& registration, const PlaceRecognitionConfig& config) {
  PlaceRecognition out;
  if (local.empty() || global.empty()) return out;
  const double r = config.resolution_m;
  double local_length = 0.0;
  for (const RegistrationSegment& s : local) local_length += s.length_m;
  const std::vector<SampledPoint> local_points = sample_segments(local, std::max(r, local_length / kMaxLocalPoints));
  const Eigen::Matrix3d information = mean_point_information(local_points);
  const Eigen::SelfAdjointEigenSolver<Eigen::Matrix2d> translation(information.topLeftCorner<2, 2>());
  if (translation.eigenvalues()(0) < registration.min_constraint) {
    out.outcome = PlaceOutcome::kDegenerate;
    return out;
  }
  std::vector<Eigen::Vector2d> points;
  points.reserve(local_points.size());
  double farthest = r;
  for (const SampledPoint& s : local_points) {
    points.push_back(s.p);
    farthest = std::max(farthest, s.p.norm());
  }

  // 1. The global search: the whole map's field, every heading, every
  // translation that puts a local point over it.
  std::vector<Eigen::Vector2d> reference;
  Eigen::AlignedBox2d region;
  for (const SampledPoint& s : sample_segments(global, r)) {
    reference.push_back(s.p);
    region.extend(s.p);
  }
  region.min().array() -= 2.0 * r;
  region.max().array() += 2.0 * r;
  const Eigen::Vector2d centre = region.center();
  CorrelativeWindow window;
  window.linear_m = 0.5 * region.sizes().x() + farthest;
  window.linear_y_m = 0.5 * region.sizes().y() + farthest;
  window.angular_step_rad = std::max(r / farthest, 2.0 * std::numbers::pi / kMaxRotations);
  window.angular_rad = std::numbers::pi - 0.5 * window.angular_step_rad;
  // Only headings at which the local walls parallel enough of the map's to
  // score what may refine to min_score (wall_directions.hpp).
  const WallDirections global_directions(global);
  const double step = window.angular_step_rad;
  window.heading_searched = [&](double heading) {
    return parallel_share(local, global_directions, heading, step, r) >= kGridLoss * config.min_score;
  };
  // Roots of the branch and bound tile the window when one top-level block
  // cannot span it (LikelihoodField::kMaxLevels).
  const int levels = std::min(LikelihoodField::levels_for(std::max(window.linear_m, *window.linear_y_m), r),
                              LikelihoodField::kMaxLevels);
  const LikelihoodField field(reference, region, r, r, levels);
  const std::optional<CorrelativeResult> search =
      correlative_search(field, points, Pose2(centre.x(), centre.y(), 0.0), window, kGridLoss * config.min_score,
                         registration.ambiguity_ratio);
  if (!search) return out;

  // Distinct peaks: the points of one move more than two cells (RMS, across
  // their walls) from those of every better one.
  const double separation2 = 4.0 * r * r;
  const auto distinct = [&](const Pose2& a, const Pose2& b) {
    const Eigen::Vector3d d = offset(a, b);
    return d.dot(information * d) > separation2;
  };
  std::vector<Pose2> peaks = {search->best.x};
  for (const CorrelativeMatch& c : search->contenders) {
    if (std::all_of(peaks.begin(), peaks.end(), [&](const Pose2& p) { return distinct(p, c.x); })) {
      peaks.push_back(c.x);
    }
  }
  out.candidates = static_cast<int>(peaks.size());

  // 2. Each peak refined by the registration, within two of the search's cells and steps.
  FrameRegistrationConfig fine = registration;
  fine.window_m = 2.0 * r;
  fine.window_rad = 2.0 * window.angular_step_rad;
  // Refined candidates below min_score still count as rivals of the best.
  fine.min_score = registration.ambiguity_ratio * config.min_score;
  std::vector<FrameRegistration> refined;
  for (std::size_t i = 0; i < peaks.size() && static_cast<int>(i) < config.max_candidates; ++i) {
    if (std::optional<FrameRegistration> reg = register_frame(local, global, peaks[i], fine)) {
      refined.push_back(*reg);
    }
  }
  if (refined.empty()) return out;
  const auto best = std::max_element(refined.begin(), refined.end(),
                                     [](const FrameRegistration& a, const FrameRegistration& b) {
                                       return a.score < b.score;
                                     });
  out.x_WL = best->x_WL;
  out.score = best->score;
  out.resolution_m = fine.resolution_m;
  out.angular_step_rad = best->angular_step_rad;
  for (const FrameRegistration& other : refined) {
    if (distinct(best->x_WL, other.x_WL)) out.rival_score = std::max(out.rival_score, other.score);
  }

  // 3. Accepted only when it is the one place.
  if (out.score < config.min_score) {
    out.outcome = PlaceOutcome::kNotFound;
  } else if (best->ambiguous || out.rival_score >= registration.ambiguity_ratio * out.score) {
    out.outcome = PlaceOutcome::kAmbiguous;
  } else if (best->degenerate || best->unresolved) {
    out.outcome = PlaceOutcome::kDegenerate;
  } else {
    out.outcome = PlaceOutcome::kPlaced;
  }
  return out;
}

}  // namespace lmf::fusion
