// The front end's registration stage (front_end.hpp, stage 2; issue 39 item 3,
// docs/design.md §10): the scan against the local submap, with a search that
// escalates when the motion did more than its window holds.
//
// The search window, centred on the motion prior, holds what the motion
// physically does between two scans at 3σ (ScanMatcherConfig::search_window_m,
// search_window_rad). Three signs say the motion may have done more, a glitch
// (a wheel over a cable, a bump, a hand on the robot) that may have carried
// the truth out of the window: no match; the search's best pose on the
// window's outermost ring; or a best pose that explains less than half of the
// scan (its score, the points' mean likelihood: more of the scan unexplained
// than explained, where a wrong pose near a glitched prior can still pass
// min_overlap). The search then runs once more over a window kEscalation
// times as wide in translation and heading, 9σ, at a cell kEscalation times
// as coarse, so it visits as many poses as the first (fewer where the window
// reaches its limits of 5 m and π). Both matches' poses are then scored on one
// field at the first search's cell (explained_shares; the coarse field
// flatters every pose alike). The wider match counts only where it explains
// at least half of the scan there, and replaces the first match when there
// was none, or when it lies elsewhere (beyond χ²(3) at prior_alpha in its own
// covariance, so a corridor's open direction, which the prior decides, does
// not count) and explains more of the scan. Otherwise the first match stands.
//
// Pure functions, thread-safe.
#pragma once

#include <optional>

#include <Eigen/Core>

#include "lmf/geometry/pose2.hpp"
#include "lmf/scan/scan_matcher.hpp"

namespace lmf {

struct Registration {
  std::optional<ScanMatch> match;
  bool search_escalated = false;       // the wider search ran ...
  bool match_from_escalation = false;  // ... and its match is the one returned
};

// The window's and the cell's growth of the escalated search: 3σ to 9σ.
inline constexpr double kEscalation = 3.0;

// The escalated search's configuration: window and cell kEscalation times as
// large, within what ScanMatcherConfig::validate accepts (at most 5 m and π).
ScanMatcherConfig escalated_search(const ScanMatcherConfig& config);

// match_scans (scan_matcher.hpp), escalating as above. The arguments are match_scans's.
Registration register_escalating(const ReferenceScan& A, const ScanPoints& B, const Pose2& u_hat,
                                 const Eigen::Matrix3d& Q, const ScanMatcherConfig& config);

}  // namespace lmf
