// ExtractionConfig from JSON, strictly: keys are the field names of
// ExtractionConfig (segment_extraction.hpp), absent keys keep their defaults,
// unknown keys and bad values are errors (std::invalid_argument naming the file
// and the key path). A separate library (lmf::scan_config) so lmf::scan does not
// depend on lmf::io, which depends on it.
//
//   {"split_distance_m": 0.06, "merge_distance_m": 0.06, "range_noise_m": 0.02}
#pragma once

#include <filesystem>

#include "lmf/io/config.hpp"
#include "lmf/scan/segment_extraction.hpp"

namespace lmf {

// Reads the fields present in `reader` into `config` (e.g. an "extraction"
// section of a larger config). The caller calls reader.finish() and then
// config.validate() (or a validate() that covers it).
void read_extraction_config(io::JsonReader& reader, ExtractionConfig& config);

// A whole file holding one ExtractionConfig object: read, finish, validate.
ExtractionConfig load_extraction_config(const std::filesystem::path& file);

}  // namespace lmf
