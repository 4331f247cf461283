// The phases of boundary_distance on their own (geodesic_phases.hpp): the bitmaps and nearest
// background points, the buckets, the two breadth-first searches, the considered targets, the search
// over all bases and the threshold.
#include "geodesic/geodesic_phases.hpp"

#include <gtest/gtest.h>

#include <bit>
#include <random>
#include <set>
#include <vector>

using namespace skel;
using namespace skel::geodesic;
using namespace skel::geodesic::detail;

namespace {

// One object voxel at (1,1,1) of 3^3: padded position (3,3,3); L is the 26 voxels around it.
struct SingleVoxel {
  VolumeU8 mask{Dims{3, 3, 3}, 0};
  Prepared P{Dims{3, 3, 3}};
  SingleVoxel() {
    mask(1, 1, 1) = 1;
    prepare(mask, P, 1, {}, true);
  }
  [[nodiscard]] uint32_t lid(int64_t x, int64_t y, int64_t z) const {
    const int64_t pos = P.dom.pos(x, y, z);
    EXPECT_TRUE(P.layer.test(pos));
    return static_cast<uint32_t>(P.layer.rank(pos));
  }
};

}  // namespace

// Ranks from one prefix per 8 words (four popcounts forward or backward in the half group), with
// and without the optional prefix per word, against a plain count; 61 words: the last group is
// padded, and densities from empty to full words.
TEST(GeodesicPhases, RankBitsCountTheSetBitsBeforeEveryPosition) {
  std::mt19937_64 rng(7);
  RankBits rb;
  const size_t n = 61;
  for (size_t w = 0; w < n; ++w) {
    const int kind = static_cast<int>(w % 5);
    const uint64_t r = rng();
    rb.words.push_back(kind == 0 ? 0 : kind == 1 ? ~uint64_t{0} : kind == 2 ? r & rng() & rng() : r);
  }
  const std::vector<uint64_t> bits = rb.words;
  uint64_t total = 0;
  for (uint64_t b : bits) total += static_cast<uint64_t>(std::popcount(b));
  EXPECT_EQ(rb.build_rank(), total);
  EXPECT_EQ(rb.word_count(), n);
  EXPECT_EQ(rb.words.size() % RankBits::kGroup, 0u);
  auto check = [&](const char* what) {
    uint64_t before = 0;
    for (size_t w = 0; w < n; ++w) {
      ASSERT_EQ(rb.prefix(w), before) << what << " word " << w;
      for (int b = 0; b < 64; ++b) {
        const int64_t pos = static_cast<int64_t>(w) * 64 + b;
        ASSERT_EQ(rb.rank(pos), before) << what << " position " << pos;
        ASSERT_EQ(DenseRanks(rb)(pos), before) << what << " position " << pos;
        ASSERT_EQ(rb.test(pos), ((bits[w] >> b) & 1u) != 0) << what << " position " << pos;
        before += (bits[w] >> b) & 1u;
      }
    }
  };
  check("group prefixes");
  const uint64_t group_bytes = rb.bytes();
  rb.build_word_prefixes();
  EXPECT_EQ(rb.bytes(), group_bytes + rb.words.size() * 4);
  check("word prefixes");
  rb.drop_word_prefixes();
  EXPECT_EQ(rb.bytes(), group_bytes);
  check("dropped word prefixes");
}

// The domain's division by the plane and the row (a multiplication by the reciprocal and one
// correction) against / and %, at multiples of the divisor and one either side, up to four times the
// positions of a 10^4 x 10^4 x 10^3 volume, and at random below 2^40.
TEST(GeodesicPhases, DomainCoordinatesEqualIntegerDivision) {
  std::mt19937_64 rng(3);
  for (const Dims& d : {Dims{1, 1, 1}, Dims{60, 7, 5}, Dims{1276, 1280, 1280}, Dims{10000, 10000, 1000}, Dims{3, 65000, 2}}) {
    const Domain D(d);
    std::vector<int64_t> ns;
    for (int64_t k : {int64_t{0}, int64_t{1}, int64_t{2}, D.BZ - 1, D.BZ, 4 * D.BZ})
      for (int64_t e = -1; e <= 1; ++e)
        if (k * D.plane + e >= 0) ns.push_back(k * D.plane + e);
    for (int64_t k : {int64_t{0}, int64_t{1}, D.BY * D.BZ - 1, D.BY * D.BZ, 4 * D.BY * D.BZ})
      for (int64_t e = -1; e <= 1; ++e)
        if (k * D.BX + e >= 0) ns.push_back(k * D.BX + e);
    for (int i = 0; i < 100000; ++i) ns.push_back(static_cast<int64_t>(rng() >> 24));  // below 2^40
    for (const int64_t n : ns) {
      int64_t x = -1, y = -1, z = -1;
      D.coords(n, x, y, z);
      ASSERT_EQ(z, n / D.plane) << n;
      ASSERT_EQ(y, (n % D.plane) / D.BX) << n;
      ASSERT_EQ(x, (n % D.plane) % D.BX) << n;
    }
  }
}

