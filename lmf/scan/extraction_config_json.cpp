#include "lmf/scan/extraction_config_json.hpp"

#include <stdexcept>
#include <string>

namespace lmf {

void read_extraction_config(io::JsonReader& reader, ExtractionConfig& config) {
  reader.read("min_range_m", config.min_range_m, io::non_negative());
  reader.read("max_range_m", config.max_range_m, io::positive());
  reader.read("no_return_margin_m", config.no_return_margin_m, io::non_negative());
  reader.read("max_point_gap_m", config.max_point_gap_m, io::positive());
  reader.read("split_distance_m", config.split_distance_m, io::positive());
  reader.read("merge_distance_m", config.merge_distance_m, io::positive());
  reader.read("min_points", config.min_points, io::at_least(2.0));
  reader.read("min_length_m", config.min_length_m, io::non_negative());
  reader.read("min_points_per_m", config.min_points_per_m, io::non_negative());
  reader.read("range_noise_m", config.range_noise_m, io::positive());
}

ExtractionConfig load_extraction_config(const std::filesystem::path& file) {
  io::JsonReader reader = io::JsonReader::from_file(file);
  ExtractionConfig config;
  read_extraction_config(reader, config);
  io::finish_and_validate(reader, config);
  return config;
}

}  // namespace lmf
