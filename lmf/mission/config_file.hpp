// The mission's JSON configuration file: one typed section per module, parsed
// strictly (unknown keys and wrong types are errors naming the file and key),
// defaults from the structs. Example (every key optional):
//   {
//     "local_map": { "ship_distance_m": 10, "constraints_enabled": true,
//                    "extraction": { "split_distance_m": 0.15 } },
//     "global_map": { "alpha": 0.05 },
//     "sighting_noise": { "sigma_xy_m": 0.05, "sigma_phi_rad": 0.02, "seed": 1 }
//   }
#pragma once

#include <filesystem>
#include <string>

#include "lmf/io/config.hpp"
#include "lmf/mission/offline_mission.hpp"

namespace lmf::mission {

void read_config(io::JsonReader& reader, fusion::GlobalMapConfig& config);
void read_config(io::JsonReader& reader, SightingNoise& config);

// Reads and validates a whole mission config. Throws std::invalid_argument.
MissionConfig load_mission_config(const std::filesystem::path& file);
MissionConfig parse_mission_config(const std::string& json_text, const std::string& source = "<string>");

}  // namespace lmf::mission