TEST(GeodesicPhases, PrepareFindsTheLayerAndTheNearestBackgroundPoint) {
  const SingleVoxel s;
  const Prepared& P = s.P;
  EXPECT_EQ(P.k, 1);
  EXPECT_EQ(P.nl, 26);
  for (int64_t z = 2; z <= 4; ++z)
    for (int64_t y = 2; y <= 4; ++y)
      for (int64_t x = 2; x <= 4; ++x) {
        const bool centre = x == 3 && y == 3 && z == 3;
        EXPECT_EQ(P.obj.test(P.dom.pos(x, y, z)), centre);
        EXPECT_EQ(P.layer.test(P.dom.pos(x, y, z)), !centre);
      }
  // Six face neighbours at distance 1; the tie goes to the lowest L-id, i.e. (3,3,2) (z - 1).
  ASSERT_EQ(P.b.size(), 1u);
  EXPECT_EQ(P.b[0], s.lid(3, 3, 2));
  EXPECT_EQ(P.lcoord[P.b[0]].x, 3);
  EXPECT_EQ(P.lcoord[P.b[0]].y, 3);
  EXPECT_EQ(P.lcoord[P.b[0]].z, 2);
  // The shell is one 6-component.
  for (uint32_t c : P.lcomp) EXPECT_EQ(c, P.lcomp[0]);
}

TEST(GeodesicPhases, PrepareSeparatesLayerComponentsAndFollowsRings) {
  // Two separate objects: a voxel and a 5x5x5 cube, whose centre lies three rings deep.
  VolumeU8 mask(Dims{12, 7, 7}, 0);
  mask(1, 3, 3) = 1;
  for (int z = 1; z <= 5; ++z)
    for (int y = 1; y <= 5; ++y)
      for (int x = 5; x <= 9; ++x) mask(x, y, z) = 1;
  Prepared P(mask.dims());
  prepare(mask, P, 2, {}, true);
  EXPECT_EQ(P.k, 126);
  const uint32_t c0 = P.lcomp[P.b[P.obj.rank(P.dom.pos(3, 5, 5))]];
  const uint32_t c1 = P.lcomp[P.b[P.obj.rank(P.dom.pos(9, 5, 5))]];
  EXPECT_NE(c0, c1);
  EXPECT_EQ(std::set<uint32_t>(P.lcomp.begin(), P.lcomp.end()).size(), 2u);
  // The cube's centre (7,3,3) -> padded (9,5,5): nearest background points at distance 3; the lowest
  // L-id among them is (9,5,2).
  const uint32_t b = P.b[P.obj.rank(P.dom.pos(9, 5, 5))];
  EXPECT_EQ(P.lpos(b), P.dom.pos(9, 5, 2));
  // Every object voxel has a base.
  for (uint32_t l : P.b) EXPECT_LT(l, static_cast<uint32_t>(P.nl));
}

