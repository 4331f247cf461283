// The phases of thin_doht on their own (thinning_phases.hpp): level ranking, the initial scan and
// queue, the smooth variant's check / direction choice / recheck, end-point importance, the basic
// loop and the statistics after thinning.
#include "thinning/thinning_phases.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <limits>
#include <vector>

#include "shapes.hpp"

using namespace skel;
using namespace skel::thinning;
using namespace skel::thinning::detail;

namespace {

template <class T>
Levels<T> levels_of(const std::vector<T>& values) {
  std::vector<uint64_t> keys;
  for (T v : values) keys.push_back(order_key(v));
  return Levels<T>(values.data(), keys);
}

// The thinning state of `mask` as scan_planes leaves it, and the planes.
struct Scanned {
  VolumeU8 st;
  std::vector<PlaneScan> planes;
};
template <class T>
Scanned scan(const VolumeU8& mask, const Volume<T>& priority, const VolumeU8* locked = nullptr, int threads = 1) {
  Scanned s{VolumeU8(mask.grid(), 0), {}};
  s.planes = scan_planes(mask, priority.data(), locked, s.st.data(), threads);
  return s;
}

}  // namespace

TEST(ThinningPhases, LevelsRankFloatPrioritiesByDistinctValue) {
  // -0 and +0 are one value; duplicates share a level; ranks follow the order of the values.
  const std::vector<float> pr = {0.5f, -0.0f, 0.0f, 2.5f, 0.5f, -1.0f};
  const Levels<float> lv = levels_of(pr);
  EXPECT_EQ(lv.count(), 4);
  const std::vector<uint32_t> expect = {2, 1, 1, 3, 2, 0};
  for (size_t i = 0; i < pr.size(); ++i) EXPECT_EQ(lv.level(static_cast<int64_t>(i)), expect[i]) << i;
}

TEST(ThinningPhases, LevelsOfIntegersUseTheValueOrTheRank) {
  // A small range maps value - min directly (levels may be empty).
  const std::vector<uint16_t> small = {15, 10, 12, 10};
  const Levels<uint16_t> a = levels_of(small);
  EXPECT_EQ(a.count(), 6);
  EXPECT_EQ(a.level(0), 5u);
  EXPECT_EQ(a.level(1), 0u);
  EXPECT_EQ(a.level(2), 2u);
  // A sparse range is ranked; signed values keep their order.
  const std::vector<int32_t> sparse = {1 << 30, -(1 << 30), 7, 1 << 30};
  const Levels<int32_t> b = levels_of(sparse);
  EXPECT_EQ(b.count(), 3);
  EXPECT_EQ(b.level(0), 2u);
  EXPECT_EQ(b.level(1), 0u);
  EXPECT_EQ(b.level(2), 1u);
  EXPECT_EQ(b.level(3), 2u);
}

TEST(ThinningPhases, ScanSetsFlagsAndFindsTheBoundaryInRasterOrder) {
  // A 3x3x3 cube at (1..3)^3 in 5^3 plus one voxel on the array face; the cube's corner (1,1,1) is
  // locked.
  VolumeU8 mask(Dims{5, 5, 5}, 0);
  for (int z = 1; z <= 3; ++z)
    for (int y = 1; y <= 3; ++y)
      for (int x = 1; x <= 3; ++x) mask(x, y, z) = 1;
  mask(4, 2, 2) = 1;
  VolumeU8 locked(mask.grid(), 0);
  locked(1, 1, 1) = 1;
  VolumeF32 pr(mask.grid(), 1.0f);
  const Scanned s = scan(mask, pr, &locked);
  ASSERT_EQ(s.planes.size(), 5u);
  std::vector<int64_t> boundary;
  int64_t objects = 0;
  for (const auto& p : s.planes) {
    for (const uint32_t o : p.boundary) boundary.push_back(p.base + o);
    objects += p.objects;
    EXPECT_FALSE(p.nan);
  }
  EXPECT_EQ(objects, 28);
  // Every object voxel except the cube's centre and (3,2,2) (covered by the face voxel) has a
  // background 6-neighbour; the face voxel is on the array face; the locked corner is never queued.
  std::vector<int64_t> expect;
  for (int64_t i = 0; i < mask.size(); ++i)
    if (mask[i] && i != mask.index(2, 2, 2) && i != mask.index(3, 2, 2) && i != mask.index(1, 1, 1))
      expect.push_back(i);
  EXPECT_EQ(boundary, expect);
  for (int64_t z = 0; z < 5; ++z)
    for (int64_t y = 0; y < 5; ++y)
      for (int64_t x = 0; x < 5; ++x) {
        const uint8_t v = s.st(x, y, z);
        const bool face = x == 0 || y == 0 || z == 0 || x == 4 || y == 4 || z == 4;
        EXPECT_EQ((v & kObject) != 0, mask(x, y, z) != 0);
        EXPECT_EQ((v & kBorder) != 0, face);
        EXPECT_EQ((v & kLocked) != 0, locked(x, y, z) != 0);
        EXPECT_EQ(v & (kQueued | kVisited | kDirty), 0);
      }
}

