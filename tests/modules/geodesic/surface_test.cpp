// Plate skeletons from the geodesic boundary distance (thesis §2.3.2–2.3.3, ch. 4, §6.2): thin
// surfaces on the mid-surface, cavities kept, robustness to boundary noise compared with
// surface-preserving thinning, rods restored by mixed-dimensional skeletons, geodesic-guided curves,
// and the rods/plates decomposition.
#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <random>

#include "distance/distance.hpp"
#include "geodesic/geodesic.hpp"
#include "geodesic/surface.hpp"
#include "thinning/thinning.hpp"
#include "analysis/topology.hpp"
#include "thinning/local_topology.hpp"

using namespace skel::thinning;
using namespace skel::analysis;

using namespace skel;
using namespace skel::geodesic;

namespace {

// Components, cavities, Euler characteristic and tunnels agree (voxel counts differ, of course).
void expect_homotopic(const VolumeU8& a, const VolumeU8& b) {
  const auto ta = topology(a), tb = topology(b);
  EXPECT_EQ(ta.components, tb.components);
  EXPECT_EQ(ta.cavities, tb.cavities);
  EXPECT_EQ(ta.euler, tb.euler);
  EXPECT_EQ(ta.tunnels, tb.tunnels);
}

int64_t count(const VolumeU8& v) {
  int64_t c = 0;
  for (auto x : v) c += x != 0;
  return c;
}

VolumeU8 slab(Dims d, int64_t z0, int64_t thickness, int64_t margin) {
  VolumeU8 v(d, 0);
  for (int64_t z = z0; z < z0 + thickness; ++z)
    for (int64_t y = margin; y < d[1] - margin; ++y)
      for (int64_t x = margin; x < d[0] - margin; ++x) v(x, y, z) = 1;
  return v;
}

// Plate skeleton: geodesic threshold selection, then thin_surface.
VolumeU8 plate_skeleton(const VolumeU8& m, int64_t t) {
  Options o;
  o.threshold = t;
  return thin_surface(boundary_distance(m, o).surface_skeleton).surface;
}

VolumeU8 hollow_sphere(int64_t n, double r_in, double r_out) {
  VolumeU8 v(Dims{n, n, n}, 0);
  const double c = (n - 1) / 2.0;
  for (int64_t z = 0; z < n; ++z)
    for (int64_t y = 0; y < n; ++y)
      for (int64_t x = 0; x < n; ++x) {
        const double r = std::sqrt((x - c) * (x - c) + (y - c) * (y - c) + (z - c) * (z - c));
        v(x, y, z) = r >= r_in && r <= r_out;
      }
  return v;
}

}  // namespace

TEST(ThinSurface, TwoThickSlabBecomesOneThickWithTheSameExtent) {
  VolumeU8 m = slab(Dims{20, 16, 8}, 3, 2, 2);
  auto r = thin_surface(m);
  for (int64_t y = 2; y < 14; ++y)
    for (int64_t x = 2; x < 18; ++x) EXPECT_EQ(r.surface(x, y, 3) + r.surface(x, y, 4), 1) << x << " " << y;
  expect_homotopic(r.surface, m);
  // A one-voxel-thin plane and a curve are left alone.
  VolumeU8 plane = slab(Dims{12, 12, 5}, 2, 1, 1);
  EXPECT_TRUE(thin_surface(plane).surface == plane);
}

TEST(GeodesicPlates, SlabSkeletonIsConnectedOnTheMidSurface) {
  // Thin and tilted slabs: the plate skeleton is one connected piece within one voxel of the
  // mid-surface, covering the slab away from its rim.
  for (int tilt = 0; tilt <= 1; ++tilt) {
    const int64_t n = 40;
    VolumeU8 m(Dims{n, n, n}, 0);
    for (int64_t z = 0; z < n; ++z)
      for (int64_t y = 4; y < n - 4; ++y)
        for (int64_t x = 4; x < n - 4; ++x) {
          const double mid = 20.0 + (tilt ? 0.35 * (x - 20.0) : 0.0);
          m(x, y, z) = std::abs(z - mid) <= 2.0;
        }
    VolumeU8 s = plate_skeleton(m, 12);
    EXPECT_EQ(topology(s).components, 1) << "tilt " << tilt;
    int64_t off = 0, covered = 0, columns = 0;
    for (int64_t z = 0; z < n; ++z)
      for (int64_t y = 0; y < n; ++y)
        for (int64_t x = 0; x < n; ++x)
          if (s(x, y, z)) {
            const double mid = 20.0 + (tilt ? 0.35 * (x - 20.0) : 0.0);
            off += std::abs(z - mid) > 1.0;
          }
    for (int64_t y = 12; y < n - 12; ++y)
      for (int64_t x = 12; x < n - 12; ++x) {
        ++columns;
        bool any = false;
        for (int64_t z = 0; z < n; ++z) any = any || s(x, y, z);
        covered += any;
      }
    EXPECT_EQ(off, 0) << "tilt " << tilt;
    EXPECT_EQ(covered, columns) << "tilt " << tilt;
  }
}