TEST(GeodesicPhases, LayerIsTheDilatedObjectMinusTheObject) {
  // Brute force over the padded domain: L = background voxels 26-adjacent to the object, including
  // the one-voxel ring outside the array; the guard ring stays empty.
  std::mt19937 rng(7);
  VolumeU8 mask(Dims{13, 6, 5}, 0);
  for (int64_t i = 0; i < mask.size(); ++i) mask[i] = rng() % 4 == 0;
  Prepared P(mask.dims());
  build_bitmaps(mask, P, 2, {});
  const Domain& D = P.dom;
  auto object = [&](int64_t x, int64_t y, int64_t z) {  // padded coordinates
    return x >= 2 && y >= 2 && z >= 2 && x < D.nx + 2 && y < D.ny + 2 && z < D.nz + 2 && mask(x - 2, y - 2, z - 2);
  };
  int64_t k = 0, nl = 0;
  for (int64_t z = 0; z < D.BZ; ++z)
    for (int64_t y = 0; y < D.BY; ++y)
      for (int64_t x = 0; x < D.BX; ++x) {
        bool near = false;
        for (int dz = -1; dz <= 1; ++dz)
          for (int dy = -1; dy <= 1; ++dy)
            for (int dx = -1; dx <= 1; ++dx) near = near || object(x + dx, y + dy, z + dz);
        const bool o = object(x, y, z), l = near && !o;
        ASSERT_EQ(P.obj.test(D.pos(x, y, z)), o) << x << "," << y << "," << z;
        ASSERT_EQ(P.layer.test(D.pos(x, y, z)), l) << x << "," << y << "," << z;
        if (o) {
          EXPECT_EQ(P.obj.rank(D.pos(x, y, z)), static_cast<uint64_t>(k));
        }
        if (l) {
          EXPECT_EQ(P.layer.rank(D.pos(x, y, z)), static_cast<uint64_t>(nl));
        }
        k += o;
        nl += l;
      }
  EXPECT_EQ(P.k, k);
  EXPECT_EQ(P.nl, nl);
  layer_coordinates(P, 2);
  for (int64_t l = 0; l < P.nl; ++l) EXPECT_TRUE(P.layer.test(P.lpos(static_cast<uint32_t>(l))));
}

TEST(GeodesicPhases, LayerComponentsAreLabelledByTheirSmallestId) {
  // Two voxels far apart: two shells of 26 L voxels, their ids interleaved in raster order.
  VolumeU8 mask(Dims{9, 3, 3}, 0);
  mask(1, 1, 1) = mask(7, 1, 1) = 1;
  Prepared P(mask.dims());
  build_bitmaps(mask, P, 1, {});
  layer_components(P);
  ASSERT_EQ(P.nl, 52);
  const uint32_t left = P.lcomp[P.layer.rank(P.dom.pos(2, 2, 2))];
  const uint32_t right = P.lcomp[P.layer.rank(P.dom.pos(10, 4, 4))];
  EXPECT_EQ(left, 0u);  // (2,2,2) is the first L voxel
  EXPECT_NE(left, right);
  for (int64_t l = 0; l < P.nl; ++l) {
    EXPECT_LE(P.lcomp[static_cast<size_t>(l)], static_cast<uint32_t>(l));
    EXPECT_TRUE(P.lcomp[static_cast<size_t>(l)] == left || P.lcomp[static_cast<size_t>(l)] == right);
  }
  EXPECT_EQ(right, P.layer.rank(P.dom.pos(8, 2, 2)));  // the right shell's first voxel in raster order
}

TEST(GeodesicPhases, BucketsGroupObjectVoxelsByBaseInRasterOrder) {
  std::mt19937 rng(3);
  VolumeU8 mask(Dims{10, 9, 8}, 0);
  for (int64_t i = 0; i < mask.size(); ++i) mask[i] = rng() % 3 != 0;
  Prepared P(mask.dims());
  prepare(mask, P, 2, {}, false);
  const Buckets B = bucket_by_base(P);
  ASSERT_EQ(B.count.size(), static_cast<size_t>(P.nl));
  EXPECT_EQ(B.end(static_cast<uint32_t>(P.nl) - 1), static_cast<uint32_t>(P.k));
  std::vector<std::vector<int64_t>> expect(static_cast<size_t>(P.nl));
  std::vector<int64_t> lpos;  // L-id -> padded position
  for (int64_t pos = 0; pos < P.dom.bits(); ++pos) {
    if (P.obj.test(pos)) expect[P.base_of(pos)].push_back(pos);  // b is kept only as offsets here
    if (P.layer.test(pos)) lpos.push_back(pos);
  }
  for (int64_t l = 0; l < P.nl; ++l) {
    std::vector<int64_t> got;
    for (uint32_t m = B.begin(static_cast<uint32_t>(l)); m < B.end(static_cast<uint32_t>(l)); ++m)
      got.push_back(B.member(m, lpos[static_cast<size_t>(l)]));
    EXPECT_EQ(got, expect[static_cast<size_t>(l)]) << l;
    EXPECT_EQ(B.has_work(static_cast<uint32_t>(l)), !got.empty());
  }
}

