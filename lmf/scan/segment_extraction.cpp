#include "lmf/scan/segment_extraction.hpp"

#include <algorithm>
#include <cmath>
#include <optional>
#include <stdexcept>
#include <string>

#include "lmf/common/config_check.hpp"

namespace lmf {
namespace {

// A valid scan point and the beam it came from.
struct ScanPoint {
  Eigen::Vector2d p;  // sensor frame (m)
  std::size_t beam = 0;
};

// A run of points [begin, end) into the point array.
struct Range {
  std::size_t begin = 0;
  std::size_t end = 0;
  std::size_t size() const { return end - begin; }
};

// Total least squares line through points[r]: the line through the centroid along
// the principal axis of the scatter matrix (orthogonal regression).
struct LineFit {
  Eigen::Vector2d centroid = Eigen::Vector2d::Zero();
  Eigen::Vector2d direction = Eigen::Vector2d::UnitX();  // unit; sensor on its left
  Eigen::Vector2d normal = Eigen::Vector2d::UnitY();     // unit; left of direction, towards the sensor
  double max_residual_m = 0.0;
  double rms_residual_m = 0.0;
};

LineFit fit_line(const std::vector<ScanPoint>& points, Range r) {
  LineFit fit;
  const double n = static_cast<double>(r.size());
  for (std::size_t i = r.begin; i < r.end; ++i) fit.centroid += points[i].p;
  fit.centroid /= n;
  double sxx = 0.0;
  double syy = 0.0;
  double sxy = 0.0;
  for (std::size_t i = r.begin; i < r.end; ++i) {
    const Eigen::Vector2d q = points[i].p - fit.centroid;
    sxx += q.x() * q.x();
    syy += q.y() * q.y();
    sxy += q.x() * q.y();
  }
  // Major axis of the 2x2 scatter matrix in closed form.
  const double theta = 0.5 * std::atan2(2.0 * sxy, sxx - syy);
  fit.direction = {std::cos(theta), std::sin(theta)};
  fit.normal = {-fit.direction.y(), fit.direction.x()};
  // docs/design.md §3: a fixed side. The sensor (origin) must lie on the left (+normal).
  // A line through the sensor cannot be seen; fall back to the beam order then.
  const double sensor_side = -fit.normal.dot(fit.centroid);
  const bool flip = std::abs(sensor_side) > 1e-9
                        ? sensor_side < 0.0
                        : fit.direction.dot(points[r.end - 1].p - points[r.begin].p) < 0.0;
  if (flip) {
    fit.direction = -fit.direction;
    fit.normal = -fit.normal;
  }
  double sum_sq = 0.0;
  for (std::size_t i = r.begin; i < r.end; ++i) {
    const double e = std::abs(fit.normal.dot(points[i].p - fit.centroid));
    fit.max_residual_m = std::max(fit.max_residual_m, e);
    sum_sq += e * e;
  }
  fit.rms_residual_m = std::sqrt(sum_sq / n);
  return fit;
}

double distance_to_line(const Eigen::Vector2d& p, const LineFit& fit) {
  return std::abs(fit.normal.dot(p - fit.centroid));
}

}  // namespace

double max_valid_range(const LaserScan& scan, const ExtractionConfig& config) {
  double upper_m = config.max_range_m;
  if (scan.max_range_m > 0.0) upper_m = std::min(upper_m, scan.max_range_m - config.no_return_margin_m);
  return upper_m;
}

namespace {

// Step 2: clusters of consecutive valid beams closer than max_point_gap_m.
std::vector<Range> make_clusters(const LaserScan& scan, const ExtractionConfig& config,
                                 std::vector<ScanPoint>& points) {
  const double upper_m = max_valid_range(scan, config);
  std::vector<Range> clusters;
  bool previous_valid = false;
  for (std::size_t i = 0; i < scan.ranges_m.size(); ++i) {
    const double r = scan.ranges_m[i];
    const bool valid = std::isfinite(r) && r >= config.min_range_m && r < upper_m;
    if (!valid) {
      previous_valid = false;
      continue;
    }
    const Eigen::Vector2d p = scan.beam_point(i);
    const bool joins = previous_valid && (p - points.back().p).norm() <= config.max_point_gap_m;
    if (!joins) clusters.push_back({points.size(), points.size()});
    points.push_back({p, i});
    clusters.back().end = points.size();
    previous_valid = true;
  }
  return clusters;
}

// Step 3: iterative end point fit. Pieces come out in beam order.
void split(const std::vector<ScanPoint>& points, Range cluster, double split_distance_m,
           std::vector<Range>& pieces) {
  std::vector<Range> stack{cluster};
  while (!stack.empty()) {
    const Range r = stack.back();
    stack.pop_back();
    if (r.size() < 3) {
      pieces.push_back(r);
      continue;
    }
    const Eigen::Vector2d a = points[r.begin].p;
    const Eigen::Vector2d b = points[r.end - 1].p;
    const Eigen::Vector2d chord = b - a;
    const double chord_length = chord.norm();
    std::size_t farthest = r.begin;
    double farthest_distance = -1.0;
    for (std::size_t i = r.begin + 1; i + 1 < r.end; ++i) {
      const Eigen::Vector2d q = points[i].p - a;
      const double d = chord_length > 1e-12
                           ? std::abs(chord.x() * q.y() - chord.y() * q.x()) / chord_length
                           : q.norm();
      if (d > farthest_distance) {
        farthest_distance = d;
        farthest = i;
      }
    }
    if (farthest_distance <= split_distance_m) {
      // The chord of two noisy end points can hide a point that is far from the
      // fitted line; every supporting point must lie near the line it supports.
      const LineFit fit = fit_line(points, r);
      if (fit.max_residual_m <= split_distance_m) {
        pieces.push_back(r);
        continue;
      }
      farthest = r.begin;
      farthest_distance = -1.0;
      for (std::size_t i = r.begin; i < r.end; ++i) {
        const double d = distance_to_line(points[i].p, fit);
        if (d > farthest_distance) {
          farthest_distance = d;
          farthest = i;
        }
      }
      if (farthest == r.begin || farthest + 1 == r.end) {
        // An outlying end point (a mixed reading at an edge): peel it off.
        // Pieces must come out in beam order (merge() joins neighbours).
        if (farthest == r.begin) {
          pieces.push_back({r.begin, r.begin + 1});
          stack.push_back({r.begin + 1, r.end});
        } else {
          stack.push_back({r.end - 1, r.end});
          stack.push_back({r.begin, r.end - 1});
        }
        continue;
      }
    }
    // The farthest point (a corner, usually) ends the first piece; the
    // boundary refinement below may hand it to the second one.
    // Push the second half first so the first half is processed (and emitted) first.
    stack.push_back({farthest + 1, r.end});
    stack.push_back({r.begin, farthest + 1});
  }
}

// Step 4: merge adjacent collinear pieces of one cluster, best pair first.
void merge(const std::vector<ScanPoint>& points, double merge_distance_m, std::vector<Range>& pieces) {
  while (pieces.size() >= 2) {
    std::size_t best = pieces.size();
    double best_residual = merge_distance_m;
    for (std::size_t k = 0; k + 1 < pieces.size(); ++k) {
      const Range joint{pieces[k].begin, pieces[k + 1].end};
      const double residual = fit_line(points, joint).max_residual_m;
      if (residual < best_residual) {
        best_residual = residual;
        best = k;
      }
    }
    if (best == pieces.size()) return;
    pieces[best].end = pieces[best + 1].end;
    pieces.erase(pieces.begin() + static_cast<std::ptrdiff_t>(best + 1));
  }
}

// Moves the point at a boundary between two adjacent pieces to the piece whose
// line it is closer to (the split point is often the corner, on both lines, or
// one beam off it), when both refitted pieces keep every point within max_distance_m.
void refine_boundaries(const std::vector<ScanPoint>& points, double max_distance_m, std::vector<Range>& pieces) {
  const auto fits = [&](Range r) { return r.size() < 3 || fit_line(points, r).max_residual_m <= max_distance_m; };
  for (std::size_t k = 0; k + 1 < pieces.size(); ++k) {
    Range& a = pieces[k];
    Range& b = pieces[k + 1];
    if (a.size() < 3 || b.size() < 3) continue;
    const LineFit fa = fit_line(points, {a.begin, a.end - 1});  // without the candidate points
    const LineFit fb = fit_line(points, {b.begin + 1, b.end});
    const Eigen::Vector2d& last_of_a = points[a.end - 1].p;
    const Eigen::Vector2d& first_of_b = points[b.begin].p;
    if (distance_to_line(last_of_a, fb) < distance_to_line(last_of_a, fa) &&
        fits({a.begin, a.end - 1}) && fits({b.begin - 1, b.end})) {
      --a.end;
      --b.begin;
    } else if (distance_to_line(first_of_b, fa) < distance_to_line(first_of_b, fb) &&
               fits({a.begin, a.end + 1}) && fits({b.begin + 1, b.end})) {
      ++a.end;
      ++b.begin;
    }
  }
}

// Step 5: the segment of one piece, or nothing when it fails the filters of step 6.
//
// Covariance of p_E = (lateral, angular) (docs/design.md §3, §4.2). Write each point in
// the fitted frame (origin at the centroid c, axis d, normal n): s_i = d·(p_i - c),
// e_i = n·(p_i - c). A small error of the line, offset a at the centroid and
// angle b, moves the residuals by e_i ≈ a + b s_i, and to first order the TLS fit
// is the ordinary least squares regression of e on s (Σ s_i = 0 at the centroid):
//   â = (1/N) Σ e_i,        b̂ = Σ s_i e_i / Σ s_i².
// A range error of std σ along beam u_i moves point i off the line by σ (u_i·n),
// so e_i has variance σ_i² = σ² (u_i·n)² (the along-line part only shifts s_i, a
// second-order effect), independently per point. Hence
//   Var(â) = Σ σ_i² / N²,  Var(b̂) = Σ s_i² σ_i² / (Σ s_i²)²,
//   Cov(â, b̂) = Σ s_i σ_i² / (N Σ s_i²),
// which for equal σ_i are the familiar σ²/N and σ²/Σ(s_i - s̄)², uncorrelated.
// (The neglected second-order terms matter only for large noise at grazing
// incidence: at 5 cm noise on a wall seen from 80° they add about 14 % to the
// variances; tests/scan checks the NEES.)
// The segment frame sits at the midpoint m of the end points, dx = s_m along the
// axis from the centroid; the lateral error there is a + b dx, so
// P = J Σ_ab Jᵀ with J = [[1, dx], [0, 1]] (the dx rule of docs/design.md §3).
std::optional<ExtractedSegment> make_segment(const std::vector<ScanPoint>& points, Range r,
                                             const ExtractionConfig& config) {
  if (r.size() < 2 || static_cast<int>(r.size()) < config.min_points) return std::nullopt;
  const LineFit fit = fit_line(points, r);

  // End points: projections of the first and last points; x of the segment
  // frame grows along `direction`, so first_point is the one with the smaller s.
  double s_first = fit.direction.dot(points[r.begin].p - fit.centroid);
  double s_last = fit.direction.dot(points[r.end - 1].p - fit.centroid);
  if (s_first > s_last) std::swap(s_first, s_last);
  const double length_m = s_last - s_first;
  if (length_m < config.min_length_m || length_m <= 0.0) return std::nullopt;
  const double n = static_cast<double>(r.size());
  if (n < config.min_points_per_m * length_m) return std::nullopt;

  double sum_ss = 0.0;
  double sum_var = 0.0;
  double sum_s_var = 0.0;
  double sum_ss_var = 0.0;
  const double var_range = config.range_noise_m * config.range_noise_m;
  for (std::size_t i = r.begin; i < r.end; ++i) {
    const Eigen::Vector2d& p = points[i].p;
    const double s = fit.direction.dot(p - fit.centroid);
    const double range = p.norm();
    const double cos_incidence = range > 0.0 ? fit.normal.dot(p) / range : 1.0;
    const double var_i = var_range * cos_incidence * cos_incidence;
    sum_ss += s * s;
    sum_var += var_i;
    sum_s_var += s * var_i;
    sum_ss_var += s * s * var_i;
  }
  if (sum_ss <= 1e-12) return std::nullopt;  // all points at one place: no direction
  Eigen::Matrix2d cov_ab;
  cov_ab(0, 0) = sum_var / (n * n);
  cov_ab(1, 1) = sum_ss_var / (sum_ss * sum_ss);
  cov_ab(0, 1) = cov_ab(1, 0) = sum_s_var / (n * sum_ss);
  const double dx = 0.5 * (s_first + s_last);
  Eigen::Matrix2d J;
  J << 1.0, dx, 0.0, 1.0;

  ExtractedSegment out;
  const Eigen::Vector2d midpoint = fit.centroid + dx * fit.direction;
  out.segment.location =
      Pose2(midpoint.x(), midpoint.y(), wrap_angle(std::atan2(fit.direction.y(), fit.direction.x())));
  out.segment.length_m = length_m;
  out.segment.covariance = J * cov_ab * J.transpose();
  out.segment.first_point = fit.centroid + s_first * fit.direction;
  out.segment.last_point = fit.centroid + s_last * fit.direction;
  out.segment.num_points = static_cast<int>(r.size());
  out.first_beam = points[r.begin].beam;
  out.last_beam = points[r.end - 1].beam;
  out.max_residual_m = fit.max_residual_m;
  out.rms_residual_m = fit.rms_residual_m;
  return out;
}

}  // namespace

void ExtractionConfig::validate() const {
  const ConfigCheck require("ExtractionConfig");
  require(std::isfinite(min_range_m) && min_range_m >= 0.0, "min_range_m", min_range_m, "finite and >= 0");
  require(std::isfinite(max_range_m) && max_range_m > min_range_m, "max_range_m", max_range_m,
          "finite and > min_range_m");
  require(std::isfinite(no_return_margin_m) && no_return_margin_m >= 0.0, "no_return_margin_m",
          no_return_margin_m, "finite and >= 0");
  require(std::isfinite(max_point_gap_m) && max_point_gap_m > 0.0, "max_point_gap_m", max_point_gap_m,
          "finite and > 0");
  require(std::isfinite(split_distance_m) && split_distance_m > 0.0, "split_distance_m", split_distance_m,
          "finite and > 0");
  require(std::isfinite(merge_distance_m) && merge_distance_m > 0.0, "merge_distance_m", merge_distance_m,
          "finite and > 0");
  require(min_points >= 2, "min_points", min_points, ">= 2");
  require(std::isfinite(min_length_m) && min_length_m >= 0.0, "min_length_m", min_length_m, "finite and >= 0");
  require(std::isfinite(min_points_per_m) && min_points_per_m >= 0.0, "min_points_per_m", min_points_per_m,
          "finite and >= 0 (0 disables the test)");
  require(std::isfinite(range_noise_m) && range_noise_m > 0.0, "range_noise_m", range_noise_m,
          "finite and > 0");
}

std::vector<ExtractedSegment> extract_segments_with_support(const LaserScan& scan,
                                                            const ExtractionConfig& config) {
  config.validate();
  std::vector<ScanPoint> points;
  points.reserve(scan.ranges_m.size());
  const std::vector<Range> clusters = make_clusters(scan, config, points);

  std::vector<ExtractedSegment> segments;
  std::vector<Range> pieces;
  for (const Range& cluster : clusters) {
    if (static_cast<int>(cluster.size()) < config.min_points) continue;
    pieces.clear();
    split(points, cluster, config.split_distance_m, pieces);
    merge(points, config.merge_distance_m, pieces);
    refine_boundaries(points, std::max(config.split_distance_m, config.merge_distance_m), pieces);
    for (const Range& piece : pieces) {
      if (auto segment = make_segment(points, piece, config)) segments.push_back(std::move(*segment));
    }
  }
  return segments;
}

std::vector<ObservedSegment> extract_segments(const LaserScan& scan, const ExtractionConfig& config) {
  std::vector<ExtractedSegment> with_support = extract_segments_with_support(scan, config);
  std::vector<ObservedSegment> segments;
  segments.reserve(with_support.size());
  for (ExtractedSegment& s : with_support) segments.push_back(s.segment);
  return segments;
}

}  // namespace lmf
