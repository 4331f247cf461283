// Geodesic boundary distance: exactness against a plain BFS reference, thread independence, and the
// behaviour on plates (high importance in the middle of a slab) and rods.
#include <gtest/gtest.h>

#include <random>

#include "geodesic/geodesic.hpp"

using namespace skel;
using namespace skel::geodesic;

namespace {

VolumeU8 random_blobs(Dims d, uint64_t seed, double fill) {
  std::mt19937_64 rng(seed);
  VolumeU8 v(d, 0);
  std::uniform_real_distribution<double> u(0, 1);
  for (auto& x : v) x = u(rng) < fill ? 1 : 0;
  // One smoothing pass (majority in the 6-neighbourhood) makes blob-like shapes.
  VolumeU8 s(d, 0);
  for (int64_t z = 0; z < d[2]; ++z)
    for (int64_t y = 0; y < d[1]; ++y)
      for (int64_t x = 0; x < d[0]; ++x) {
        int c = v(x, y, z);
        c += v.at_or(x - 1, y, z, 0) + v.at_or(x + 1, y, z, 0) + v.at_or(x, y - 1, z, 0) + v.at_or(x, y + 1, z, 0) +
             v.at_or(x, y, z - 1, 0) + v.at_or(x, y, z + 1, 0);
        s(x, y, z) = c >= 4 ? 1 : 0;
      }
  return s;
}

VolumeU8 slab(Dims d, int64_t thickness, int64_t margin) {
  VolumeU8 v(d, 0);
  const int64_t z0 = d[2] / 2 - thickness / 2;
  for (int64_t z = z0; z < z0 + thickness; ++z)
    for (int64_t y = margin; y < d[1] - margin; ++y)
      for (int64_t x = margin; x < d[0] - margin; ++x) v(x, y, z) = 1;
  return v;
}

}  // namespace

TEST(Geodesic, EqualsReferenceOnRandomObjects) {
  for (uint64_t seed = 1; seed <= 12; ++seed) {
    const Dims d{9 + static_cast<int64_t>(seed % 4), 10, 8 + static_cast<int64_t>(seed % 3)};
    VolumeU8 m = random_blobs(d, seed, 0.45 + 0.02 * static_cast<double>(seed % 5));
    for (Mode mode : {Mode::Threshold, Mode::Full}) {
      for (int64_t t : {2, 5, 9}) {
        Options o;
        o.mode = mode;
        o.threshold = t;
        o.threads = 1 + static_cast<int>(seed % 3);
        Result a = boundary_distance(m, o);
        Result r = boundary_distance_reference(m, o);
        ASSERT_TRUE(a.importance == r.importance) << "seed " << seed << " t " << t << " full " << (mode == Mode::Full);
        ASSERT_TRUE(a.surface_skeleton == r.surface_skeleton);
        if (mode == Mode::Full) break;  // t only selects the surface in full mode
      }
    }
  }
}

TEST(Geodesic, ObjectTouchingTheArrayBorderUsesTheOutsideRing) {
  VolumeU8 m(Dims{6, 6, 6}, 1);  // everything is object: L is the ring outside the array
  Options o;
  o.threshold = 4;
  Result a = boundary_distance(m, o);
  Result r = boundary_distance_reference(m, o);
  EXPECT_TRUE(a.importance == r.importance);
  EXPECT_GT(a.stats.layer_voxels, 0);
  EXPECT_EQ(a.stats.object_voxels, 216);
}

TEST(Geodesic, IdenticalForAnyThreadCount) {
  VolumeU8 m = random_blobs(Dims{40, 36, 30}, 7, 0.5);
  Options o;
  o.threshold = 12;
  o.threads = 1;
  Result a = boundary_distance(m, o);
  for (int th : {2, 4}) {
    o.threads = th;
    Result b = boundary_distance(m, o);
    EXPECT_TRUE(a.importance == b.importance) << th;
  }
}

// The diagnostic counts (bone/geodesic.csv) are identical for any thread count too: which base a
// pivot settles no longer depends on which worker gets there first. Repeated, because a race shows
// only now and then.
TEST(Geodesic, DiagnosticCountsIdenticalForAnyThreadCount) {
  VolumeU8 m = random_blobs(Dims{56, 52, 44}, 11, 0.52);
  for (int64_t t : {8, 20}) {
    Options o;
    o.threshold = t;
    o.threads = 1;
    const Result a = boundary_distance(m, o);
    EXPECT_GT(a.stats.pivots, 0) << t;
    EXPECT_GT(a.stats.saturated_by_pivot, 0) << t;
    for (int rep = 0; rep < 2; ++rep)
      for (int th : {2, 3, 4}) {
        o.threads = th;
        const Result b = boundary_distance(m, o);
        SCOPED_TRACE("t " + std::to_string(t) + ", " + std::to_string(th) + " threads, run " + std::to_string(rep));
        EXPECT_TRUE(a.importance == b.importance);
        EXPECT_EQ(a.stats.base_points, b.stats.base_points);
        EXPECT_EQ(a.stats.searches, b.stats.searches);
        EXPECT_EQ(a.stats.pivots, b.stats.pivots);
        EXPECT_EQ(a.stats.long_searches, b.stats.long_searches);
        EXPECT_EQ(a.stats.saturated_by_pivot, b.stats.saturated_by_pivot);
        EXPECT_EQ(a.stats.visited, b.stats.visited);
      }
  }
}