// bucket_by_base works in chunks of base planes (a few per thread, each walking the object voxels
// within reach of its bases): the buckets are the same for any thread count, in raster order.
TEST(GeodesicPhases, BucketsAreTheSameForAnyThreadCount) {
  std::mt19937 rng(5);
  VolumeU8 mask(Dims{14, 11, 96}, 0);
  for (int64_t i = 0; i < mask.size(); ++i) mask[i] = rng() % 3 != 0;
  for (int64_t z = 30; z < 42; ++z)  // a solid part: members up to 6 planes from their base
    for (int64_t y = 0; y < 11; ++y)
      for (int64_t x = 0; x < 14; ++x) mask(x, y, z) = 1;
  Prepared P(mask.dims());
  prepare(mask, P, 2, {}, true);
  const Buckets B1 = bucket_by_base(P, 1);
  std::vector<std::vector<int64_t>> expect(static_cast<size_t>(P.nl));
  for (int64_t pos = 0; pos < P.dom.bits(); ++pos)
    if (P.obj.test(pos)) expect[P.b[P.obj.rank(pos)]].push_back(pos);
  for (int threads : {2, 3, 4, 8}) {
    const Buckets B = bucket_by_base(P, threads);
    ASSERT_EQ(B.count, B1.count) << threads;
    ASSERT_EQ(B.big, B1.big) << threads;
    ASSERT_EQ(B.block, B1.block) << threads;
    for (int64_t l = 0; l < P.nl; ++l) {
      std::vector<int64_t> got;
      for (uint32_t m = B.begin(static_cast<uint32_t>(l)); m < B.end(static_cast<uint32_t>(l)); ++m)
        got.push_back(B.member(m, P.lpos(static_cast<uint32_t>(l))));
      ASSERT_EQ(got, expect[static_cast<size_t>(l)]) << "threads " << threads << ", L-id " << l;
    }
  }
}

TEST(GeodesicPhases, TargetsAreTheLowerNeighboursAndTheBackgroundUpperOnes) {
  const SingleVoxel s;
  std::vector<uint32_t> t;
  for_each_target(s.P, s.P.dom.pos(3, 3, 3), [&](uint32_t c) { t.push_back(c); });
  EXPECT_EQ(t, (std::vector<uint32_t>{s.lid(2, 3, 3), s.lid(4, 3, 3), s.lid(3, 2, 3), s.lid(3, 4, 3), s.lid(3, 3, 2),
                                      s.lid(3, 3, 4)}));
  // An object upper neighbour is skipped; an object lower neighbour gives its base.
  VolumeU8 mask(Dims{4, 3, 3}, 0);
  mask(1, 1, 1) = mask(2, 1, 1) = 1;
  Prepared P(mask.dims());
  prepare(mask, P, 1, {}, true);
  std::vector<uint32_t> a, b;
  for_each_target(P, P.dom.pos(3, 3, 3), [&](uint32_t c) { a.push_back(c); });
  for_each_target(P, P.dom.pos(4, 3, 3), [&](uint32_t c) { b.push_back(c); });
  EXPECT_EQ(a.size(), 5u);
  ASSERT_EQ(b.size(), 6u);
  EXPECT_EQ(b[0], P.b[P.obj.rank(P.dom.pos(3, 3, 3))]);
}

TEST(GeodesicPhases, OwnSearchMeasuresSixPathsInTheLayer) {
  const SingleVoxel s;
  Scratch S(static_cast<size_t>(s.P.nl), 0);
  const uint32_t src = s.lid(3, 3, 2);
  const std::vector<uint32_t> want = {s.lid(3, 3, 4), s.lid(2, 3, 2), s.lid(2, 3, 3)};
  const std::vector<int64_t> want_pos = {s.P.dom.pos(3, 3, 4), s.P.dom.pos(2, 3, 2), s.P.dom.pos(2, 3, 3)};
  std::vector<uint32_t> wd;
  // Around the voxel to the opposite side: 4 steps; a neighbour: 1; an edge-adjacent voxel: 2.
  const int64_t visited = own_bfs(s.P, S, src, s.P.dom.pos(3, 3, 2), 100, want, want_pos, wd);
  EXPECT_EQ(wd, (std::vector<uint32_t>{4, 1, 2}));
  // A* closes only voxels on shortest paths towards the targets: at most the 26 of L, at least the
  // 5 of one shortest path to the far side.
  EXPECT_GE(visited, 5);
  EXPECT_LE(visited, 26);
  // Range encoding: the closed voxels carry this search's stamp, nothing else does, and nothing is
  // cleared; the next search takes the next stamp, so these marks mean "open" to it.
  const uint16_t st = S.cur;
  int64_t stamped = 0;
  for (uint16_t m : S.stamp) {
    EXPECT_TRUE(m == 0 || m == st);
    stamped += m == st;
  }
  EXPECT_EQ(stamped, visited);
  for (const auto& b : S.buckets) EXPECT_TRUE(b.empty());  // the queue is left empty
  // With limit 3 the opposite side is not reached (and the search stops at key 3).
  own_bfs(s.P, S, src, s.P.dom.pos(3, 3, 2), 3, want, want_pos, wd);
  EXPECT_EQ(wd, (std::vector<uint32_t>{kNone, 1, 2}));
  EXPECT_EQ(S.cur, st + 1);
  // Limit exactly the distance: reached.
  own_bfs(s.P, S, src, s.P.dom.pos(3, 3, 2), 4, want, want_pos, wd);
  EXPECT_EQ(wd, (std::vector<uint32_t>{4, 1, 2}));
}