TEST(GeodesicPlates, HollowSphereWithPlatesKeepsItsCavity) {
  VolumeU8 m = hollow_sphere(40, 10.0, 13.0);
  // Two plates attached outside (fig. 4.8).
  for (int64_t z = 18; z < 21; ++z)
    for (int64_t y = 2; y < 38; ++y)
      for (int64_t x = 0; x < 40; ++x)
        if (std::abs(x - 19.5) > 12.0) m(x, y, z) = 1;
  const auto tm = topology(m);
  ASSERT_EQ(tm.cavities, 1);
  VolumeU8 s = plate_skeleton(m, 10);
  const auto ts = topology(s);
  EXPECT_EQ(ts.cavities, tm.cavities);
  EXPECT_EQ(ts.components, 1);
}

TEST(GeodesicPlates, BoundaryNoiseAddsFewerVoxelsThanSurfaceThinning) {
  const Dims d{48, 48, 20};
  VolumeU8 clean = slab(d, 7, 6, 4);
  VolumeU8 noisy = clean;
  std::mt19937 rng(5);
  // Bumps of one voxel on both faces of the slab.
  for (int64_t y = 4; y < 44; ++y)
    for (int64_t x = 4; x < 44; ++x) {
      if (rng() % 4 == 0) noisy(x, y, 6) = 1;
      if (rng() % 4 == 0) noisy(x, y, 13) = 1;
    }
  auto spurious = [](const VolumeU8& a, const VolumeU8& ref) {
    int64_t c = 0;
    for (int64_t i = 0; i < a.size(); ++i) c += a[i] && !ref[i];
    return c;
  };
  const VolumeU8 g_clean = plate_skeleton(clean, 16), g_noisy = plate_skeleton(noisy, 16);
  const VolumeU8 t_clean = thin_surface(clean).surface, t_noisy = thin_surface(noisy).surface;
  const int64_t g_extra = spurious(g_noisy, g_clean), t_extra = spurious(t_noisy, t_clean);
  std::printf("spurious voxels from boundary noise: geodesic %lld, surface-preserving thinning %lld\n",
              static_cast<long long>(g_extra), static_cast<long long>(t_extra));
  EXPECT_LT(g_extra * 4, t_extra);
}

TEST(GeodesicPlates, RodsVanishWithGrowingThresholdAndReturnInTheMixedSkeleton) {
  // A plate with a rod (radius 2) standing on it.
  const int64_t n = 36;
  VolumeU8 m = slab(Dims{n, n, n}, 4, 4, 2);
  for (int64_t z = 8; z < 32; ++z)
    for (int64_t y = 0; y < n; ++y)
      for (int64_t x = 0; x < n; ++x)
        if ((x - 18) * (x - 18) + (y - 18) * (y - 18) <= 5) m(x, y, z) = 1;
  auto rod_voxels = [&](const VolumeU8& s) {
    int64_t c = 0;
    for (int64_t z = 14; z < 30; ++z)
      for (int64_t y = 0; y < n; ++y)
        for (int64_t x = 0; x < n; ++x) c += s(x, y, z);
    return c;
  };
  Options small;
  small.threshold = 4;
  Options large;
  large.threshold = 16;
  const int64_t rod_small = rod_voxels(boundary_distance(m, small).surface_skeleton);
  const int64_t rod_large = rod_voxels(boundary_distance(m, large).surface_skeleton);
  EXPECT_GT(rod_small, 0);
  EXPECT_EQ(rod_large, 0);
  // Mixed-dimensional skeleton: the plate skeleton locked during distance-ordered thinning.
  VolumeU8 plate = plate_skeleton(m, 16);
  VolumeF32 dist = distance::euclidean(m);
  ThinningOptions to;
  to.end_point_length = 2;
  auto mixed = thin_doht(m, dist, &plate, to);
  EXPECT_GT(rod_voxels(mixed.skeleton), 10);  // the rod is back as a curve
  expect_homotopic(mixed.skeleton, m);
}

