#include "lmf/mission/config_file.hpp"

#include "lmf/local_map/local_map_config_json.hpp"

namespace lmf::mission {

void read_config(io::JsonReader& r, fusion::GlobalMapConfig& c) {
  struct Read {
    io::JsonReader& r;
    void operator()(const char* name, double& v) const { r.read(name, v); }
    void operator()(const char* name, bool& v) const { r.read(name, v); }
    void operator()(const char* name, int& v) const { r.read(name, v); }
    void operator()(const char* name, fusion::HealthCheck& v) const {
      r.read_choice(name, v, fusion::kHealthCheckNames);
    }
    void operator()(const char* name, fusion::FrameRegistrationConfig& g) const {
      if (io::JsonReader* section = r.optional_section(name)) fusion::visit_fields(g, Read{*section});
    }
    void operator()(const char* name, fusion::PlaceRecognitionConfig& g) const {
      if (io::JsonReader* section = r.optional_section(name)) fusion::visit_fields(g, Read{*section});
    }
  };
  fusion::visit_fields(c, Read{r});
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
