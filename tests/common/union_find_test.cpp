#include "lmf/common/union_find.hpp"

#include <algorithm>
#include <cstdint>
#include <map>
#include <vector>

#include <gtest/gtest.h>

namespace {

using lmf::UnionFind;

TEST(UnionFind, AnUnseenIdIsItsOwnSet) {
  UnionFind<std::int64_t> sets;
  EXPECT_EQ(sets.find(7), 7);
  EXPECT_EQ(sets.find(7), 7);
  EXPECT_EQ(sets.sets(), (std::map<std::int64_t, std::vector<std::int64_t>>{{7, {7}}}));
}

TEST(UnionFind, TheSmallestIdIsTheRootWhateverTheOrderOfUnions) {
  UnionFind<std::int64_t> sets;
  sets.unite(9, 5);
  sets.unite(12, 9);
  sets.unite(3, 40);
  EXPECT_EQ(sets.find(12), 5);
  EXPECT_EQ(sets.find(9), 5);
  EXPECT_EQ(sets.find(40), 3);
  sets.unite(40, 12);  // joins the two sets through non-roots
  for (const std::int64_t id : {3, 5, 9, 12, 40}) EXPECT_EQ(sets.find(id), 3) << id;
  const auto all = sets.sets();
  ASSERT_EQ(all.size(), 1u);
  std::vector<std::int64_t> members = all.at(3);
  std::sort(members.begin(), members.end());
  EXPECT_EQ(members, (std::vector<std::int64_t>{3, 5, 9, 12, 40}));
}

TEST(UnionFind, SeparateSetsStaySeparate) {
  UnionFind<int> sets;
  sets.unite(1, 2);
  sets.unite(3, 4);
  sets.unite(2, 2);
  EXPECT_NE(sets.find(1), sets.find(3));
  EXPECT_EQ(sets.sets().size(), 2u);
}

}  // namespace
