// The range-proportional part of the laser's point noise (ScanMatcherConfig::
// range_noise_per_m) measured on the log itself (docs/design.md §10, "The
// point noise grows with the range"). A laser states its accuracy as a
// constant or a share of the range, and a log rarely says which laser wrote
// it; the registrations' residuals do. Each registration gives its own
// evidence of range_noise_per_m² (range_noise_evidence: how much wider the
// farthest third of its residuals spreads than the nearest third, per unit of
// r²); the estimate is the square root of the median of the last kWindow of
// them, never below 0, once kMinMatches are in.
//
// Each registration's value under-reads a laser whose noise is a large share
// of the range: residuals beyond the refinement's last gate (0.25 m) are not
// pairings, so the far third's spread is cut (the simulator at 0.5 % / 1 % of
// the range measures 0.0023 / 0.0031). It also includes the reference points'
// own noise and their normals' error at range: it is the spread the
// covariance needs, not the laser's data sheet.
//
// Pure and deterministic; not thread-safe.
#pragma once

#include <cstddef>
#include <deque>
#include <optional>
#include <string>

#include <vector>

#include <Eigen/Core>

#include "lmf/geometry/pose2.hpp"
#include "lmf/scan/scan_matcher.hpp"

namespace lmf {

// One registration's evidence of range_noise_per_m²: the points B placed with
// x against the reference A, paired within last_gate_m, the nearest and the
// farthest third by range (the middle third keeps the two apart),
// (σ_far² − σ_near²) / (mean r²_far − mean r²_near), each σ the third's
// MAD-based std (robust to wrong pairings). Signed (noise alone makes it
// negative half the time where the range adds nothing); std::nullopt where
// fewer than min_correspondences points pair, or the far third is not at
// least twice as far as the near one (the range-proportional part then at
// least quadruples).
std::optional<double> range_noise_evidence(const ReferenceScan& A, const std::vector<Eigen::Vector2d>& B,
                                           const Pose2& x, const ScanMatcherConfig& config);

class RangeNoiseEstimate {
 public:
  // About 50 m of travel at the datasets' half-metre spacing: the laser, not
  // the place, is what is measured.
  static constexpr std::size_t kWindow = 100;
  // A fifth of the window: the median of 20 values is off by at most its
  // 40th-60th percentile band.
  static constexpr std::size_t kMinMatches = 20;

  // One registration's range_noise_evidence (std::nullopt and non-finite values are not counted).
  void add(const std::optional<double>& slope2);
  // range_noise_per_m (m per m); std::nullopt before kMinMatches matches gave evidence.
  std::optional<double> range_noise_per_m() const;
  std::size_t matches() const { return matches_; }  // that gave evidence, in all

 private:
  std::deque<double> slopes2_;
  std::size_t matches_ = 0;
};

// "0.030 m (+) 0.0040 x range (measured over 770 matches)", or "(configured)"
// where measured_over_matches is 0: the point noise a summary prints (the two
// parts add in quadrature).
std::string describe_point_noise(double point_sigma_m, double range_noise_per_m, std::size_t measured_over_matches);

}  // namespace lmf
