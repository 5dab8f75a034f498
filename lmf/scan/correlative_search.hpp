// Correlative scan matching over a window (Olson, "Real-time correlative scan
// matching", ICRA 2009; the branch and bound of Hess et al., "Real-time loop
// closure in 2D LIDAR SLAM", ICRA 2016, §V): the reference points are
// rasterised into a likelihood field, and every pose of a grid of poses around
// a centre is scored by the mean likelihood of the scan's points placed with
// it. The best one is found exactly (for that grid of poses) by branch and
// bound over translation, with precomputed max-pooled copies of the field as
// upper bounds. No derivative, no basin: it finds the right increment when the
// odometry is off by far more than a local method tolerates, and its result
// starts the local refinement (scan_matcher.hpp).
//
// Pure, thread-safe.
#pragma once

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <functional>
#include <optional>
#include <vector>

#include <Eigen/Core>
#include <Eigen/Geometry>

#include "lmf/geometry/pose2.hpp"

namespace lmf {

// The likelihood field of a set of points over a rectangular region: square
// cells of `resolution_m`, each holding exp(−d² / (2 σ²)) of the distance d
// from its centre to the nearest point (0 beyond 2σ), quantised to 0..255.
// Level l (0 <= l < levels) holds at cell c the maximum of level 0 over the
// 2^l x 2^l block of cells starting at c; the levels are defined from
// c = −(2^(levels−1) − 1) on, so every block that overlaps the region has a
// value. Outside: 0.
class LikelihoodField {
 public:
  static constexpr int kMaxLevels = 8;
  // The levels a search of ± window_m at resolution_m needs: enough that one
  // top-level block spans the window's 2 ⌊window_m / resolution_m⌋ + 1
  // translations per axis. A window of more than 63 cells needs more than
  // kMaxLevels: configurations check it when they are read.
  static int levels_for(double window_m, double resolution_m);

  // Throws std::invalid_argument for a non-positive resolution or sigma, levels outside [1, kMaxLevels].
  LikelihoodField(const std::vector<Eigen::Vector2d>& points, const Eigen::AlignedBox2d& region, double resolution_m,
                  double sigma_m, int levels);

  double resolution_m() const { return resolution_m_; }
  int levels() const { return static_cast<int>(levels_.size()); }
  // The cell holding p (may be outside the region; clamped far outside so the
  // integer conversion stays defined, those cells read 0).
  Eigen::Vector2i cell(const Eigen::Vector2d& p) const {
    constexpr double kFar = 1e6;
    const Eigen::Vector2d c = (p - origin_) / resolution_m_;
    return {static_cast<int>(std::floor(std::clamp(c.x(), -kFar, kFar))),
            static_cast<int>(std::floor(std::clamp(c.y(), -kFar, kFar)))};
  }
  // 0..255; 0 outside.
  int value(int level, int ix, int iy) const {
    const int x = ix + padding_;
    const int y = iy + padding_;
    if (x < 0 || y < 0 || x >= padded_width_ || y >= padded_height_) return 0;
    return levels_[static_cast<std::size_t>(level)][static_cast<std::size_t>(y) * padded_width_ + x];
  }
  // The likelihood at p, in [0, 1].
  double likelihood(const Eigen::Vector2d& p) const {
    const Eigen::Vector2i c = cell(p);
    return value(0, c.x(), c.y()) / 255.0;
  }

 private:
  Eigen::Vector2d origin_;  // lower corner of cell (0, 0)
  double resolution_m_;
  int padding_ = 0;
  int padded_width_ = 0;
  int padded_height_ = 0;
  std::vector<std::vector<std::uint8_t>> levels_;
};

// The grid of poses searched: x = (c.x + i r, c.y + j r, c.φ + k δ) for the
// centre c, |i r| <= linear_m, |j r| <= linear_y_m or linear_m (r the field's resolution),
// |k δ| <= angular_rad, δ = angular_step_rad.
struct CorrelativeWindow {
  double linear_m = 0.0;
  double angular_rad = 0.0;
  double angular_step_rad = 0.0;
  // When set, the half-extent in y (m), linear_m then being x's only: a
  // window shaped like the region searched (a long building).
  std::optional<double> linear_y_m;
  // When set, only the headings k δ (offsets from the centre's) for which it
  // is true are searched: a caller's necessary condition on the heading.
  std::function<bool(double)> heading_searched;
};

struct CorrelativeMatch {
  Pose2 x;             // pose of the scan in the field's frame
  double score = 0.0;  // mean likelihood of the points placed with x, in [0, 1]
};

struct CorrelativeResult {
  CorrelativeMatch best;
  // Every pose of the window other than the best scoring at least
  // contender_ratio times the best (the best's own neighbours among them): the
  // caller decides which are distinct peaks.
  std::vector<CorrelativeMatch> contenders;
};

// The pose of the window with the highest score, if that score exceeds
// min_score, and its contenders. `points` in the scan's own frame.
// Throws std::invalid_argument for a negative window, a non-positive angular
// step or a contender_ratio outside (0, 1].
std::optional<CorrelativeResult> correlative_search(const LikelihoodField& field,
                                                    const std::vector<Eigen::Vector2d>& points, const Pose2& centre,
                                                    const CorrelativeWindow& window, double min_score,
                                                    double contender_ratio = 1.0);

// Whether x, a pose of the window's grid around centre (the field's cell
// resolution_m), lies on the grid's outermost ring in some axis: a best pose
// there may be the flank of a peak that lies beyond the window. An axis the
// window does not search (half-width below one cell or step) has no edge.
bool on_window_edge(const Pose2& x, const Pose2& centre, const CorrelativeWindow& window, double resolution_m);

}  // namespace lmf
