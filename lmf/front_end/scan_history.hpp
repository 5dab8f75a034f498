// The recent local history the scan matcher matches against (docs/design.md §10): the
// last few scans, each with its pose relative to the newest one, x_NK. Each
// added scan N' comes with its increment x_NN' from the previous newest N (the
// match, or the odometry), and every stored pose is re-expressed exactly,
// x_N'K = ⊖x_NN' ⊕ x_NK, so the history is relative to the robot itself: it
// does not depend on any map frame and survives LocalMap::reset().
//
// Not thread-safe; synchronous.
#pragma once

#include <cstddef>
#include <deque>

#include "lmf/geometry/pose2.hpp"
#include "lmf/scan/laser_scan.hpp"
#include "lmf/scan/scan_matcher.hpp"

namespace lmf {

class ScanHistory {
 public:
  struct Keyframe {
    Pose2 x_NK;             // pose of this scan K in the newest scan N's frame
    OrientedPoints points;  // in K's own frame
  };

  // Throws std::invalid_argument for an invalid config.
  explicit ScanHistory(const ScanMatcherConfig& config = {});

  // Adds `scan` as the new newest N', seen at x_NN' from the current newest N.
  // When `connected` is false (the increment is only the odometry's after a
  // failed match, or unknown) the older scans are dropped: their poses relative
  // to N' would carry the odometry's error into the reference. Then the older
  // scans are thinned (ScanMatcherConfig::history_scans, keyframe_*), and the
  // reference for the next match is rebuilt.
  void add(const LaserScan& scan, const Pose2& x_NN, bool connected);
  void add(OrientedPoints points, const Pose2& x_NN, bool connected);
  void clear();

  bool empty() const { return keyframes_.empty(); }
  std::size_t size() const { return keyframes_.size(); }
  // Newest first.
  const std::deque<Keyframe>& keyframes() const { return keyframes_; }
  // The union of the keyframes' points in the newest scan's frame, prepared for
  // match_scans (empty before the first scan).
  const ReferenceScan& reference() const { return reference_; }

 private:
  ScanMatcherConfig config_;
  std::deque<Keyframe> keyframes_;
  ReferenceScan reference_;
};

}  // namespace lmf
