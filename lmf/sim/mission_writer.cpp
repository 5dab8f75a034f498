#include "lmf/sim/mission_writer.hpp"

#include <cmath>
#include <cstdio>
#include <fstream>
#include <stdexcept>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "lmf/geometry/stamped_pose.hpp"
#include "lmf/io/carmen.hpp"
#include "lmf/io/svg.hpp"
#include "lmf/io/trajectory.hpp"

namespace lmf::sim {
namespace {

using nlohmann::json;

// Fixed precision for JSON numbers: rounded to 1e-6 (and no negative zero), then printed
// in the shortest form that reads back the same, which does not depend on the platform.
double fixed(double v) {
  const double r = std::round(v * 1e6) / 1e6;
  return r == 0.0 ? 0.0 : r;
}
json xy(const Eigen::Vector2d& p) { return json::array({fixed(p.x()), fixed(p.y())}); }
json pose(const Pose2& x) { return json::array({fixed(x.x), fixed(x.y), fixed(x.phi)}); }
json box(const Box& b) { return {{"min", xy(b.min)}, {"max", xy(b.max)}}; }

// Pretty JSON whose arrays of plain values stay on one line (a wall per line).
void dump(const json& j, int indent, std::string& out) {
  const std::string pad(static_cast<std::size_t>(indent + 2), ' ');
  const std::string end_pad(static_cast<std::size_t>(indent), ' ');
  if (j.is_object()) {
    if (j.empty()) {
      out += "{}";
      return;
    }
    out += "{\n";
    bool first = true;
    for (auto it = j.begin(); it != j.end(); ++it) {
      if (!first) out += ",\n";
      first = false;
      out += pad + json(it.key()).dump() + ": ";
      dump(it.value(), indent + 2, out);
    }
    out += "\n" + end_pad + "}";
  } else if (j.is_array()) {
    bool flat = true;
    for (const auto& e : j) flat = flat && !e.is_structured();
    if (flat) {
      out += "[";
      for (std::size_t i = 0; i < j.size(); ++i) out += (i ? ", " : "") + j[i].dump();
      out += "]";
      return;
    }
    out += "[\n";
    for (std::size_t i = 0; i < j.size(); ++i) {
      out += (i ? ",\n" : "") + pad;
      dump(j[i], indent + 2, out);
    }
    out += "\n" + end_pad + "]";
  } else {
    out += j.dump();
  }
}

void write_json(const std::filesystem::path& file, const json& j) {
  std::string text;
  dump(j, 0, text);
  text += "\n";
  std::ofstream out(file, std::ios::binary);
  out << text;
  out.close();
  if (!out) throw std::runtime_error("write_mission: cannot write " + file.string());
}

std::string robot_name(int id) { return "robot" + std::to_string(id); }

json real_odometry_json(const RealOdometryConfig& r) {
  return {{"translation_scale_sigma", fixed(r.translation_scale_sigma)},
          {"rotation_scale_sigma", fixed(r.rotation_scale_sigma)},
          {"heading_bias_sigma_rad_per_m", fixed(r.heading_bias_sigma_rad_per_m)},
          {"translation_noise_fraction", fixed(r.translation_noise_fraction)},
          {"rotation_noise_fraction", fixed(r.rotation_noise_fraction)},
          {"heading_noise_rad2_per_m", fixed(r.heading_noise_rad2_per_m)},
          {"heading_noise_per_step_rad", fixed(r.heading_noise_per_step_rad)},
          {"slip_per_m", fixed(r.slip_per_m)},
          {"slip_per_rad", fixed(r.slip_per_rad)},
          {"heading_glitch_rate_per_m", fixed(r.heading_glitch_rate_per_m)},
          {"heading_glitch_min_rad", fixed(r.heading_glitch_min_rad)},
          {"heading_glitch_max_rad", fixed(r.heading_glitch_max_rad)},
          {"translation_glitch_rate_per_m", fixed(r.translation_glitch_rate_per_m)},
          {"translation_glitch_min_m", fixed(r.translation_glitch_min_m)},
          {"translation_glitch_max_m", fixed(r.translation_glitch_max_m)},
          {"model",
           "per robot s_t=1+N(0,translation_scale_sigma^2), s_r=1+N(0,rotation_scale_sigma^2), "
           "b=N(0,heading_bias_sigma_rad_per_m^2); per increment (lmf/sim/odometry.hpp): "
           "dx=s_t dx+N(0,(translation_noise_fraction d)^2)+translation glitch, "
           "dy=s_t dy+N(0,(slip_per_m d+slip_per_rad |dphi|)^2), "
           "dphi=s_r dphi+b d+N(0,(rotation_noise_fraction |dphi|)^2+heading_noise_rad2_per_m d+"
           "heading_noise_per_step_rad^2)+heading glitch; glitches Poisson per metre"}};
}

json config_json(const MissionConfig& c) {
  json j = {
      {"seed", c.seed},
      {"num_robots", c.num_robots},
      {"duration_s", fixed(c.duration_s)},
      {"scan_rate_hz", fixed(c.scan_rate_hz)},
      {"start_time_s", fixed(c.start_time_s)},
      {"robot_radius_m", fixed(c.robot_radius_m)},
      {"robots_visible_in_scans", c.robots_visible_in_scans},
      {"robot_gap_m", fixed(c.robot_gap_m)},
      {"max_wait_s", fixed(c.max_wait_s)},
      {"world",
       {{"ring_length_m", fixed(c.world.ring_length_m)},
        {"ring_width_m", fixed(c.world.ring_width_m)},
        {"corridor_width_m", fixed(c.world.corridor_width_m)},
        {"wall_thickness_m", fixed(c.world.wall_thickness_m)},
        {"door_width_m", fixed(c.world.door_width_m)},
        {"side_corridor_length_m", fixed(c.world.side_corridor_length_m)},
        {"room_probability", fixed(c.world.room_probability)},
        {"table_probability", fixed(c.world.table_probability)}}},
      {"laser",
       {{"num_beams", c.laser.num_beams},
        {"angle_min_rad", -0.5 * 3.14159265358979323846},
        {"angle_increment_rad", beam_increment_for_180deg(c.laser.num_beams)},
        {"range_noise_sigma_m", fixed(c.laser.range_noise_sigma_m)},
        {"range_noise_per_m", fixed(c.laser.range_noise_per_m)},
        {"max_range_m", fixed(c.laser.max_range_m)}}},
      {"motion",
       {{"speed_mps", fixed(c.motion.speed_mps)},
        {"turn_radius_m", fixed(c.motion.turn_radius_m)},
        {"rotation_speed_radps", fixed(c.motion.rotation_speed_radps)},
        {"wall_margin_m", fixed(c.motion.wall_margin_m)},
        {"room_visit_probability", fixed(c.motion.room_visit_probability)},
        {"revisit_room_probability", fixed(c.motion.revisit_room_probability)}}},
      {"odometry",
       {{"translation_fraction", fixed(c.odometry.translation_fraction)},
        {"rotation_fraction", fixed(c.odometry.rotation_fraction)},
        {"heading_drift_rad_per_m", fixed(c.odometry.heading_drift_rad_per_m)},
        {"model",
         "per scan increment u=(dx,dy,dphi), d=|(dx,dy)|: dx,dy += N(0,(translation_fraction*d)^2), "
         "dphi += N(0,(rotation_fraction*|dphi|+heading_drift_rad_per_m*d)^2); odometry starts at the true "
         "start pose"}}},
      {"sightings",
       {{"max_range_m", fixed(c.sightings.max_range_m)},
        {"field_of_view_rad", fixed(c.sightings.field_of_view_rad)},
        {"min_interval_s", fixed(c.sightings.min_interval_s)}}},
      {"people",
       {{"count", c.people.count},
        {"radius_m", fixed(c.people.radius_m)},
        {"min_speed_mps", fixed(c.people.min_speed_mps)},
        {"max_speed_mps", fixed(c.people.max_speed_mps)}}},
  };
  j["odometry_model"] = odometry_model_name(c.odometry_model);
  if (c.odometry_model == OdometryModel::kReal) j["real_odometry"] = real_odometry_json(c.real_odometry);
  return j;
}

}  // namespace

void write_world_svg(const Mission& mission, const std::filesystem::path& file) {
  const World& world = mission.world;
  io::SvgDocument svg(20.0, 20.0);
  svg.set_title("lmf-sim world, seed " + std::to_string(world.seed));
  svg.include_point(world.bounds.min);
  svg.include_point(world.bounds.max);

  svg.begin_group("rooms", "rooms");
  io::SvgStyle room_style;
  room_style.stroke = "none";
  room_style.fill = "#f2efe6";
  for (const auto& room : world.rooms) {
    svg.add_polygon({room.box.min, {room.box.max.x(), room.box.min.y()}, room.box.max, {room.box.min.x(), room.box.max.y()}},
                    room_style);
  }
  svg.end_group();

  svg.begin_group("walls", "walls");
  io::SvgStyle wall_style;
  wall_style.stroke = "#222222";
  wall_style.stroke_width_px = 1.5;
  for (const auto& w : world.walls) svg.add_line(w.a, w.b, wall_style);
  svg.end_group();

  static const char* kColors[] = {"#1f77b4", "#d62728", "#2ca02c", "#ff7f0e", "#9467bd", "#8c564b", "#e377c2", "#17becf"};
  for (const auto& run : mission.robots) {
    const std::string color = kColors[static_cast<std::size_t>(run.id) % 8];
    svg.begin_group(robot_name(run.id) + " true path", robot_name(run.id));
    io::SvgStyle path_style;
    path_style.stroke = color;
    path_style.stroke_width_px = 1.2;
    path_style.stroke_opacity = 0.8;
    std::vector<Eigen::Vector2d> points;
    for (const auto& x : run.true_poses) {
      const Eigen::Vector2d p(x.x, x.y);
      if (points.empty() || (p - points.back()).norm() >= 0.25) points.push_back(p);
    }
    if (!run.true_poses.empty()) points.push_back({run.true_poses.back().x, run.true_poses.back().y});
    svg.add_polyline(points, path_style);
    if (!run.true_poses.empty()) {
      const Pose2& s = run.true_poses.front();
      io::SvgStyle marker;
      marker.stroke = "black";
      marker.fill = color;
      svg.add_circle({s.x, s.y}, 0.35, marker);
      svg.add_line({s.x, s.y}, {s.x + 0.8 * std::cos(s.phi), s.y + 0.8 * std::sin(s.phi)}, marker);
      io::SvgTextStyle label;
      label.color = color;
      label.bold = true;
      svg.add_text({s.x + 0.4, s.y + 0.5}, "R" + std::to_string(run.id) + " start", label);
    }
    svg.end_group();
  }
  svg.add_scale_bar(10.0, "m");
  svg.write(file);
}

void write_mission(const Mission& mission, const std::filesystem::path& dir) {
  std::error_code ec;
  std::filesystem::create_directories(dir, ec);
  if (ec) throw std::runtime_error("write_mission: cannot create " + dir.string() + ": " + ec.message());
  const MissionConfig& c = mission.config;
  const World& world = mission.world;

  json robots = json::array();
  for (const auto& run : mission.robots) {
    const std::string name = robot_name(run.id);
    io::CarmenWriteOptions options;
    options.host = "lmf-sim";
    char line[160];
    std::snprintf(line, sizeof line, "lmf-sim seed %llu robot %d: FLASER pose fields = noisy odometry",
                  static_cast<unsigned long long>(c.seed), run.id);
    options.header_comments.emplace_back(line);
    std::snprintf(line, sizeof line, "max_range_m %.3f (a reading of max_range_m means no return); range noise %.3f m + %.4f m/m",
                  c.laser.max_range_m, c.laser.range_noise_sigma_m, c.laser.range_noise_per_m);
    options.header_comments.emplace_back(line);
    io::write_carmen_log(dir / (name + ".log"), run.scans, options);

    std::vector<StampedPose> poses;
    poses.reserve(run.true_poses.size());
    for (std::size_t k = 0; k < run.true_poses.size(); ++k) poses.push_back({run.scans[k].utime, run.true_poses[k]});
    io::write_trajectory(dir / (name + ".gt"), poses,
                         {"lmf-sim seed " + std::to_string(c.seed) + " " + name + ": true pose x_WR per scan, t x y theta"});

    robots.push_back({{"id", run.id},
                      {"log", name + ".log"},
                      {"ground_truth", name + ".gt"},
                      {"scans", run.scans.size()},
                      {"start_pose", run.true_poses.empty() ? json::array() : pose(run.true_poses.front())},
                      {"distance_m", fixed(run.distance_m)},
                      {"odometry_distance_m", fixed(run.odometry_distance_m)}});
    if (c.odometry_model == OdometryModel::kReal) {
      robots.back()["odometry_errors"] = {{"translation_scale", fixed(run.odometry_errors.translation_scale)},
                                          {"rotation_scale", fixed(run.odometry_errors.rotation_scale)},
                                          {"heading_bias_rad_per_m", fixed(run.odometry_errors.heading_bias_rad_per_m)}};
    }
  }

  json walls = json::array();
  for (const auto& w : world.walls) walls.push_back({fixed(w.a.x()), fixed(w.a.y()), fixed(w.b.x()), fixed(w.b.y())});
  json rooms = json::array();
  for (const auto& r : world.rooms) {
    rooms.push_back({{"min", xy(r.box.min)}, {"max", xy(r.box.max)}, {"door", xy(r.door_center)}, {"table", r.has_table}});
  }
  json tables = json::array();
  for (const auto& t : world.tables) tables.push_back(box(t));
  json loop = json::array();
  for (const auto& p : world.loop) loop.push_back(xy(p));
  write_json(dir / "walls.json",
             {{"format", "lmf-sim walls v1"},
              {"seed", world.seed},
              {"loop_length_m", fixed(world.loop_length_m)},
              {"loop", loop},
              {"corridor_width_m", fixed(world.config.corridor_width_m)},
              {"wall_thickness_m", fixed(world.config.wall_thickness_m)},
              {"door_width_m", fixed(world.config.door_width_m)},
              {"bounds", box(world.bounds)},
              {"walls_note", "one face per wall: [x1, y1, x2, y2] in metres, free space on the left of (x1,y1)->(x2,y2)"},
              {"walls", walls},
              {"rooms", rooms},
              {"tables", tables}});

  json sightings = json::array();
  for (const auto& s : mission.sightings) {
    sightings.push_back({{"utime", s.utime},
                         {"t", fixed(static_cast<double>(s.utime) * 1e-6)},
                         {"observer", s.observer},
                         {"observed", s.observed},
                         {"observer_scan", s.observer_scan},
                         {"observed_scan", s.observed_scan},
                         {"x_AB", pose(s.x_AB)},
                         {"range_m", fixed(s.range_m)}});
  }
  write_json(dir / "sightings.json",
             {{"format", "lmf-sim sightings v1"},
              {"note", "true pose x_AB of the observed robot B in the observer A's frame at utime, the time of scan observer_scan of A and observed_scan of B"},
              {"max_range_m", fixed(c.sightings.max_range_m)},
              {"field_of_view_rad", fixed(c.sightings.field_of_view_rad)},
              {"min_interval_s", fixed(c.sightings.min_interval_s)},
              {"sightings", sightings}});

  write_world_svg(mission, dir / "world.svg");

  write_json(dir / "mission.json",
             {{"format", "lmf-sim mission v1"},
              {"config", config_json(c)},
              {"world", {{"walls", world.walls.size()}, {"rooms", world.rooms.size()}, {"loop_length_m", fixed(world.loop_length_m)}}},
              {"robots", robots},
              {"sightings", mission.sightings.size()},
              {"files", {"walls.json", "sightings.json", "world.svg", "mission.json"}}});
}

}  // namespace lmf::sim
