// LocalMapConfig from JSON, strictly: keys are the field names of
// LocalMapConfig (local_map_config.hpp), with the segment extraction in an
// "extraction" section (ExtractionConfig field names); absent keys keep their
// defaults, unknown keys and bad values are errors (std::invalid_argument naming
// the file and the key path). A separate library (lmf::local_map_config) so
// lmf::local_map does not depend on lmf::io.
//
//   {"ship_distance_m": 10, "constraints_enabled": true,
//    "extraction": {"split_distance_m": 0.15}}
#pragma once

#include <filesystem>

#include "lmf/io/config.hpp"
#include "lmf/local_map/local_map_config.hpp"

namespace lmf {

// Reads the fields present in `reader` into `config` (e.g. a "local_map"
// section of a larger config). The caller calls reader.finish() and then
// config.validate().
void read_local_map_config(io::JsonReader& reader, LocalMapConfig& config);

// A whole file holding one LocalMapConfig object: read, finish, validate.
LocalMapConfig load_local_map_config(const std::filesystem::path& file);

}  // namespace lmf