namespace {
// A 40 x 40 x 4 slab of object (z = 4..7) in a 40 x 40 x 12 volume.
VolumeU8 slab_40x40x4() {
  VolumeU8 m(Dims{40, 40, 12}, 0);
  for (int64_t z = 4; z < 8; ++z)
    for (int64_t y = 0; y < 40; ++y)
      for (int64_t x = 0; x < 40; ++x) m(x, y, z) = 1;
  return m;
}
}  // namespace

TEST(GeodesicPhases, OwnSearchGoesStraightAlongAFlatSurface) {
  // A 40 x 40 x 4 slab: from a voxel of L above the slab to one 15 steps away in x, also above it.
  // A* closes the 16 voxels of the straight path and nothing else (a breadth-first search would
  // close the ~2 * 15^2 voxels within 15 steps); across the slab (around the rim) the distance is
  // long, and with limit 20 the search proves "> 20" without closing more than the keys <= 20 allow.
  const VolumeU8 m = slab_40x40x4();
  Prepared P(m.dims());
  prepare(m, P, 1, {}, false);
  Scratch S(static_cast<size_t>(P.nl), 0);
  const int64_t src = P.dom.pos(10 + 2, 20 + 2, 8 + 2), far = P.dom.pos(25 + 2, 20 + 2, 8 + 2);
  const int64_t below = P.dom.pos(10 + 2, 20 + 2, 3 + 2);  // under the slab: around the rim, > 20
  ASSERT_TRUE(P.layer.test(src) && P.layer.test(far) && P.layer.test(below));
  const uint32_t sid = static_cast<uint32_t>(P.layer.rank(src));
  std::vector<uint32_t> wd;
  EXPECT_EQ(own_bfs(P, S, sid, src, 100, {static_cast<uint32_t>(P.layer.rank(far))}, {far}, wd), 16);
  EXPECT_EQ(wd, (std::vector<uint32_t>{15}));
  const int64_t v = own_bfs(P, S, sid, src, 20, {static_cast<uint32_t>(P.layer.rank(below))}, {below}, wd);
  EXPECT_EQ(wd, (std::vector<uint32_t>{kNone}));
  // Keys g + h <= 20 with h >= 5 (the slab is 4 thick): g <= 15 on the top face, a diamond of
  // 2 * 15^2 + 2 * 15 + 1 = 481 voxels at most near x = 10 (the rims are 10 and more away).
  EXPECT_GT(v, 0);
  EXPECT_LE(v, 481);
}

// Queued-g marks (threshold mode: a scratch with pivot distances): on a flat surface every voxel
// between the source and a diagonal target is reached from two neighbours on paths of the same
// length; it is queued once (the second path is not shorter), and the distance is the same as
// without the marks.
TEST(GeodesicPhases, OwnSearchQueuesAVoxelAgainOnlyOnAShorterPath) {
  const VolumeU8 m = slab_40x40x4();
  Prepared P(m.dims());
  prepare(m, P, 1, {}, false);
  const int64_t src = P.dom.pos(10 + 2, 10 + 2, 8 + 2), far = P.dom.pos(22 + 2, 19 + 2, 8 + 2);
  const uint32_t sid = static_cast<uint32_t>(P.layer.rank(src));
  const std::vector<uint32_t> want = {static_cast<uint32_t>(P.layer.rank(far))};
  std::vector<uint32_t> wd, wd_plain;
  Scratch plain(static_cast<size_t>(P.nl), 0);  // no pivot distances: no marks
  Scratch S(static_cast<size_t>(P.nl), 50);
  ASSERT_EQ(S.queued.size(), S.stamp.size());
  ASSERT_TRUE(plain.queued.empty());
  own_bfs(P, plain, sid, src, 40, want, {far}, wd_plain);
  own_bfs(P, S, sid, src, 40, want, {far}, wd);
  EXPECT_EQ(wd_plain, (std::vector<uint32_t>{21}));
  EXPECT_EQ(wd, wd_plain);
  int64_t distinct = 0;
  for (uint32_t q : S.queued) distinct += (q >> 16) == S.cur;
  EXPECT_GT(distinct, 21);
  EXPECT_EQ(S.last_queued, distinct);                 // each voxel queued once
  EXPECT_GT(plain.last_queued, S.last_queued);        // without the marks: twice on equal paths
}