TEST(ThinningPhases, ScanReportsNaNPriorities) {
  VolumeU8 mask(Dims{3, 3, 3}, 0);
  mask(1, 1, 1) = 1;
  mask(0, 0, 2) = 1;
  VolumeF32 pr(mask.grid(), 0.0f);
  pr(1, 1, 1) = std::numeric_limits<float>::quiet_NaN();
  pr(0, 0, 0) = std::numeric_limits<float>::quiet_NaN();  // background: ignored
  Scanned s = scan(mask, pr);
  EXPECT_TRUE(s.planes[1].nan);
  EXPECT_FALSE(s.planes[0].nan);
  EXPECT_FALSE(s.planes[2].nan);
  int64_t objects = 0;
  EXPECT_THROW(gather_keys(s.planes, objects), InputError);
}

TEST(ThinningPhases, InitialQueueHoldsTheBoundaryPerLevelInRasterOrder) {
  const VolumeU8 mask = test::random_blobs(24, 5, 0.5);
  const VolumeU32 pr = test::chamfer345(mask);
  std::vector<std::vector<int64_t>> first;
  for (int threads : {1, 3}) {
    Scanned s = scan(mask, pr, nullptr, threads);
    std::vector<int64_t> boundary;
    for (const auto& p : s.planes)
      for (const uint32_t o : p.boundary) boundary.push_back(p.base + o);
    int64_t objects = 0;
    const Levels<uint32_t> lv(pr.data(), gather_keys(s.planes, objects));
    BucketQueue<uint32_t> q(lv.count());
    fill_initial_queue(s.planes, lv, s.st.data(), mask.nz(), threads, q);
    // Expected: the boundary voxels (raster order) split by level, order kept.
    std::vector<std::vector<int64_t>> expect(static_cast<size_t>(lv.count()));
    for (int64_t i : boundary) expect[lv.level(i)].push_back(i);
    std::vector<std::vector<int64_t>> got;
    for (const auto& b : q.bucket) got.emplace_back(b.begin(), b.end());
    EXPECT_EQ(got, expect) << threads;
    EXPECT_EQ(q.size, static_cast<int64_t>(boundary.size()));
    EXPECT_EQ(q.lowest, 0);
    for (const auto& p : s.planes) EXPECT_TRUE(p.boundary.empty());
    int64_t queued = 0;
    for (int64_t i = 0; i < mask.size(); ++i) queued += (s.st[i] & kQueued) != 0;
    EXPECT_EQ(queued, static_cast<int64_t>(boundary.size()));
    if (first.empty()) first = got;
    else EXPECT_EQ(got, first);
  }
}

TEST(ThinningPhases, SubIterationsRotateThroughTheDirections) {
  // Order up, down, north, south, east, west = +z, -z, +y, -y, +x, -x = bits 4, 5, 2, 3, 0, 1,
  // starting at position iteration % 6.
  const std::vector<int> order = {4, 5, 2, 3, 0, 1};
  for (int64_t it = 0; it < 12; ++it) EXPECT_EQ(choose_subiteration(63u, it), order[static_cast<size_t>(it % 6)]);
  EXPECT_EQ(choose_subiteration(1u, 0), 0);   // only +x present
  EXPECT_EQ(choose_subiteration(3u, 1), 0);   // +x and -x: +x comes first from position 1
  EXPECT_EQ(choose_subiteration(3u, 5), 1);   // from position 5: -x
  EXPECT_EQ(choose_subiteration(0u, 3), -1);
}