TEST(Geodesic, SlabMidSurfaceIsSelectedAndPivotsSaveSearches) {
  // A 4-voxel thick slab: the two sides are far apart along the boundary (around the rim), so the
  // voxels at the mid-plane get importance t; near the rim the value drops.
  VolumeU8 m = slab(Dims{48, 48, 16}, 4, 4);
  Options o;
  o.threshold = 10;
  Result a = boundary_distance(m, o);
  // Mid-surface far from the rim: selected.
  const int64_t zmid = 16 / 2;  // upper voxel of the pair across the mid-plane
  int64_t selected_interior = 0, interior = 0;
  for (int64_t y = 14; y < 34; ++y)
    for (int64_t x = 14; x < 34; ++x) {
      ++interior;
      selected_interior += a.surface_skeleton(x, y, zmid);
    }
  EXPECT_EQ(selected_interior, interior);
  // No voxel outside the two middle planes is selected away from the rim.
  for (int64_t z = 0; z < 16; ++z) {
    if (z == zmid || z == zmid - 1) continue;
    for (int64_t y = 14; y < 34; ++y)
      for (int64_t x = 14; x < 34; ++x) EXPECT_EQ(a.surface_skeleton(x, y, z), 0) << x << " " << y << " " << z;
  }
  EXPECT_GT(a.stats.saturated_by_pivot, 0);
  EXPECT_LT(a.stats.searches, a.stats.base_points + a.stats.base_points / 2);
  Result r = boundary_distance_reference(m, o);
  EXPECT_TRUE(a.importance == r.importance);
}

// Landmark fields on a plate: the searches across its rim (the expensive ones) build fields, the
// importance is bit-identical to the plain A*'s (which equals the definition: the tests above), for
// 1 and 2 threads, and the
// A* closes fewer voxels (visited counts the fields' voxels too, so the difference is a lower bound
// of the saving).
TEST(Geodesic, LandmarksOnAPlateKeepTheImportanceAndCloseFewerVoxels) {
  VolumeU8 m = slab(Dims{100, 80, 14}, 6, 3);
  Options o;
  o.threshold = 40;
  o.landmarks = false;
  const Result plain = boundary_distance(m, o);
  EXPECT_EQ(plain.stats.landmarks, 0);
  o.landmarks = true;
  for (int th : {1, 2}) {
    o.threads = th;
    const Result a = boundary_distance(m, o);
    EXPECT_TRUE(a.importance == plain.importance) << th;
    EXPECT_GT(a.stats.landmarks, 0) << th;
    EXPECT_LT(a.stats.visited, plain.stats.visited) << th;
    EXPECT_EQ(a.stats.searches, plain.stats.searches) << th;
  }
}

TEST(Geodesic, ThresholdBeyondPivotRangeEqualsReference) {
  // Pivot distances are 16-bit, so for t + t/4 >= 65534 the pivots are switched off; the values
  // must not change (here every path is shorter than t, so the values are the plain distances).
  VolumeU8 m = slab(Dims{20, 18, 10}, 4, 2);
  Options o;
  o.threshold = 60000;
  o.threads = 2;
  Result a = boundary_distance(m, o);
  Result r = boundary_distance_reference(m, o);
  EXPECT_EQ(a.stats.pivots, 0);
  EXPECT_TRUE(a.importance == r.importance);
  o.threshold = 10;
  Result b = boundary_distance(m, o);
  EXPECT_GT(b.stats.pivots, 0);
  EXPECT_TRUE(b.importance == boundary_distance_reference(m, o).importance);
}

TEST(Geodesic, EmptyAndInvalid) {
  VolumeU8 e(Dims{5, 5, 5}, 0);
  Result r = boundary_distance(e);
  EXPECT_EQ(r.stats.object_voxels, 0);
  for (float v : r.importance) EXPECT_EQ(v, 0.0f);
  Options o;
  o.threshold = 0;
  EXPECT_THROW(boundary_distance(e, o), InputError);
}