TEST(GeodesicPhases, OwnSearchStampWrapsByClearingOnce) {
  const SingleVoxel s;
  Scratch S(static_cast<size_t>(s.P.nl), 0);
  const uint32_t src = s.lid(3, 3, 2);
  const std::vector<uint32_t> want = {s.lid(3, 3, 4)};
  const std::vector<int64_t> want_pos = {s.P.dom.pos(3, 3, 4)};
  std::vector<uint32_t> wd;
  S.cur = 0xFFFE;  // the second search wraps
  for (int i = 0; i < 3; ++i) {
    own_bfs(s.P, S, src, s.P.dom.pos(3, 3, 2), 100, want, want_pos, wd);
    EXPECT_EQ(wd, (std::vector<uint32_t>{4}));  // stale stamps of the search before never count
  }
  EXPECT_EQ(S.stamp_resets, 1);
  EXPECT_EQ(S.cur, 2);  // 0xFFFF, wrap to 1, 2
}

TEST(GeodesicPhases, PivotSearchKeepsDistancesInOrder) {
  const SingleVoxel s;
  Scratch S(static_cast<size_t>(s.P.nl), 10);
  const uint32_t src = s.lid(3, 3, 2);
  const int64_t visited = pivot_bfs(s.P, S, src, s.P.dom.pos(3, 3, 2), 2);
  EXPECT_EQ(visited, static_cast<int64_t>(S.pqueue.size()));
  ASSERT_FALSE(S.pqueue.empty());
  EXPECT_EQ(S.pqueue.front(), src);
  EXPECT_EQ(S.pivot_at(src), 0u);
  EXPECT_EQ(S.pivot_at(s.lid(2, 3, 2)), 1u);
  EXPECT_EQ(S.pivot_at(s.lid(2, 3, 3)), 2u);
  EXPECT_FALSE(S.pivot_visited(s.lid(3, 3, 4)));  // 4 > limit
  for (size_t i = 1; i < S.pqueue.size(); ++i) EXPECT_LE(S.pivot_at(S.pqueue[i - 1]), S.pivot_at(S.pqueue[i]));
  for (uint32_t v : S.pqueue) EXPECT_LE(S.pivot_at(v), 2u);
  // A second search resets the first one's distances.
  pivot_bfs(s.P, S, s.lid(3, 3, 4), s.P.dom.pos(3, 3, 4), 0);
  EXPECT_EQ(S.pqueue.size(), 1u);
  EXPECT_FALSE(S.pivot_visited(src));
}

TEST(GeodesicPhases, SearchOverAllBasesAndThreshold) {
  // The single voxel's importance: max over its targets of g(b, target) = 4 (the opposite side).
  for (uint32_t t : {20u, 3u}) {
    const SingleVoxel s;
    const Buckets B = bucket_by_base(s.P);
    VolumeF32 imp(s.mask.grid(), 0.0f);
    SearchShared sh(s.P, B, s.mask, imp.data(), t, false);
    EXPECT_EQ(sh.pivot_margin, std::max<uint32_t>(2, t / 4));
    search_bases(sh, 2, {});
    EXPECT_EQ(sh.n_bases.load(), 1);
    EXPECT_EQ(sh.done_bases.load(), 1);
    EXPECT_EQ(imp(1, 1, 1), static_cast<float>(std::min<uint32_t>(4, t)));
    EXPECT_EQ(imp(0, 0, 0), 0.0f);
    VolumeU8 skel(s.mask.grid(), 7);
    threshold_surface(imp, skel, t, 2);
    for (int64_t i = 0; i < skel.size(); ++i) EXPECT_EQ(skel[i], i == s.mask.index(1, 1, 1) && t <= 4 ? 1 : 0);
  }
}

