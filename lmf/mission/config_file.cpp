#include "lmf/mission/config_file.hpp"

#include "lmf/local_map/local_map_config_json.hpp"

namespace lmf::mission {

void read_config(io::JsonReader& r, fusion::GlobalMapConfig& c) {
  r.read("alpha", c.alpha);
  r.read("local_map_covariance_scale", c.local_map_covariance_scale);
  r.read("gate_angle_rad", c.gate_angle_rad);
  r.read("gate_distance_m", c.gate_distance_m);
  r.read("gate_gap_m", c.gate_gap_m);
  r.read("gate_sigmas", c.gate_sigmas);
  r.read("min_overlap_m", c.min_overlap_m);
  r.read("careful_relative_tolerance", c.careful_relative_tolerance);
  r.read("careful_absolute_floor", c.careful_absolute_floor);
  r.read("snapshot_tolerance", c.snapshot_tolerance);
  r.read("max_coordinate_m", c.max_coordinate_m);
  r.read("first_robot_defines_world", c.first_robot_defines_world);
  r.read_choice("health", c.health,
                {{"none", fusion::HealthCheck::kNone},
                 {"touched", fusion::HealthCheck::kTouched},
                 {"full_ldlt", fusion::HealthCheck::kFullLdlt},
                 {"full_eigen", fusion::HealthCheck::kFullEigen}});
  r.read("frame_history_per_robot", c.frame_history_per_robot);
  r.read("footprint_radius_m", c.footprint_radius_m);
  r.read("crossing_margin_m", c.crossing_margin_m);
  r.read("crossing_max_angle_rad", c.crossing_max_angle_rad);
  if (io::JsonReader* g = r.optional_section("registration")) {
    g->read("enabled", c.registration.enabled);
    g->read("window_m", c.registration.window_m);
    g->read("window_rad", c.registration.window_rad);
    g->read("resolution_m", c.registration.resolution_m);
    g->read("min_score", c.registration.min_score);
    g->read("ambiguity_ratio", c.registration.ambiguity_ratio);
    g->read("min_constraint", c.registration.min_constraint);
    g->read("own_recent_maps", c.registration.own_recent_maps);
  }
}

void read_config(io::JsonReader& r, SightingNoise& c) {
  r.read("sigma_xy_m", c.sigma_xy_m);
  r.read("sigma_phi_rad", c.sigma_phi_rad);
  r.read("seed", c.seed);
}

namespace {

MissionConfig read_mission(io::JsonReader& r) {
  MissionConfig config;
  if (io::JsonReader* s = r.optional_section("local_map")) read_local_map_config(*s, config.local_map);
  if (io::JsonReader* s = r.optional_section("global_map")) read_config(*s, config.global_map);
  if (io::JsonReader* s = r.optional_section("sighting_noise")) read_config(*s, config.sighting_noise);
  io::finish_and_validate(r, config);
  return config;
}

}  // namespace

MissionConfig load_mission_config(const std::filesystem::path& file) {
  io::JsonReader reader = io::JsonReader::from_file(file);
  return read_mission(reader);
}

MissionConfig parse_mission_config(const std::string& json_text, const std::string& source) {
  io::JsonReader reader = io::JsonReader::from_string(json_text, source);
  return read_mission(reader);
}

}  // namespace lmf::mission