TEST(ThinningPhases, CandidateDirectionsOfAnEndPoint) {
  // One object neighbour below (-z): only the up mask matches (background above, object below).
  const uint32_t below = 1u << neighbour_bit(0, 0, -1);
  EXPECT_EQ(matched_directions(below, direction_masks()), 1u << 4);
  EXPECT_EQ(thinning_directions(below), 1u << 4);
  EXPECT_EQ(candidate_directions(below, direction_masks()), (1u << 4) | 64u);  // end point: bit 6
  // Two neighbours below: not an end point.
  const uint32_t two = below | 1u << neighbour_bit(1, 0, -1);
  const uint32_t d = candidate_directions(two, direction_masks());
  EXPECT_EQ(d & 64u, 0u);
  EXPECT_EQ(d, thinning_directions(two));
  EXPECT_NE(d & (1u << 4), 0u);
}

TEST(ThinningPhases, BitParallelDirectionsEqualTheMaskLoop) {
  // directions_of (all 26 masks at once; the check and thinning_directions use it) against the
  // reference loop over the masks: 2^20 configurations spread over all 2^26 (every 64th, its low
  // bits varied) and 2^20 random ones. (All 2^26 agree: checked once, 6 s.)
  const DirectionMasks& dm = direction_masks();
  int64_t differ = 0;
  uint64_t state = 0x9E3779B97F4A7C15ull;
  for (uint32_t k = 0; k < (1u << 20); ++k) {
    state = state * 6364136223846793005ull + 1442695040888963407ull;
    for (const uint32_t nb : {(k << 6) | (k % 64), static_cast<uint32_t>(state >> 38)}) {
      differ += directions_of(nb) != matched_directions(nb, dm);
      differ += candidate_directions(nb) != candidate_directions(nb, dm);
    }
  }
  EXPECT_EQ(differ, 0);
  for (const uint32_t nb : {0u, (1u << 26) - 1, 1u << neighbour_bit(0, 0, -1), 1u << neighbour_bit(1, 1, 1)})
    EXPECT_EQ(directions_of(nb), matched_directions(nb, dm)) << nb;
}

TEST(ThinningPhases, NeighbourhoodWordsFromRowLoadsEqualSingleVoxelReads) {
  // Thinner::neighbourhood reads each row of the 3x3x3 block with one 4-byte load (the last row
  // shifted by one byte so that no load passes the array's end): on random masks, with random flag
  // bits set beside kObject, every voxel's word equals neighbourhood_at on the mask, the last
  // interior voxel (nx-2, ny-2, nz-2) included; and gather + deletable_with equal deletable.
  uint64_t state = 12345;
  auto next = [&] {
    state = state * 6364136223846793005ull + 1442695040888963407ull;
    return static_cast<uint32_t>(state >> 33);
  };
  for (const Dims d : {Dims{3, 3, 3}, Dims{7, 5, 6}, Dims{4, 9, 3}, Dims{16, 3, 5}}) {
    for (int fill = 1; fill <= 3; ++fill) {
      VolumeU8 mask(d, 0);
      for (int64_t i = 0; i < mask.size(); ++i) mask[i] = next() % 4 < static_cast<uint32_t>(fill) ? 1 : 0;
      VolumeF32 pr(mask.grid(), 0.0f);
      Scanned s = scan(mask, pr);
      for (int64_t i = 0; i < s.st.size(); ++i)  // flags beside kObject must not leak into the word
        if (s.st[i] & kObject) s.st[i] |= static_cast<uint8_t>(next() % 2 ? kQueued | kDirty : 0);
      Thinner th(s.st.data(), mask.dims(), 2);
      for (int64_t z = 0; z < d[2]; ++z)
        for (int64_t y = 0; y < d[1]; ++y)
          for (int64_t x = 0; x < d[0]; ++x) {
            const int64_t i = x + d[0] * (y + d[1] * z);
            ASSERT_EQ(th.neighbourhood(i), neighbourhood_at(mask, x, y, z)) << x << " " << y << " " << z;
            if (!mask[i]) continue;
            uint32_t a = 0, b = 0;
            const bool whole = th.deletable(i, a);
            const bool split = th.gather(i, b) && th.deletable_with(i, b);
            EXPECT_EQ(whole, split);
            if (whole) {
              EXPECT_EQ(a, b);
            }
            // The check's one-call form: candidate_directions of a deletable voxel, else 0.
            uint32_t c = 0;
            if (th.gather(i, c)) {
              EXPECT_EQ(th.deletable_directions(i, c), whole ? candidate_directions(c) : 0u);
            }
          }
    }
  }
}