namespace {

// Random blob-like objects: uniform noise, then a 6-neighbourhood majority pass.
VolumeU8 blobs(Dims d, uint64_t seed, double fill) {
  std::mt19937_64 rng(seed);
  std::uniform_real_distribution<double> u(0, 1);
  VolumeU8 v(d, 0), s(d, 0);
  for (auto& x : v) x = u(rng) < fill ? 1 : 0;
  for (int64_t z = 0; z < d[2]; ++z)
    for (int64_t y = 0; y < d[1]; ++y)
      for (int64_t x = 0; x < d[0]; ++x) {
        const int c = v(x, y, z) + v.at_or(x - 1, y, z, 0) + v.at_or(x + 1, y, z, 0) + v.at_or(x, y - 1, z, 0) +
                      v.at_or(x, y + 1, z, 0) + v.at_or(x, y, z - 1, 0) + v.at_or(x, y, z + 1, 0);
        s(x, y, z) = c >= 4 ? 1 : 0;
      }
  return s;
}

struct SearchRun {
  VolumeF32 importance;
  int64_t searches, pivots, saturated, visited, landmarks, long_searches;
};

// landmark_min_visited: -1 = the default policy, 0 = a landmark field after every own search.
SearchRun run_search(const VolumeU8& mask, uint32_t t, int threads, bool force_box, bool landmarks = false,
                     int64_t landmark_min_visited = -1) {
  Prepared P(mask.dims());
  prepare(mask, P, threads, {}, false, false);
  const Buckets B = bucket_by_base(P);
  SearchRun r{VolumeF32(mask.grid(), 0.0f), 0, 0, 0, 0, 0, 0};
  SearchShared sh(P, B, mask, r.importance.data(), t, false);
  sh.force_box = force_box;
  sh.landmarks = landmarks;
  sh.landmark_min_visited = landmark_min_visited;
  search_bases(sh, threads, {});
  r.searches = sh.n_search.load();
  r.pivots = sh.n_pivots.load();
  r.saturated = sh.n_saturated.load();
  r.visited = sh.n_visited.load();
  r.landmarks = sh.n_landmarks.load();
  r.long_searches = sh.n_long.load();
  return r;
}

}  // namespace

// The block-local scratch (a box that moves from block to block, indexed by position) gives the
// same importance as the dense scratch (indexed by L-id) and as the definition, and the same
// counts, for 1 and 2 threads. 66 voxels in x make two 64-voxel x-blocks, so the box moves along
// every axis and is clipped at the domain's faces.
TEST(GeodesicPhases, BoxScratchEqualsDenseScratchAndReference) {
  for (uint64_t seed : {5u, 6u}) {
    const VolumeU8 m = blobs(Dims{66, 14, 12 + static_cast<int64_t>(seed)}, seed, 0.5);
    for (uint32_t t : {4u, 9u}) {
      // The definition (slow: a BFS over L per voxel) once; dense equals it on all of
      // Geodesic.EqualsReferenceOnRandomObjects.
      Options o;
      o.threshold = t;
      const bool with_ref = seed == 5 && t == 9;
      const Result ref = with_ref ? boundary_distance_reference(m, o) : Result{};
      const SearchRun dense = run_search(m, t, 1, false);
      EXPECT_GT(dense.pivots, 0);
      for (int threads : {1, 2}) {
        const SearchRun box = run_search(m, t, threads, true);
        SCOPED_TRACE("seed " + std::to_string(seed) + " t " + std::to_string(t) + " threads " + std::to_string(threads));
        if (with_ref) {
          EXPECT_TRUE(box.importance == ref.importance);
        }
        EXPECT_TRUE(box.importance == dense.importance);
        EXPECT_EQ(box.searches, dense.searches);
        EXPECT_EQ(box.pivots, dense.pivots);
        EXPECT_EQ(box.saturated, dense.saturated);
        EXPECT_EQ(box.visited, dense.visited);
      }
    }
  }
}

