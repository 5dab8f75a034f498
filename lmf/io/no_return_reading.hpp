// The reading a laser writes for a beam with no return, found in a log that
// does not say it (CARMEN FLASER has no maximum-range field).
//
// A laser that sees nothing within its range writes one fixed value, its
// ceiling: a SICK LMS 81.91 m (or 32.767 m, 51.15 m by mode), a Hokuyo URG
// its 5.6 m or 8 m, a simulator its configured range. Read as a return, that
// value draws an arc at the ceiling around the robot, which moves with it:
// matched, the arc says "the robot stood still" (a short-range laser in a
// corridor loses most of its along-the-corridor travel to it). So the reader
// finds the ceiling from the readings themselves: a value above most
// readings that many scans touch and almost none pass. A wall at one exact
// distance in many scans, with farther walls seen in others, is not one.
//
// Pure, thread-safe.
#pragma once

#include <cstddef>
#include <functional>
#include <optional>
#include <string>
#include <vector>

#include "lmf/scan/laser_scan.hpp"

namespace lmf::io {

// The ceiling also lies above the scans' median reading: a log of one
// constant range has no ceiling to tell.
struct NoReturnCeiling {
  // A scan touches the ceiling when one of its readings equals it: at least
  // one scan in twenty does, and at least this many (an exact value repeated
  // by chance in a few scans is not a ceiling).
  double min_share_touching = 0.05;
  std::size_t min_scans_touching = 10;
  // A reading passes it when it lies beyond the ceiling by more than this
  // (another no-return code of the same laser may lie a little above) ...
  double pass_margin_m = 0.1;
  // ... and fewer than one scan in a hundred may read past it.
  double max_share_passing = 0.01;
};

struct NoReturnReading {
  std::optional<double> range_m;  // the ceiling, when the readings show one
  std::size_t scans_touching = 0;
  std::size_t scans_passing = 0;
  std::size_t scans = 0;
  double median_reading_m = 0.0;  // the median of the scans' median readings
};

// The ceiling of the readings of those `scans` for which `counted` is true
// (all when it is empty), as above: range_m unset when no value is touched by
// enough scans, or too many scans read past the one that is.
NoReturnReading find_no_return_reading(const std::vector<LaserScan>& scans,
                                       const std::function<bool(const LaserScan&)>& counted = {},
                                       const NoReturnCeiling& ceiling = {});

// One line for people: "no-return reading 8.000 m (in 93 % of the scans)", or
// why none was found.
std::string describe(const NoReturnReading& reading);

}  // namespace lmf::io