TEST(ThinningPhases, CachedSimpleTestAndDirectionsEqualTheDirectOnes) {
  // Thinner::topology_code keeps the simple test's answer and directions_of in a direct-mapped cache
  // whose slots store part of a bijective hash of the configuration: random configurations (many
  // sharing a slot: 2^20 of them for 2^15 slots), each asked twice, the second time mostly a hit,
  // and the configurations in between evicting each other, must give the direct answers.
  VolumeU8 st(Dims{3, 3, 3}, 0);
  const Thinner th(st.data(), st.dims(), 0);
  uint64_t state = 777;
  auto next = [&] {
    state = state * 6364136223846793005ull + 1442695040888963407ull;
    return static_cast<uint32_t>(state >> 38);  // 26 bits
  };
  int simple = 0;
  for (int k = 0; k < (1 << 20); ++k) {
    const uint32_t nb = next();
    const uint32_t want = is_simple_direct(nb) ? 64u | directions_of(nb) : 0u;
    simple += want != 0;
    ASSERT_EQ(th.topology_code(nb), want) << nb;
    ASSERT_EQ(th.topology_code(nb), want) << nb;
    ASSERT_EQ(th.simple(nb), want != 0) << nb;
  }
  EXPECT_GT(simple, 0);
  // Configurations of one slot (the same top 15 bits of the hash, every 11-bit tag), in turn: the
  // hash's multiplier inverted modulo 2^32 by Newton's iteration.
  uint32_t inv = 0x9E3779B1u;
  for (int k = 0; k < 5; ++k) inv *= 2u - 0x9E3779B1u * inv;
  ASSERT_EQ(inv * 0x9E3779B1u, 1u);
  for (const uint32_t slot : {0u, 12345u, (1u << 15) - 1}) {
    for (uint32_t tag = 0; tag < (1u << 11); ++tag) {
      const uint32_t nb = (((slot << 11) | tag) * inv) & ((1u << 26) - 1);
      ASSERT_EQ(Thinner::slot_hash(nb) >> 11, slot);
      ASSERT_EQ(th.topology_code(nb), is_simple_direct(nb) ? 64u | directions_of(nb) : 0u) << nb;
    }
  }
}

TEST(ThinningPhases, EndPointImportanceCountsTheBranchUpToTheJunction) {
  // A line x = 0..6 at y = 1 and a branch (3, 2..4) off its middle, all at z = 1 in 9x7x3.
  VolumeU8 mask(Dims{9, 7, 3}, 0);
  for (int x = 0; x <= 6; ++x) mask(x, 1, 1) = 1;
  for (int y = 2; y <= 4; ++y) mask(3, y, 1) = 1;
  VolumeF32 pr(mask.grid(), 0.0f);
  Scanned s = scan(mask, pr);
  // The branch: (3,4) and (3,3) are end points in turn; (3,2) touches three line voxels.
  EXPECT_EQ(Thinner(s.st.data(), mask.dims(), 5).importance(mask.index(3, 4, 1)), 2);
  // The line's end (0,1): (0,1), (1,1); then (2,1) has two further neighbours ((3,1) and (3,2)).
  EXPECT_EQ(Thinner(s.st.data(), mask.dims(), 5).importance(mask.index(0, 1, 1)), 2);
  // Counting stops at l + 1.
  EXPECT_EQ(Thinner(s.st.data(), mask.dims(), 1).importance(mask.index(3, 4, 1)), 2);
  // An isolated line of five voxels: every voxel after the first is an end point in turn, the last
  // has no further neighbour.
  VolumeU8 line(Dims{7, 3, 3}, 0);
  for (int x = 1; x <= 5; ++x) line(x, 1, 1) = 1;
  Scanned t = scan(line, VolumeF32(line.grid(), 0.0f));
  EXPECT_EQ(Thinner(t.st.data(), line.dims(), 10).importance(line.index(1, 1, 1)), 4);
  EXPECT_EQ(Thinner(t.st.data(), line.dims(), 2).importance(line.index(1, 1, 1)), 3);
  // deletable(): with l = 3 the end point of the five-voxel line is kept (importance 4 > 3).
  uint32_t nb = 0;
  EXPECT_FALSE(Thinner(t.st.data(), line.dims(), 3).deletable(line.index(1, 1, 1), nb));
  EXPECT_TRUE(Thinner(t.st.data(), line.dims(), 4).deletable(line.index(1, 1, 1), nb));
  EXPECT_FALSE(Thinner(t.st.data(), line.dims(), 0).deletable(line.index(3, 1, 1), nb));  // not simple
}