TEST(GeodesicPlates, GeodesicGuidedCurveIsCentredWhereDistanceOrderedThinningFollowsTheThickRim) {
  // Fig. 4.9: a flat ring (annulus between radii 6 and 18) whose outer rim is thicker. Its
  // one-dimensional skeleton is a loop; with the distance transform as priority the loop follows the
  // thick rim, with the geodesic importance it runs through the middle of the ring.
  const int64_t n = 44;
  VolumeU8 m(Dims{n, n, 16}, 0);
  const double c = (n - 1) / 2.0;
  for (int64_t z = 0; z < 16; ++z)
    for (int64_t y = 0; y < n; ++y)
      for (int64_t x = 0; x < n; ++x) {
        const double r = std::hypot(x - c, y - c);
        const double half = r > 15.0 ? 3.5 : 1.5;  // rim 7 voxels thick, ring 3 voxels thick
        if (r >= 6.0 && r <= 19.0 && std::abs(z - 7.5) <= half) m(x, y, z) = 1;
      }
  auto mean_radius = [&](const VolumeU8& s) {
    double sum = 0;
    int64_t k = 0;
    for (int64_t z = 0; z < 16; ++z)
      for (int64_t y = 0; y < n; ++y)
        for (int64_t x = 0; x < n; ++x)
          if (s(x, y, z)) {
            sum += std::hypot(x - c, y - c);
            ++k;
          }
    return k ? sum / static_cast<double>(k) : 0.0;
  };
  ThinningOptions to;
  to.end_point_length = 0;
  const auto by_distance = thin_doht(m, distance::euclidean(m), nullptr, to);
  Options full;
  full.mode = Mode::Full;
  const auto imp = boundary_distance(m, full).importance;
  const auto by_geodesic = thin_doht(m, imp, nullptr, to);
  const double rd = mean_radius(by_distance.skeleton), rg = mean_radius(by_geodesic.skeleton);
  std::printf("loop radius: distance-ordered %.2f, geodesic-guided %.2f (ring 6..19, rim from 15)\n", rd, rg);
  EXPECT_EQ(topology(by_geodesic.skeleton).tunnels, 1);
  EXPECT_GT(rd, 15.0);           // on the thick rim
  EXPECT_LT(rg, 15.0);           // inside the ring proper
  EXPECT_GT(rd - rg, 1.0);
}

TEST(RodsPlates, ClassifiesPlateAndRod) {
  const int64_t n = 40;
  VolumeU8 m = slab(Dims{n, n, n}, 4, 4, 2);
  for (int64_t z = 8; z < 36; ++z)
    for (int64_t y = 0; y < n; ++y)
      for (int64_t x = 0; x < n; ++x)
        if ((x - 20) * (x - 20) + (y - 20) * (y - 20) <= 5) m(x, y, z) = 1;
  Options o;
  o.threshold = 20;
  const auto g = boundary_distance(m, o);
  VolumeU8 plate = thin_surface(g.surface_skeleton).surface;
  const VolumeF32 dist = distance::euclidean(m);
  auto mixed = thin_doht(m, dist, &plate, {});
  auto r = rods_plates(m, mixed.skeleton, g.importance, dist);
  // Plate voxels far from the rod are plate, rod voxels far from the plate are rod.
  EXPECT_EQ(r.labels(8, 8, 5), 2);
  EXPECT_EQ(r.labels(20, 20, 30), 1);
  const auto& cls = r.table.strings("class");
  ASSERT_EQ(cls, (std::vector<std::string>{"rod", "plate"}));
  const auto& vox = r.table.ints("voxels");
  EXPECT_EQ(vox[0] + vox[1], count(m));
  EXPECT_GT(vox[1], 5 * vox[0]);
  EXPECT_EQ(r.table.ints("pieces")[0], 1);
}
