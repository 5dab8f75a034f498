#include "lmf/scan/scan_matcher_config_json.hpp"

namespace lmf {

void read_scan_matcher_config(io::JsonReader& reader, ScanMatcherConfig& config) {
  reader.read("enabled", config.enabled);
  reader.read("min_range_m", config.min_range_m, io::non_negative());
  reader.read("max_range_m", config.max_range_m, io::positive());
  reader.read("no_return_margin_m", config.no_return_margin_m, io::non_negative());
  reader.read("max_object_extent_m", config.max_object_extent_m, io::non_negative());
  reader.read("object_range_jump_m", config.object_range_jump_m, io::positive());
  reader.read("object_consistency_alpha", config.object_consistency_alpha, io::in_open(0.0, 1.0));
  reader.read("normal_radius_m", config.normal_radius_m, io::positive());
  reader.read("max_normal_flatness", config.max_normal_flatness, io::in_closed(0.0, 1.0));
  reader.read("search_window_m", config.search_window_m, io::non_negative());
  reader.read("search_window_rad", config.search_window_rad, io::non_negative());
  reader.read("search_resolution_m", config.search_resolution_m, io::positive());
  reader.read("min_overlap", config.min_overlap, io::non_negative());
  reader.read("field_along_lines", config.field_along_lines);
  reader.read("ambiguity_ratio", config.ambiguity_ratio, io::positive());
  reader.read("history_scans", config.history_scans, io::at_least(1.0));
  reader.read("keyframe_distance_m", config.keyframe_distance_m, io::non_negative());
  reader.read("keyframe_angle_rad", config.keyframe_angle_rad, io::non_negative());
  reader.read("reference_voxel_m", config.reference_voxel_m, io::positive());
  reader.read("first_gate_m", config.first_gate_m, io::positive());
  reader.read("last_gate_m", config.last_gate_m, io::positive());
  reader.read("max_iterations", config.max_iterations, io::at_least(1.0));
  reader.read("min_correspondences", config.min_correspondences, io::at_least(3.0));
  reader.read("point_sigma_m", config.point_sigma_m, io::positive());
  reader.read("range_noise_per_m", config.range_noise_per_m, io::non_negative());
  reader.read("range_noise_from_residuals", config.range_noise_from_residuals);
  reader.read("huber_k", config.huber_k, io::positive());
  reader.read("residual_sigma", config.residual_sigma);
  reader.read("residual_correlation", config.residual_correlation);
  reader.read("max_independent_points", config.max_independent_points, io::positive());
  reader.read("model_noise_m", config.model_noise_m, io::non_negative());
  reader.read("model_noise_rad", config.model_noise_rad, io::non_negative());
  reader.read("prior_alpha", config.prior_alpha, io::in_open(0.0, 1.0));
}

}  // namespace lmf