TEST(ThinningPhases, SmoothCheckFlagAndRecheckOnALine) {
  // A three-voxel line along x, one priority level, l = 0: both ends are deletable end points (-x and
  // +x), the middle voxel is not simple.
  VolumeU8 mask(Dims{5, 5, 5}, 0);
  for (int x = 1; x <= 3; ++x) mask(x, 2, 2) = 1;
  VolumeF32 pr(mask.grid(), 1.0f);
  Scanned s = scan(mask, pr);
  int64_t objects = 0;
  const Levels<float> lv(pr.data(), gather_keys(s.planes, objects));
  ThinningStatistics stats;
  stats.object_voxels = objects;
  Thinner th(s.st.data(), mask.dims(), 0);
  BucketQueue<uint32_t> q(lv.count());
  fill_initial_queue(s.planes, lv, s.st.data(), mask.nz(), 1, q);
  const Interrupter irq;
  Removal<float, uint32_t> r(s.st.data(), th, lv, q, pr.data(), stats, 1, irq);

  BigVector<uint32_t> tv;
  BigVector<uint8_t> tc;
  r.take_level(0, tv, tc);
  const int64_t a = mask.index(1, 2, 2), m = mask.index(2, 2, 2), b = mask.index(3, 2, 2);
  ASSERT_EQ(std::vector<int64_t>(tv.begin(), tv.end()), (std::vector<int64_t>{a, m, b}));
  EXPECT_TRUE(tc.empty());  // nothing cached in the initial queue
  EXPECT_EQ(q.size, 0);
  BigVector<uint8_t> dirs(3, 0);
  EXPECT_EQ(r.check(tv, tc, dirs), 3);
  EXPECT_EQ(std::vector<uint8_t>(dirs.begin(), dirs.end()), (std::vector<uint8_t>{2 | 64, 0, 1 | 64}));

  int64_t nc = 0;
  const uint32_t x_set = r.flag(tv, dirs, 3, nc);
  EXPECT_EQ(x_set, 3u);
  ASSERT_EQ(nc, 2);
  EXPECT_EQ(static_cast<int64_t>(tv[0]), a);
  EXPECT_EQ(dirs[0], 2 | 64);
  EXPECT_EQ(static_cast<int64_t>(tv[1]), b);
  EXPECT_EQ(dirs[1], 1 | 64);
  EXPECT_TRUE(s.st[a] & kQueued);
  EXPECT_FALSE(s.st[m] & kQueued);

  // Sub-iteration 1 takes +x (bit 0): the left end goes back to the level without a cached direction
  // (end points are never cached), the right end is removed, which queues the middle voxel (dirty).
  const int d = choose_subiteration(x_set, 1);
  ASSERT_EQ(d, 0);
  r.recheck(tv, dirs, nc, 1u << d, 0);
  EXPECT_FALSE(s.st[b] & kObject);
  EXPECT_EQ(stats.removed, 1);
  std::vector<int64_t> requeued(q.bucket[0].begin(), q.bucket[0].end());
  EXPECT_EQ(requeued, (std::vector<int64_t>{a, m}));
  EXPECT_TRUE(q.cache[0].empty());  // an end point and a fresh voxel: no cached directions
  EXPECT_EQ(q.size, 2);
  EXPECT_TRUE(s.st[m] & kDirty);
}