// Landmark fields (the ALT heuristic of the own searches) change only how many voxels the A*
// closes: the importance equals that of the plain A* (and the definition), the searches, pivots,
// long searches and saturations are the same, with the dense and the box scratch, for 1 and 2
// threads, and the counts (landmarks and visited included) do not depend on the thread count.
// Stress policy (a field after every own search) and the default one.
TEST(GeodesicPhases, LandmarkSearchesEqualPlainAStar) {
  int64_t fields = 0;
  for (uint64_t seed : {5u, 7u}) {
    const VolumeU8 m = blobs(Dims{66, 20, 14 + static_cast<int64_t>(seed)}, seed, 0.52);
    for (uint32_t t : {4u, 9u, 20u}) {
      const SearchRun plain = run_search(m, t, 1, false);
      Options o;
      o.threshold = t;
      if (seed == 5 && t == 9) {
        o.landmarks = true;
        EXPECT_TRUE(plain.importance == boundary_distance_reference(m, o).importance);
      }
      for (int64_t lm_min : {int64_t{0}, int64_t{-1}}) {
        for (bool box : {false, true}) {
          SearchRun first{};
          for (int threads : {1, 2}) {
            const SearchRun r = run_search(m, t, threads, box, true, lm_min);
            SCOPED_TRACE("seed " + std::to_string(seed) + " t " + std::to_string(t) + " min " + std::to_string(lm_min) +
                         " box " + std::to_string(box) + " threads " + std::to_string(threads));
            EXPECT_TRUE(r.importance == plain.importance);
            EXPECT_EQ(r.searches, plain.searches);
            EXPECT_EQ(r.pivots, plain.pivots);
            EXPECT_EQ(r.long_searches, plain.long_searches);
            EXPECT_EQ(r.saturated, plain.saturated);
            if (threads == 1) {
              first = r;
              if (lm_min == 0) {
                EXPECT_GT(r.landmarks, 0);
                fields += r.landmarks;
              }
            } else {
              EXPECT_EQ(r.landmarks, first.landmarks);
              EXPECT_EQ(r.visited, first.visited);
            }
          }
        }
      }
    }
  }
  EXPECT_GT(fields, 100);
}

// Buckets of 255 members and more (their count is kept aside): a solid cube with one background
// voxel in its centre, which is the nearest background point of the ~900 voxels around it.
TEST(GeodesicPhases, BucketsWithManyMembers) {
  VolumeU8 mask(Dims{25, 25, 25}, 1);
  mask(12, 12, 12) = 0;
  Prepared P(mask.dims());
  prepare(mask, P, 2, {}, true);
  const Buckets B = bucket_by_base(P);
  ASSERT_FALSE(B.big.empty());
  const uint32_t cavity = static_cast<uint32_t>(P.layer.rank(P.dom.pos(14, 14, 14)));
  EXPECT_GE(B.members_of(cavity), 255u);
  std::vector<std::vector<int64_t>> expect(static_cast<size_t>(P.nl));
  for (int64_t pos = 0; pos < P.dom.bits(); ++pos)
    if (P.obj.test(pos)) expect[P.b[P.obj.rank(pos)]].push_back(pos);
  for (int64_t l = 0; l < P.nl; ++l) {
    std::vector<int64_t> got;
    for (uint32_t m = B.begin(static_cast<uint32_t>(l)); m < B.end(static_cast<uint32_t>(l)); ++m) got.push_back(B.member(m, P.lpos(static_cast<uint32_t>(l))));
    ASSERT_EQ(got, expect[static_cast<size_t>(l)]) << l;
  }
  EXPECT_EQ(B.end(static_cast<uint32_t>(P.nl) - 1), static_cast<uint32_t>(P.k));
  Options o;
  o.threshold = 6;
  EXPECT_TRUE(boundary_distance(mask, o).importance == boundary_distance_reference(mask, o).importance);
}

// Offsets beyond +-127 arise only deep inside objects more than 254 voxels thick all round: in a
// solid 261³ cube the voxels of the central column below the centre have their nearest background
// point on the face z = -1 straight below (131 steps from the centre: through the side table while
// the rings run), and the ones nearer another face are not affected.
TEST(GeodesicPhases, FarNearestPointsFromTheRings) {
  const int64_t n = 261, c = 130;
  VolumeU8 mask(Dims{n, n, n}, 1);
  Prepared P(mask.dims());
  prepare(mask, P, 2, {}, false, false);
  EXPECT_FALSE(P.bfar.empty());
  for (int64_t z = 0; z <= c; ++z)
    ASSERT_EQ(P.base_pos(P.dom.pos(c + 2, c + 2, z + 2)), P.dom.pos(c + 2, c + 2, 1)) << z;
  // Near the face x = 0, the base is straight across that face (an 8-bit offset).
  EXPECT_EQ(P.base_pos(P.dom.pos(5 + 2, c + 2, c + 2)), P.dom.pos(1, c + 2, c + 2));
}
