// ScanMatcherConfig from JSON, strictly: keys are the field names of
// ScanMatcherConfig (scan_matcher.hpp), absent keys keep their defaults, unknown
// keys and bad values are errors naming the file and the key path.
//
//   {"enabled": true, "point_sigma_m": 0.03, "max_independent_points": 20}
#pragma once

#include "lmf/io/config.hpp"
#include "lmf/scan/scan_matcher.hpp"

namespace lmf {

// Reads the fields present in `reader` into `config` (e.g. the "scan_matching"
// section of a local map config). The caller calls reader.finish() and then
// config.validate() (or a validate() that covers it).
void read_scan_matcher_config(io::JsonReader& reader, ScanMatcherConfig& config);

}  // namespace lmf