TEST(ThinningPhases, BasicLoopReducesACubeToOneVoxel) {
  VolumeU8 mask(Dims{5, 5, 5}, 0);
  for (int z = 1; z <= 3; ++z)
    for (int y = 1; y <= 3; ++y)
      for (int x = 1; x <= 3; ++x) mask(x, y, z) = 1;
  const VolumeU32 pr = test::chamfer345(mask);
  Scanned s = scan(mask, pr);
  ThinningStatistics stats;
  const Levels<uint32_t> lv(pr.data(), gather_keys(s.planes, stats.object_voxels));
  Thinner th(s.st.data(), mask.dims(), 0);
  BucketQueue<uint32_t> q(lv.count());
  fill_initial_queue(s.planes, lv, s.st.data(), mask.nz(), 1, q);
  const Interrupter irq;
  Removal<uint32_t, uint32_t>(s.st.data(), th, lv, q, pr.data(), stats, 1, irq).run_basic();
  EXPECT_EQ(stats.removed, 26);
  EXPECT_GE(stats.tests, 26);
  EXPECT_EQ(q.size, 0);
  const std::vector<int64_t> skel = collect_skeleton(s.st.data(), mask.dims(), 1);
  ASSERT_EQ(skel.size(), 1u);
  EXPECT_FALSE(s.st[skel[0]] & kQueued);
}

TEST(ThinningPhases, SkeletonStatistics) {
  // A 3x3x3 cube (one interior voxel), a two-voxel line (two end points), a locked voxel.
  VolumeU8 mask(Dims{12, 5, 5}, 0);
  for (int z = 1; z <= 3; ++z)
    for (int y = 1; y <= 3; ++y)
      for (int x = 1; x <= 3; ++x) mask(x, y, z) = 1;
  mask(6, 2, 2) = mask(7, 2, 2) = 1;
  mask(10, 2, 2) = 1;
  VolumeU8 locked(mask.grid(), 0);
  locked(10, 2, 2) = 1;
  Scanned s = scan(mask, VolumeF32(mask.grid(), 0.0f), &locked);
  const std::vector<int64_t> skel = collect_skeleton(s.st.data(), mask.dims(), 2);
  std::vector<int64_t> expect;
  for (int64_t i = 0; i < mask.size(); ++i)
    if (mask[i]) expect.push_back(i);
  EXPECT_EQ(skel, expect);
  ThinningStatistics stats;
  count_skeleton(Thinner(s.st.data(), mask.dims(), 2), s.st.data(), skel, mask.dims(), 2, stats);
  EXPECT_EQ(stats.skeleton_voxels, 30);
  EXPECT_EQ(stats.locked_voxels, 1);
  EXPECT_EQ(stats.kept_end_points, 2);
  EXPECT_EQ(stats.interior_voxels, 1);
  finish_state(s.st.data(), skel, mask.dims(), 2);
  for (int64_t i = 0; i < mask.size(); ++i) EXPECT_EQ(s.st[i], mask[i]);
}

TEST(ThinningPhases, StuckComponentsAreContractibleAndUnanchored) {
  // A two-voxel line, a locked two-voxel line, a single voxel and an 8-voxel square ring (a tunnel).
  VolumeU8 mask(Dims{16, 6, 3}, 0);
  mask(1, 1, 1) = mask(2, 1, 1) = 1;
  mask(5, 1, 1) = mask(6, 1, 1) = 1;
  mask(9, 1, 1) = 1;
  for (int y = 1; y <= 3; ++y)
    for (int x = 11; x <= 13; ++x)
      if (x != 12 || y != 2) mask(x, y, 1) = 1;
  VolumeU8 locked(mask.grid(), 0);
  locked(5, 1, 1) = 1;
  for (int l : {0, 2}) {
    Scanned s = scan(mask, VolumeF32(mask.grid(), 0.0f), &locked);
    const std::vector<int64_t> skel = collect_skeleton(s.st.data(), mask.dims(), 1);
    ThinningStatistics stats;
    count_skeleton(Thinner(s.st.data(), mask.dims(), l), s.st.data(), skel, mask.dims(), l, stats);
    // l = 0 keeps no end points, so only the free two-voxel line is stuck; with l > 0 its end points
    // anchor it.
    EXPECT_EQ(stats.stuck_components, l == 0 ? 1 : 0) << l;
    EXPECT_EQ(stats.stuck_voxels, l == 0 ? 2 : 0) << l;
    for (int64_t i : skel) EXPECT_TRUE(s.st[i] & kVisited);
  }
}

