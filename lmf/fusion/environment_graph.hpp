// The environment graph (docs/design.md §5 step 7): the submap frames F_i are its
// nodes; an edge joins consecutive submaps of one robot (by local map number)
// and every pair of submaps whose segments were paired in one fusion.
//
// Holds the submaps (which local map each frame was made from) and the paired
// edges; the consecutive edges follow from the submaps. Not thread-safe.
#pragma once

#include <cstdint>
#include <optional>
#include <set>
#include <utility>
#include <vector>

#include "lmf/spmap/entity.hpp"

namespace lmf::fusion {

using spmap::EntityId;

struct GraphEdge {
  enum class Kind { kConsecutive, kPaired };
  EntityId a = 0;  // submap frames, a < b
  EntityId b = 0;
  Kind kind = Kind::kPaired;
};

// A submap frame and the local map (robot, seq) it was made from.
struct SubmapRecord {
  EntityId frame = 0;
  int robot_id = 0;
  std::int64_t seq = 0;
};

class EnvironmentGraph {
 public:
  // A new node, in the order submaps are made.
  void add_submap(EntityId frame, int robot_id, std::int64_t seq) { submaps_.push_back({frame, robot_id, seq}); }
  // Edges between every two of `submaps` (the submaps one fusion touched).
  void connect(const std::set<EntityId>& submaps);

  bool is_submap(EntityId frame) const;
  // The frame of the submap made from local map `seq` of the robot, if any.
  std::optional<EntityId> submap_of(int robot_id, std::int64_t seq) const;
  const std::vector<SubmapRecord>& submaps() const { return submaps_; }
  // Consecutive and paired edges, each pair once (consecutive wins), by (a, b).
  std::vector<GraphEdge> edges() const;

 private:
  friend class GlobalMapArchive;  // global_map_archive.cpp: exact save/restore
  std::vector<SubmapRecord> submaps_;
  std::set<std::pair<EntityId, EntityId>> paired_edges_;  // (a, b), a < b
};

}  // namespace lmf::fusion
