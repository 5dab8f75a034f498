// Output of the global map: map.json (machine-readable) and map.svg (a drawing).
//
// map.json (format "lmf-map", version 1), all poses in the global frame W,
// metres and radians, poses as [x, y, phi]:
//   counts:   segments, submaps, robots, graph_edges, queued_local_maps, state_dimension
//   segments: id, submap, start [x, y], end [x, y], pose, length_m,
//             covariance 2x2 of (lateral m, angle rad) seen from W
//   submaps:  id, robot, seq, pose, covariance 3x3, segments (count)
//   robots:   id, seq (local map whose origin the frame is), frame (x_WL), covariance 3x3
//   graph:    nodes [submap ids], edges [{a, b, kind: "consecutive" | "paired"}]
//
// map.svg layers: trajectories, 2-sigma bands, environment graph (optional, off
// by default), segments, submap frames, robot frames, legend, scale bar.
#pragma once

#include <filesystem>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "lmf/fusion/global_map.hpp"
#include "lmf/geometry/pose2.hpp"
#include "lmf/io/svg.hpp"

namespace lmf::fusion {

nlohmann::json map_to_json(const GlobalMap& map);

// Writes map_to_json(map) (indented). Throws std::runtime_error if the file
// cannot be written.
void write_map_json(const GlobalMap& map, const std::filesystem::path& file);

// A path to draw with the map, in W (e.g. a robot's corrected or true poses).
struct MapTrajectory {
  std::string label;  // e.g. "robot 1"
  std::vector<Pose2> poses;
  std::string color;  // SVG colour; empty: one per robot from a palette
};

struct MapSvgOptions {
  double pixels_per_metre = 20.0;
  std::string title = "lmf global map";
  bool sigma_bands = true;   // the band_sigmas envelope of each segment's lateral error
  double band_sigmas = 2.0;
  bool graph = false;        // environment graph (nodes at the submap frames); off: it hides the walls
  bool frames = true;        // submap and robot frames
};

io::SvgDocument map_to_svg(const GlobalMap& map, const std::vector<MapTrajectory>& trajectories = {},
                           const MapSvgOptions& options = {});

// Writes map_to_svg(...). Throws std::runtime_error if the file cannot be written.
void write_map_svg(const GlobalMap& map, const std::filesystem::path& file,
                   const std::vector<MapTrajectory>& trajectories = {}, const MapSvgOptions& options = {});

}  // namespace lmf::fusion