TEST(ThinningPhases, QueueEntriesAreFourBytesUpTo2To32Voxels) {
  // Voxel indices 0 .. n-1 fit a uint32_t while n <= 2^32 (no allocation: the dims alone decide).
  EXPECT_EQ(queue_entry_bytes(Dims{512, 512, 512}), 4);
  EXPECT_EQ(queue_entry_bytes(Dims{1280, 1280, 1280}), 4);
  EXPECT_EQ(queue_entry_bytes(Dims{2048, 2048, 1024}), 4);  // exactly 2^32 voxels: last index 2^32 - 1
  EXPECT_EQ(queue_entry_bytes(Dims{2048, 2048, 1025}), 8);
  EXPECT_EQ(queue_entry_bytes(Dims{1625, 1625, 1625}), 4);  // 4 291 015 625
  EXPECT_EQ(queue_entry_bytes(Dims{1626, 1626, 1626}), 8);  // 4 298 942 376
  EXPECT_EQ(queue_entry_bytes(Dims{int64_t{1} << 32, 1, 1}), 4);
  EXPECT_EQ(queue_entry_bytes(Dims{(int64_t{1} << 32) + 1, 1, 1}), 8);
  // The last index of a 2^32-voxel volume round-trips through a 4-byte entry; the queue keeps it.
  BucketQueue<uint32_t> q(2);
  const int64_t last = (int64_t{1} << 32) - 1;
  q.push(1, last);
  EXPECT_EQ(static_cast<int64_t>(q.bucket[1][0]), last);
  BucketQueue<uint64_t> q8(1);
  q8.push(0, last + 5);
  EXPECT_EQ(static_cast<int64_t>(q8.bucket[0][0]), last + 5);
}

TEST(ThinningPhases, CachedDirectionsStayAlignedWithTheirEntries) {
  // cache[v] stays empty until an entry with cached directions arrives, then holds one byte per entry
  // of bucket v (0 for uncached ones); take_level moves both, settle clears both.
  VolumeU8 mask(Dims{6, 6, 6}, 1);
  VolumeF32 pr(mask.grid(), 1.0f);
  Scanned s = scan(mask, pr);
  int64_t objects = 0;
  const Levels<float> lv(pr.data(), gather_keys(s.planes, objects));
  BucketQueue<uint32_t> q(lv.count());
  q.push(0, 7);
  EXPECT_TRUE(q.cache[0].empty());
  q.push_cached(0, 8, kCacheValid | 5);
  q.push(0, 9);
  q.push_cached(0, 10, kCacheValid | 32);
  ASSERT_EQ(q.bucket[0].size(), 4u);
  EXPECT_EQ(std::vector<uint8_t>(q.cache[0].begin(), q.cache[0].end()),
            (std::vector<uint8_t>{0, kCacheValid | 5, 0, kCacheValid | 32}));
  ThinningStatistics stats;
  stats.object_voxels = objects;
  Thinner th(s.st.data(), mask.dims(), 0);
  const Interrupter irq;
  Removal<float, uint32_t> r(s.st.data(), th, lv, q, pr.data(), stats, 1, irq);
  BigVector<uint32_t> tv;
  BigVector<uint8_t> tc;
  r.take_level(0, tv, tc);
  EXPECT_EQ(std::vector<uint32_t>(tv.begin(), tv.end()), (std::vector<uint32_t>{7, 8, 9, 10}));
  EXPECT_EQ(tc.size(), 4u);
  EXPECT_TRUE(q.bucket[0].empty());
  EXPECT_TRUE(q.cache[0].empty());
  EXPECT_EQ(q.size, 0);
  // The cached entries (8, 10) keep their directions in check() (no kDirty: untested); the uncached
  // ones (7, 9: voxels (1, 1, 0) and (3, 1, 0) on the array face) are tested.
  BigVector<uint8_t> dirs(4, 0);
  const int64_t tested = r.check(tv, tc, dirs);
  EXPECT_EQ(tested, 2);
  EXPECT_EQ(dirs[1], 5);
  EXPECT_EQ(dirs[3], 32);
}

