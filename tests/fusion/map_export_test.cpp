// map.json parses and carries the counts and geometry; map.svg is drawn.
#include "lmf/fusion/map_export.hpp"

#include <filesystem>
#include <fstream>
#include <set>
#include <sstream>

#include <unistd.h>

#include <gtest/gtest.h>

#include "fusion/synthetic_maps.hpp"

namespace lmf::fusion {
namespace {

GlobalMap two_rooms_two_robots() {
  GlobalMap map;
  const std::vector<synthetic::Wall> room_a = synthetic::room(0.0, 0.0, 6.0, 4.0);
  const std::vector<synthetic::Wall> room_b = synthetic::room(8.0, 0.0, 6.0, 4.0);
  const Pose2 step(4.0, 0.0, 0.0);
  map.fuse(synthetic::make_snapshot(0, 0, Pose2(), step, room_a));
  std::vector<synthetic::Wall> seen{room_a[1]};
  seen.insert(seen.end(), room_b.begin(), room_b.end());
  map.fuse(synthetic::make_snapshot(0, 1, step, step, seen));
  map.join_robot(1, Pose2(1.0, 1.0, 0.5), Eigen::Vector3d(0.01, 0.01, 0.001).asDiagonal());
  map.fuse(synthetic::make_snapshot(1, 0, Pose2(1.0, 1.0, 0.5), Pose2(0.5, 0.0, 0.0), room_a));
  return map;
}

std::filesystem::path temp_file(const std::string& name) {
  return std::filesystem::temp_directory_path() / ("lmf_fusion_test_" + std::to_string(::getpid()) + "_" + name);
}

TEST(MapExportTest, JsonParsesAndHasTheCounts) {
  const GlobalMap map = two_rooms_two_robots();
  const std::filesystem::path file = temp_file("map.json");
  write_map_json(map, file);
  std::ifstream in(file);
  const nlohmann::json doc = nlohmann::json::parse(in);
  std::filesystem::remove(file);

  EXPECT_EQ(doc.at("format"), "lmf-map");
  const MapCounts c = map.counts();
  EXPECT_EQ(doc.at("counts").at("segments").get<int>(), c.segments);
  EXPECT_EQ(c.segments, 8);
  EXPECT_EQ(doc.at("counts").at("submaps").get<int>(), 2);
  EXPECT_EQ(doc.at("counts").at("robots").get<int>(), 2);
  EXPECT_EQ(doc.at("counts").at("state_dimension").get<long>(), c.state_dimension);
  ASSERT_EQ(doc.at("segments").size(), 8u);
  ASSERT_EQ(doc.at("submaps").size(), 2u);
  ASSERT_EQ(doc.at("robots").size(), 2u);

  std::set<long> submap_ids;
  for (const auto& f : doc.at("submaps")) submap_ids.insert(f.at("id").get<long>());
  for (const auto& s : doc.at("segments")) {
    EXPECT_EQ(submap_ids.count(s.at("submap").get<long>()), 1u);
    ASSERT_EQ(s.at("start").size(), 2u);
    const auto& cov = s.at("covariance");
    ASSERT_EQ(cov.size(), 2u);
    EXPECT_DOUBLE_EQ(cov[0][1].get<double>(), cov[1][0].get<double>());
    EXPECT_GT(cov[0][0].get<double>(), 0.0);
    // Endpoints are length_m apart.
    const double dx = s.at("end")[0].get<double>() - s.at("start")[0].get<double>();
    const double dy = s.at("end")[1].get<double>() - s.at("start")[1].get<double>();
    EXPECT_NEAR(std::hypot(dx, dy), s.at("length_m").get<double>(), 1e-9);
  }
  // Room B's right... the walls are where they were made: the first wall of room A.
  const auto& first = doc.at("segments")[0];
  EXPECT_NEAR(first.at("start")[0].get<double>(), -3.0, 1e-9);
  EXPECT_NEAR(first.at("start")[1].get<double>(), -2.0, 1e-9);
  EXPECT_NEAR(first.at("end")[0].get<double>(), 3.0, 1e-9);

  const auto& graph = doc.at("graph");
  EXPECT_EQ(graph.at("nodes").size(), 2u);
  ASSERT_EQ(graph.at("edges").size(), 1u);
  EXPECT_EQ(graph.at("edges")[0].at("kind"), "consecutive");
  EXPECT_EQ(submap_ids.count(graph.at("edges")[0].at("a").get<long>()), 1u);
  EXPECT_EQ(doc.at("robots")[1].at("id").get<int>(), 1);
  EXPECT_EQ(doc.at("robots")[1].at("seq").get<int>(), 1);
}

TEST(MapExportTest, SvgHasTheLayers) {
  const GlobalMap map = two_rooms_two_robots();
  const std::filesystem::path file = temp_file("map.svg");
  write_map_svg(map, file, {{"robot 0", {Pose2(), Pose2(4.0, 0.0, 0.0), Pose2(8.0, 0.0, 0.0)}, ""}});
  std::ifstream in(file);
  std::stringstream text;
  text << in.rdbuf();
  std::filesystem::remove(file);
  const std::string svg = text.str();
  EXPECT_EQ(svg.rfind("<svg", 0), 0u);
  for (const char* layer : {"segments", "bands", "submaps", "robots", "trajectories", "legend"}) {
    EXPECT_NE(svg.find(std::string("id=\"") + layer + "\""), std::string::npos) << layer;
  }
  // The environment graph is an optional layer, off by default.
  EXPECT_EQ(svg.find("id=\"graph\""), std::string::npos);
  EXPECT_EQ(svg.find("graph edge"), std::string::npos);
  for (const char* row : {"wall segment", "2-sigma lateral band", "robot 0", "submap frame", "robot frame"}) {
    EXPECT_NE(svg.find(row), std::string::npos) << row;
  }
  std::size_t lines = 0;
  for (std::size_t at = svg.find("class=\"segment\""); at != std::string::npos;
       at = svg.find("class=\"segment\"", at + 1)) {
    ++lines;
  }
  EXPECT_EQ(lines, 8u);

  MapSvgOptions with_graph;
  with_graph.graph = true;
  const std::string drawn = map_to_svg(map, {}, with_graph).str();
  EXPECT_NE(drawn.find("id=\"graph\""), std::string::npos);
  EXPECT_NE(drawn.find("graph edge: consecutive"), std::string::npos);
  EXPECT_NE(drawn.find("graph edge: paired"), std::string::npos);
  EXPECT_THROW(write_map_svg(map, "/nonexistent-dir/map.svg"), std::runtime_error);
  EXPECT_THROW(write_map_json(map, "/nonexistent-dir/map.json"), std::runtime_error);
}

}  // namespace
}  // namespace lmf::fusion
