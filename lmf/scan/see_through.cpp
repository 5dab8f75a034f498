#include "lmf/scan/see_through.hpp"

#include <algorithm>
#include <cmath>
#include <limits>
#include <numbers>
#include <stdexcept>

#include "lmf/common/config_check.hpp"

namespace lmf {

void SeeThroughConfig::validate() const {
  const ConfigCheck require("SeeThroughConfig");
  require(std::isfinite(margin_m) && margin_m > 0.0, "margin_m", margin_m, "finite and > 0");
  require(std::isfinite(end_margin_m) && end_margin_m >= 0.0, "end_margin_m", end_margin_m, "finite and >= 0");
  require(std::isfinite(min_incidence_rad) && min_incidence_rad >= 0.0 && min_incidence_rad < std::numbers::pi / 2,
          "min_incidence_rad", min_incidence_rad, "in [0, pi/2)");
  require(min_beams >= 1, "min_beams", min_beams, ">= 1");
  require(std::isfinite(min_fraction) && min_fraction > 0.0 && min_fraction <= 1.0, "min_fraction", min_fraction,
          "in (0, 1]");
  require(std::isfinite(min_coverage) && min_coverage >= 0.0 && min_coverage <= 1.0, "min_coverage", min_coverage,
          "in [0, 1]");
}

bool SeeThroughCount::seen_through(const SeeThroughConfig& config) const {
  return through >= config.min_beams &&
         static_cast<double>(through) >= config.min_fraction * static_cast<double>(through + support) &&
         through_extent_m >= config.min_coverage * checked_length_m;
}

std::vector<SeeThroughCount> count_see_through(const LaserScan& scan, const std::vector<SensorSegment>& segments,
                                               double min_range_m, double max_range_m,
                                               const SeeThroughConfig& config) {
  std::vector<SeeThroughCount> counts(segments.size());
  const auto beams = static_cast<long>(scan.ranges_m.size());
  if (beams == 0 || !(scan.angle_increment_rad > 0.0)) return counts;
  const double sin_min_incidence = std::sin(config.min_incidence_rad);

  for (std::size_t s = 0; s < segments.size(); ++s) {
    const SensorSegment& segment = segments[s];
    const double c = std::cos(segment.location.phi);
    const double sn = std::sin(segment.location.phi);
    const double half = 0.5 * segment.length_m;
    const double mx = segment.location.x;
    const double my = segment.location.y;
    const double d = -sn * mx + c * my;  // the line n·p = d, unit normal n = (-sin, cos)
    SeeThroughCount& count = counts[s];
    count.checked_length_m = std::max(0.0, segment.length_m - 2.0 * config.end_margin_m);
    double through_min = std::numeric_limits<double>::infinity();
    double through_max = -std::numeric_limits<double>::infinity();

    const auto visit = [&](std::size_t i) {
      const double theta = scan.beam_angle(i);
      const double ux = std::cos(theta);
      const double uy = std::sin(theta);
      const double n_dot_u = -sn * ux + c * uy;
      if (std::abs(n_dot_u) < sin_min_incidence) return;  // grazing
      const double r_cross = d / n_dot_u;                 // the beam meets the line at this range
      if (!(r_cross > 0.0)) return;
      const double along = c * (r_cross * ux - mx) + sn * (r_cross * uy - my);
      if (std::abs(along) > half - config.end_margin_m) return;  // near (or past) an end
      const double r = scan.ranges_m[i];
      if (!(std::isfinite(r) && r >= min_range_m && r < max_range_m)) return;  // no return
      if (r > r_cross + config.margin_m) {
        ++count.through;
        through_min = std::min(through_min, along);
        through_max = std::max(through_max, along);
      } else if (r >= r_cross - config.margin_m) {
        ++count.support;
      }  // else: something in front of the segment hides it
    };

    // The beams between the bearings of the two ends (the shorter arc
    // [lo, lo + span]), measured from angle_min: the arc starts at w in
    // [-pi, pi), or at w + 2 pi (the last beams of a 360° scanner).
    const double a1 = std::atan2(my - half * sn, mx - half * c);
    const double a2 = std::atan2(my + half * sn, mx + half * c);
    const double lo = wrap_angle(a2 - a1) >= 0.0 ? a1 : a2;
    const double span = std::abs(wrap_angle(a2 - a1));
    const double w = wrap_angle(lo - scan.angle_min_rad);
    for (const double start : {w, w + 2.0 * std::numbers::pi}) {
      const auto first = std::max(0L, static_cast<long>(std::ceil(start / scan.angle_increment_rad)));
      const auto last = std::min(beams - 1, static_cast<long>(std::floor((start + span) / scan.angle_increment_rad)));
      for (long i = first; i <= last; ++i) visit(static_cast<std::size_t>(i));
    }
    if (count.through > 0) count.through_extent_m = through_max - through_min;
  }
  return counts;
}

}  // namespace lmf