TEST(ThinningPhases, LargeBucketsGrowWithoutLosingOrderOrCachedDirections) {
  // Past 4 MiB a full bucket (and its cache bytes) grows by grow_releasing instead of a plain
  // reallocation: 3 M entries in bucket 1 (several growths of the 4-byte entries, two of the cache
  // bytes), every seventh with cached directions, come back in push order with their bytes aligned.
  BucketQueue<uint32_t> q(2);
  constexpr uint32_t n = 3u << 20;
  for (uint32_t i = 0; i < n; ++i) {
    if (i % 7 == 3) q.push_cached(1, i * 3, static_cast<uint8_t>(kCacheValid | (i % 63)));
    else q.push(1, i * 3);
  }
  ASSERT_EQ(q.bucket[1].size(), n);
  ASSERT_EQ(q.cache[1].size(), n);
  EXPECT_EQ(q.size, static_cast<int64_t>(n));
  for (uint32_t i = 0; i < n; ++i) {
    ASSERT_EQ(q.bucket[1][i], i * 3) << i;
    const uint8_t want = i % 7 == 3 ? static_cast<uint8_t>(kCacheValid | (i % 63)) : uint8_t{0};
    ASSERT_EQ(q.cache[1][i], want) << i;
  }
  EXPECT_TRUE(q.bucket[0].empty());
}

TEST(ThinningPhases, FourAndEightByteQueueEntriesGiveTheSameSkeleton) {
  // Volumes above 2^32 voxels use 8-byte entries: forced here on small volumes, the same skeleton
  // and statistics as the 4-byte entries, for masks touching the array faces (border voxels) and
  // with locks; both variants.
  std::vector<VolumeU8> masks = {test::random_blobs(30, 3, 0.47, 2), test::random_blobs(26, 8, 0.52, 3)};
  VolumeU8 faces(Dims{17, 13, 11}, 1);  // a full box: every face voxel is a border voxel
  faces(8, 6, 5) = 0;
  masks.push_back(faces);
  for (size_t k = 0; k < masks.size(); ++k) {
    const VolumeU8& m = masks[k];
    const VolumeU32 pr = test::chamfer345(m);
    VolumeU8 locks(m.dims(), 0);
    for (int64_t i = 0; i < m.size(); i += 211) locks[i] = 1;
    for (auto v : {ThinningVariant::Basic, ThinningVariant::Smooth})
      for (const VolumeU8* lk : {static_cast<const VolumeU8*>(nullptr), static_cast<const VolumeU8*>(&locks)})
        for (int t : {1, 2}) {
          ThinningOptions o;
          o.variant = v;
          o.threads = t;
          const ThinningResult a = thin_doht_with_entries(m, pr, lk, o, 4);
          const ThinningResult b = thin_doht_with_entries(m, pr, lk, o, 8);
          const ThinningResult c = thin_doht(m, pr, lk, o);
          const std::string what = "mask " + std::to_string(k) + " threads " + std::to_string(t);
          EXPECT_TRUE(a.skeleton == b.skeleton) << what;
          EXPECT_TRUE(a.skeleton == c.skeleton) << what;
          EXPECT_EQ(a.stats.tests, b.stats.tests) << what;
          EXPECT_EQ(a.stats.removed, b.stats.removed) << what;
          EXPECT_EQ(a.stats.sub_iterations, b.stats.sub_iterations) << what;
          EXPECT_GT(a.stats.removed, 0) << what;
        }
  }
  EXPECT_THROW((void)thin_doht_with_entries(masks[0], test::chamfer345(masks[0]), nullptr, {}, 6), Error);
}
