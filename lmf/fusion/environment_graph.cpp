#include "lmf/fusion/environment_graph.hpp"

#include <algorithm>
#include <iterator>
#include <map>

namespace lmf::fusion {

void EnvironmentGraph::connect(const std::set<EntityId>& submaps) {
  for (auto a = submaps.begin(); a != submaps.end(); ++a) {
    for (auto b = std::next(a); b != submaps.end(); ++b) paired_edges_.insert({*a, *b});
  }
}

bool EnvironmentGraph::is_submap(EntityId frame) const {
  return std::any_of(submaps_.begin(), submaps_.end(), [frame](const SubmapRecord& r) { return r.frame == frame; });
}

std::optional<EntityId> EnvironmentGraph::submap_of(int robot_id, std::int64_t seq) const {
  for (const SubmapRecord& r : submaps_) {
    if (r.robot_id == robot_id && r.seq == seq) return r.frame;
  }
  return std::nullopt;
}

std::vector<GraphEdge> EnvironmentGraph::edges() const {
  std::map<std::pair<EntityId, EntityId>, GraphEdge::Kind> edges;
  std::map<int, std::vector<std::pair<std::int64_t, EntityId>>> by_robot;
  for (const SubmapRecord& r : submaps_) by_robot[r.robot_id].emplace_back(r.seq, r.frame);
  for (auto& [robot_id, list] : by_robot) {
    std::sort(list.begin(), list.end());
    for (std::size_t i = 1; i < list.size(); ++i) {
      const EntityId a = std::min(list[i - 1].second, list[i].second);
      const EntityId b = std::max(list[i - 1].second, list[i].second);
      edges[{a, b}] = GraphEdge::Kind::kConsecutive;
    }
  }
  for (const auto& key : paired_edges_) edges.emplace(key, GraphEdge::Kind::kPaired);
  std::vector<GraphEdge> out;
  for (const auto& [key, kind] : edges) out.push_back({key.first, key.second, kind});
  return out;
}

}  // namespace lmf::fusion
