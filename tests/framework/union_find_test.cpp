// skel::UnionFind: sets, the smallest-id root rule (roots do not depend on the order of unions) and
// parent(i) <= i, which lets callers resolve every id by one forward pass.
#include <gtest/gtest.h>

#include <algorithm>
#include <cstdint>
#include <random>
#include <utility>
#include <vector>

#include "skel/union_find.hpp"

using skel::UnionFind;

TEST(UnionFind, SingletonsThenUnions) {
  UnionFind uf(6);
  EXPECT_EQ(uf.size(), 6);
  for (int64_t i = 0; i < 6; ++i) EXPECT_EQ(uf.find(i), i);
  EXPECT_TRUE(uf.unite(4, 2));
  EXPECT_TRUE(uf.unite(5, 4));
  EXPECT_FALSE(uf.unite(2, 5));  // already one set
  EXPECT_TRUE(uf.unite(3, 1));
  EXPECT_EQ(uf.find(5), 2);  // the smallest id is the root
  EXPECT_EQ(uf.find(4), 2);
  EXPECT_EQ(uf.find(3), 1);
  EXPECT_EQ(uf.find(0), 0);
  EXPECT_TRUE(uf.unite(5, 3));
  for (int64_t i : {1, 2, 3, 4, 5}) EXPECT_EQ(uf.find(i), 1);
  EXPECT_EQ(UnionFind().size(), 0);
}

TEST(UnionFind, RootsIndependentOfUnionOrderAndFlattenResolves) {
  const int64_t n = 2000;
  std::mt19937_64 rng(7);
  std::vector<std::pair<int64_t, int64_t>> pairs;
  for (int k = 0; k < 1500; ++k)
    pairs.emplace_back(static_cast<int64_t>(rng() % n), static_cast<int64_t>(rng() % n));
  // Reference: label propagation to the minimum id over the pairs until stable.
  std::vector<int64_t> ref(n);
  for (int64_t i = 0; i < n; ++i) ref[i] = i;
  for (bool changed = true; changed;) {
    changed = false;
    for (const auto& [a, b] : pairs) {
      const int64_t m = std::min(ref[a], ref[b]);
      if (ref[a] != m || ref[b] != m) changed = true;
      ref[a] = ref[b] = m;
    }
  }
  for (int round = 0; round < 3; ++round) {
    UnionFind uf(n);
    for (const auto& [a, b] : pairs) uf.unite(a, b);
    for (int64_t i = 0; i < n; ++i) {
      EXPECT_LE(uf.parents()[i], i);
      ASSERT_EQ(uf.find(i), ref[i]) << "id " << i << " round " << round;
    }
    uf.flatten();
    for (int64_t i = 0; i < n; ++i) ASSERT_EQ(uf.parents()[i], ref[i]);
    const std::vector<int64_t> roots = std::move(uf).release();
    EXPECT_EQ(static_cast<int64_t>(roots.size()), n);
    std::shuffle(pairs.begin(), pairs.end(), rng);
    for (auto& p : pairs)
      if (rng() & 1) std::swap(p.first, p.second);
  }
}

TEST(UnionFind, ForwardPassWithoutFlatten) {
  // A chain united from the far end: long paths before any find, still parent(i) <= i.
  const int64_t n = 100000;
  UnionFind uf(n);
  for (int64_t i = n - 1; i > 0; --i) uf.unite(i, i - 1);
  std::vector<int64_t> p = std::move(uf).release();
  for (int64_t i = 0; i < n; ++i) p[i] = p[p[i]];
  for (int64_t i = 0; i < n; ++i) ASSERT_EQ(p[i], 0);
}
