#include "lmf/front_end/escalating_registration.hpp"

#include <algorithm>
#include <numbers>
#include <vector>

namespace lmf {
namespace {

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
  out.search_escalated = true;
  std::optional<ScanMatch> wider = match_scans(A, B, u_hat, Q, escalated_search(config));
  // Elsewhere: beyond χ²(3) in the wider match's own covariance.
  if (!wider || (out.match && !differs_beyond(*wider, out.match->x_AB, config.prior_alpha))) return out;
  std::vector<Pose2> poses{wider->x_AB};
  if (out.match) poses.push_back(out.match->x_AB);
  const std::vector<double> shares = explained_shares(A, B.all, poses, config);
  if (shares[0] < kExplainedShare || (out.match && shares[0] <= shares[1])) return out;
  out.match = std::move(wider);
  out.match_from_escalation = true;
  return out;
}

}  // namespace lmf
