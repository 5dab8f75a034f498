// Disjoint sets over integer ids (union-find), the smallest id of a set being
// its root: merged entities keep the oldest id (ids are never reused, so the
// smallest is the oldest).
//
// find() compresses paths. An id never seen before is a set of its own.
// Not thread-safe; header-only.
#pragma once

#include <algorithm>
#include <map>
#include <unordered_map>
#include <vector>

namespace lmf {

template <typename Id>
class UnionFind {
 public:
  // The root (smallest id) of a's set.
  Id find(Id a) {
    const auto [it, inserted] = parent_.try_emplace(a, a);
    if (inserted) return a;
    Id root = a;
    while (parent_.at(root) != root) root = parent_.at(root);
    while (a != root) {
      Id& parent = parent_.at(a);
      a = parent;
      parent = root;
    }
    return root;
  }

  // Merges the sets of a and b.
  void unite(Id a, Id b) {
    const Id ra = find(a);
    const Id rb = find(b);
    if (ra != rb) parent_[std::max(ra, rb)] = std::min(ra, rb);
  }

  // Every set with its members (roots included), by root. The members of a set
  // come in the hash map's order of the ids: deterministic for one sequence of
  // calls on one standard library, not sorted.
  std::map<Id, std::vector<Id>> sets() {
    std::vector<Id> ids;
    ids.reserve(parent_.size());
    for (const auto& [id, parent] : parent_) ids.push_back(id);
    std::map<Id, std::vector<Id>> out;
    for (const Id id : ids) out[find(id)].push_back(id);
    return out;
  }

 private:
  std::unordered_map<Id, Id> parent_;
};

}  // namespace lmf
