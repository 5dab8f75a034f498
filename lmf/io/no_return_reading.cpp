#include "lmf/io/no_return_reading.hpp"

#include <algorithm>
#include <cmath>
#include <utility>
#include <cstdio>
#include <unordered_map>

#include "lmf/common/median.hpp"

namespace lmf::io {

NoReturnReading find_no_return_reading(const std::vector<LaserScan>& scans,
                                       const std::function<bool(const LaserScan&)>& counted,
                                       const NoReturnCeiling& ceiling) {
  NoReturnReading out;
  // For each distinct reading, the scans that hold it; each scan's farthest
  // and median reading.
  std::unordered_map<double, std::size_t> scans_holding;
  std::vector<double> farthest;
  std::vector<double> medians;
  std::vector<double> readings;
  for (const LaserScan& scan : scans) {
    if (counted && !counted(scan)) continue;
    ++out.scans;
    readings.clear();
    for (const double r : scan.ranges_m) {
      if (std::isfinite(r)) readings.push_back(r);
    }
    if (readings.empty()) continue;
    std::sort(readings.begin(), readings.end());
    medians.push_back(readings[readings.size() / 2]);
    farthest.push_back(readings.back());
    readings.erase(std::unique(readings.begin(), readings.end()), readings.end());
    for (const double r : readings) ++scans_holding[r];
  }
  if (medians.empty()) return out;
  out.median_reading_m = median(std::move(medians));
  // The largest reading enough scans touch.
  const double needed = std::max(static_cast<double>(ceiling.min_scans_touching),
                                 ceiling.min_share_touching * static_cast<double>(out.scans));
  std::optional<double> top;
  for (const auto& [r, count] : scans_holding) {
    if (static_cast<double>(count) >= needed && (!top || r > *top)) top = r;
  }
  if (!top) return out;
  out.scans_touching = scans_holding[*top];
  out.scans_passing = static_cast<std::size_t>(std::count_if(
      farthest.begin(), farthest.end(), [&](double r) { return r > *top + ceiling.pass_margin_m; }));
  if (*top > out.median_reading_m &&
      static_cast<double>(out.scans_passing) < ceiling.max_share_passing * static_cast<double>(out.scans)) {
    out.range_m = top;
  }
  return out;
}

std::string describe(const NoReturnReading& reading) {
  char text[160];
  if (reading.range_m) {
    std::snprintf(text, sizeof text, "no-return reading %.3f m (in %.0f %% of the scans)", *reading.range_m,
                  100.0 * static_cast<double>(reading.scans_touching) / static_cast<double>(reading.scans));
  } else if (reading.scans_touching > 0) {
    std::snprintf(text, sizeof text,
                  "no no-return reading: the most common farthest one is not above the median reading, or %zu of "
                  "%zu scans read past it",
                  reading.scans_passing, reading.scans);
  } else {
    std::snprintf(text, sizeof text, "no no-return reading: no farthest value common to the scans");
  }
  return text;
}

}  // namespace lmf::io
