#include "lmf/local_map/local_map_config_json.hpp"

#include <stdexcept>
#include <string>

#include "lmf/scan/extraction_config_json.hpp"
#include "lmf/scan/scan_matcher_config_json.hpp"

namespace lmf {

void read_local_map_config(io::JsonReader& reader, LocalMapConfig& config) {
  reader.read("odom_translation_noise_ratio", config.odom_translation_noise_ratio, io::non_negative());
  reader.read("odom_rotation_noise_ratio", config.odom_rotation_noise_ratio, io::non_negative());
  reader.read("odom_drift_rad_per_m", config.odom_drift_rad_per_m, io::non_negative());
  reader.read("odom_noise_floor_m", config.odom_noise_floor_m, io::non_negative());
  reader.read("odom_noise_floor_rad", config.odom_noise_floor_rad, io::non_negative());
  reader.read("observation_lateral_noise_m", config.observation_lateral_noise_m, io::non_negative());
  reader.read("observation_angular_noise_rad", config.observation_angular_noise_rad, io::non_negative());
  reader.read("observation_end_noise_m", config.observation_end_noise_m, io::non_negative());
  reader.read("pairing_alpha", config.pairing_alpha, io::in_open(0.0, 1.0));
  reader.read("overlap_gap_tolerance_m", config.overlap_gap_tolerance_m, io::non_negative());
  reader.read("joint_alpha", config.joint_alpha, io::in_open(0.0, 1.0));
  reader.read("joint_compatibility_restarts", config.joint_compatibility_restarts);
  reader.read("careful_inverse_tolerance", config.careful_inverse_tolerance, io::in_open(0.0, 1.0));
  reader.read("fusion_alpha", config.fusion_alpha, io::in_open(0.0, 1.0));
  reader.read("constraints_enabled", config.constraints_enabled);
  reader.read("constraint_max_angle_rad", config.constraint_max_angle_rad, io::non_negative());
  reader.read("constraint_alpha", config.constraint_alpha, io::in_open(0.0, 1.0));
  reader.read("ship_distance_m", config.ship_distance_m, io::positive());
  reader.read("max_segments", config.max_segments, io::positive());
  reader.read("covariance_tolerance", config.covariance_tolerance, io::non_negative());
  reader.read("covariance_check_interval", config.covariance_check_interval);
  reader.read("scans_have_odometry", config.scans_have_odometry);
  reader.read("motion_filter", config.motion_filter);
  if (io::JsonReader* extraction = reader.optional_section("extraction")) {
    read_extraction_config(*extraction, config.extraction);
  }
  if (io::JsonReader* scan_matching = reader.optional_section("scan_matching")) {
    read_scan_matcher_config(*scan_matching, config.scan_matching);
  }
  if (io::JsonReader* learning = reader.optional_section("odometry_learning")) {
    OdometryLearningConfig& c = config.odometry_learning;
    learning->read("enabled", c.enabled);
    learning->read("prior_increments", c.prior_increments, io::positive());
    learning->read("memory_increments", c.memory_increments, io::at_least(1.0));
    learning->read("sweeps_per_increment", c.sweeps_per_increment, io::at_least(1.0));
    learning->read("student_dof", c.student_dof, io::positive());
    learning->read("scale_prior_std", c.scale_prior_std, io::positive());
    learning->read("heading_bias_prior_std_rad_per_m", c.heading_bias_prior_std_rad_per_m, io::positive());
    learning->read("max_scale_error", c.max_scale_error, io::in_open(0.0, 1.0));
    learning->read("max_heading_bias_rad_per_m", c.max_heading_bias_rad_per_m, io::non_negative());
  }
  if (io::JsonReader* see_through = reader.optional_section("see_through")) {
    see_through->read("enabled", config.see_through.enabled);
    see_through->read("margin_m", config.see_through.margin_m, io::positive());
    see_through->read("end_margin_m", config.see_through.end_margin_m, io::non_negative());
    see_through->read("min_incidence_rad", config.see_through.min_incidence_rad, io::non_negative());
    see_through->read("min_beams", config.see_through.min_beams);
    see_through->read("min_fraction", config.see_through.min_fraction, io::positive());
    see_through->read("min_coverage", config.see_through.min_coverage, io::non_negative());
  }
}

LocalMapConfig load_local_map_config(const std::filesystem::path& file) {
  io::JsonReader reader = io::JsonReader::from_file(file);
  LocalMapConfig config;
  read_local_map_config(reader, config);
  io::finish_and_validate(reader, config);
  return config;
}

}  // namespace lmf
