#include "lmf/front_end/escalating_registration.hpp"

#include <algorithm>
#include <cmath>
#include <numbers>

#include <Eigen/Cholesky>

#include "lmf/spmap/ekf.hpp"

namespace lmf {
namespace {

// Whether b lies elsewhere than a: their difference beyond χ²(3) at alpha in b's covariance.
bool elsewhere(const ScanMatch& a, const ScanMatch& b, double alpha) {
  const Pose2 d = between(b.x_AB, a.x_AB);
  const Eigen::Vector3d delta(d.x, d.y, wrap_angle(d.phi));
  const Eigen::LDLT<Eigen::Matrix3d> ldlt(b.covariance);
  if (ldlt.info() != Eigen::Success) return false;
  const double d2 = delta.dot(ldlt.solve(delta));
  return std::isfinite(d2) && d2 > spmap::chi2_threshold(3, alpha);
}

// The share of B's points the pose x explains on the first search's field (its
// mean likelihood there): that search's score at one pose, a window of zero
// width; 0 below min_overlap.
double explained_share(const ReferenceScan& A, const std::vector<Eigen::Vector2d>& B, const Pose2& x,
                       const Eigen::Matrix3d& Q, const ScanMatcherConfig& config) {
  ScanMatcherConfig at_x = config;
  at_x.search_window_m = 0.0;
  at_x.search_window_rad = 0.0;
  const std::optional<ScanMatch> scored = match_scans(A, B, x, Q, at_x);
  return scored ? scored->search_score : 0.0;
}

// A search whose best pose explains less than half of the scan (its score, the
// points' mean likelihood) left more of it unexplained than explained.
constexpr double kExplainedShare = 0.5;

}  // namespace

ScanMatcherConfig escalated_search(const ScanMatcherConfig& config) {
  ScanMatcherConfig wider = config;
  wider.search_window_m = std::min(kEscalation * config.search_window_m, 5.0);
  wider.search_window_rad = std::min(kEscalation * config.search_window_rad, std::numbers::pi);
  wider.search_resolution_m = kEscalation * config.search_resolution_m;
  return wider;
}

Registration register_escalating(const ReferenceScan& A, const ScanPoints& B, const Pose2& u_hat,
                                 const Eigen::Matrix3d& Q, const ScanMatcherConfig& config) {
  Registration out;
  out.match = match_scans(A, B, u_hat, Q, config);
  if (out.match && !out.match->search_at_window_edge && out.match->search_score >= kExplainedShare) return out;
  out.escalated = true;
  std::optional<ScanMatch> wider = match_scans(A, B, u_hat, Q, escalated_search(config));
  if (!wider || (out.match && !elsewhere(*out.match, *wider, config.prior_alpha))) return out;
  // The wider search's score is on its coarse field, which flatters every
  // pose alike: both refined poses are scored on the first search's field.
  const double wider_share = explained_share(A, B.all, wider->x_AB, Q, config);
  if (wider_share < kExplainedShare || (out.match && wider_share <= explained_share(A, B.all, out.match->x_AB, Q, config))) {
    return out;
  }
  out.match = std::move(wider);
  out.escalated_match = true;
  return out;
}

}  // namespace lmf
