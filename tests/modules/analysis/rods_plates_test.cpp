// Rods and plates per skeleton element (thesis §6.2, fig. 6.14): segmentation of mixed skeletons into
// curve and surface elements, per-element classification (plate borders stay plate, where the
// per-voxel g/d threshold calls them rods), propagation to the object and the structural indices.
#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <map>
#include <set>

#include "analysis/names.hpp"
#include "analysis/rods_plates.hpp"
#include "distance/distance.hpp"
#include "geodesic/geodesic.hpp"
#include "geodesic/surface.hpp"
#include "skel/error.hpp"
#include "skel/run_module.hpp"
#include "thinning/thinning.hpp"

using namespace skel;
using namespace skel::analysis;

namespace {

int64_t count(const VolumeU8& v) {
  int64_t c = 0;
  for (auto x : v) c += x != 0;
  return c;
}

// One-voxel-thin square plate in the plane z = z0 over [lo, hi)^2.
void thin_plate(VolumeU8& s, int64_t z0, int64_t lo, int64_t hi) {
  for (int64_t y = lo; y < hi; ++y)
    for (int64_t x = lo; x < hi; ++x) s(x, y, z0) = 1;
}
// One-voxel-thin straight rod along z at (x, y) over [z0, z1].
void thin_rod(VolumeU8& s, int64_t x, int64_t y, int64_t z0, int64_t z1) {
  for (int64_t z = z0; z <= z1; ++z) s(x, y, z) = 1;
}

int64_t kinds(const SkeletonSegmentation& s, ElementKind k) {
  int64_t c = 0;
  for (auto e : s.kind) c += e == k;
  return c;
}

// The mixed skeleton as the bone pipeline makes it: plates from the geodesic boundary distance,
// thinned, locked during distance-ordered thinning.
struct Mixed {
  VolumeF32 distance;
  geodesic::Result geodesic;
  VolumeU8 skeleton;
};
Mixed mixed_skeleton(const VolumeU8& m, int64_t t) {
  Mixed r;
  r.distance = distance::euclidean(m);
  geodesic::Options o;
  o.threshold = t;
  r.geodesic = geodesic::boundary_distance(m, o);
  const VolumeU8 plates = geodesic::thin_surface(r.geodesic.surface_skeleton).surface;
  thinning::ThinningOptions to;
  to.end_point_length = 2;
  r.skeleton = thinning::thin_doht(m, r.distance, &plates, to).skeleton;
  return r;
}

// Thick slabs z in [z0, z0 + th) over [margin, n - margin)^2.
void slab(VolumeU8& m, int64_t z0, int64_t th, int64_t margin) {
  for (int64_t z = z0; z < z0 + th; ++z)
    for (int64_t y = margin; y < m.ny() - margin; ++y)
      for (int64_t x = margin; x < m.nx() - margin; ++x) m(x, y, z) = 1;
}
// Cylinder along z around (cx, cy) with radius r over [z0, z1).
void cylinder(VolumeU8& m, double cx, double cy, double r, int64_t z0, int64_t z1) {
  for (int64_t z = z0; z < z1; ++z)
    for (int64_t y = 0; y < m.ny(); ++y)
      for (int64_t x = 0; x < m.nx(); ++x)
        if (std::hypot(x - cx, y - cy) <= r) m(x, y, z) = 1;
}

}  // namespace

TEST(RodsPlatesElements, ThinPlatesJoinedByRodsGiveOneElementPerPlateAndRod) {
  // N = 3 stacked plates, M = 5 rods: 3 between plates 0 and 1, 2 between plates 1 and 2, plus one
  // dangling rod on the top plate (M = 6 in all). Every rod meets a plate at a 1-x-junction voxel.
  VolumeU8 s(Dims{32, 32, 40}, 0);
  thin_plate(s, 4, 4, 28);
  thin_plate(s, 16, 4, 28);
  thin_plate(s, 28, 4, 28);
  thin_rod(s, 8, 8, 5, 15);
  thin_rod(s, 20, 10, 5, 15);
  thin_rod(s, 12, 22, 5, 15);
  thin_rod(s, 10, 14, 17, 27);
  thin_rod(s, 22, 22, 17, 27);
  thin_rod(s, 16, 16, 29, 36);  // dangling: ends in a 1-boundary
  const auto seg = segment_skeleton(s);
  EXPECT_EQ(kinds(seg, ElementKind::surface), 3);
  EXPECT_EQ(kinds(seg, ElementKind::curve), 6);
  EXPECT_EQ(kinds(seg, ElementKind::cluster), 0);
  EXPECT_EQ(seg.junction_clusters, 11);  // two ends of five rods, one of the dangling one
  for (const auto& touched : seg.cluster_elements) EXPECT_EQ(touched.size(), 2u);  // a rod and a plate
  // Every skeleton voxel ends up in an element; rod voxels and plate voxels are never mixed.
  for (size_t i = 0; i < seg.voxels.size(); ++i) {
    ASSERT_GT(seg.element[i], 0);
    if (seg.own[i]) {
      EXPECT_EQ(seg.element[i], seg.own[i]);
    }
  }
  // Element ids in the order of their first voxel: the bottom plate is element 1.
  EXPECT_EQ(seg.kind[0], ElementKind::surface);

  // With a plate thickness from a distance map the patches classify as plates, the curves as rods.
  VolumeF32 d(s.grid(), 1.0f);
  const auto r = rods_plates_elements(s, s, d);
  EXPECT_EQ(r.indices.ints("plates")[0], 3);
  EXPECT_EQ(r.indices.ints("rods")[0], 6);
  EXPECT_EQ(r.indices.ints("rod_plate_junctions")[0], 11);
  EXPECT_EQ(r.indices.ints("junctions")[0], 11);
  // The junction voxels join the plates: each plate owns all of its 24 x 24 voxels.
  const auto& cls = r.table.strings("class");
  const auto& skv = r.table.ints("skeleton_voxels");
  for (size_t e = 0; e < cls.size(); ++e)
    if (cls[e] == "plate") {
      EXPECT_EQ(skv[e], 24 * 24);
    }
  // The interior rods have 9 voxels between their 1-x-junctions; length 9 voxel steps + 2 halves.
  const auto& length = r.table.reals("length");
  for (size_t e = 0; e < cls.size(); ++e)
    if (cls[e] == "rod" && skv[e] == 11) {
      EXPECT_NEAR(length[e], 11.0, 1e-9);
    }
}

TEST(RodsPlatesElements, PlateBorderStaysPlateWhereThePerVoxelRatioFlipsItToRod) {
  // A single plate, 4 voxels thick, with a thick border (a rim band 5 voxels wide and 10 thick), and
  // its medial surface (the mid-plane out to a voxel from the rim) as skeleton. Near the rim g/d
  // behaves as on a rod (thesis §6.2), so the per-voxel threshold calls border voxels rods; the element
  // method keeps the whole patch one plate.
  VolumeU8 m(Dims{56, 56, 16}, 0), skel(Dims{56, 56, 16}, 0);
  for (int64_t z = 0; z < 16; ++z)
    for (int64_t y = 4; y < 52; ++y)
      for (int64_t x = 4; x < 52; ++x) {
        const bool rim = x < 9 || y < 9 || x >= 47 || y >= 47;
        if ((z >= 6 && z < 10) || (rim && z >= 3 && z < 13)) m(x, y, z) = 1;
        if (z == 8 && x >= 5 && y >= 5 && x < 51 && y < 51) skel(x, y, z) = 1;
      }
  const VolumeF32 dist = distance::euclidean(m);
  geodesic::Options full;
  full.mode = geodesic::Mode::Full;
  const VolumeF32 importance = geodesic::boundary_distance(m, full).importance;
  const auto voxel = geodesic::rods_plates(m, skel, importance, dist);
  int64_t voxel_rods = 0, voxel_rod_skeleton = 0;
  for (auto c : voxel.labels) voxel_rods += c == 1;
  for (auto c : voxel.skeleton_labels) voxel_rod_skeleton += c == 1;
  std::printf("per voxel: %lld rod voxels (%lld on the skeleton) of %lld\n", static_cast<long long>(voxel_rods),
              static_cast<long long>(voxel_rod_skeleton), static_cast<long long>(count(m)));
  EXPECT_GT(voxel_rod_skeleton, 0) << "the per-voxel method should misclassify the plate border";

  const auto r = rods_plates_elements(m, skel, dist);
  EXPECT_EQ(r.indices.ints("plates")[0], 1);
  EXPECT_EQ(r.indices.ints("rods")[0], 0);
  int64_t rods = 0, plates = 0;
  for (auto c : r.classes) {
    rods += c == 1;
    plates += c == 2;
  }
  EXPECT_EQ(rods, 0);
  EXPECT_EQ(plates, count(m));
  EXPECT_DOUBLE_EQ(r.indices.reals("pBV_BV")[0], 1.0);
  // The per-voxel rods are on the border: every skeleton voxel it calls rod lies within the rim band.
  for (int64_t y = 0; y < 56; ++y)
    for (int64_t x = 0; x < 56; ++x)
      if (voxel.skeleton_labels(x, y, 8) == 1) {
        EXPECT_TRUE(x < 12 || y < 12 || x >= 44 || y >= 44) << x << "," << y;
      }
}

TEST(RodsPlatesElements, SlabsJoinedByCylindersDecomposeIntoTwoPlatesAndTheirRods) {
  // Two thick plates joined by two rods (the object, skeletonized as in pipelines/bone_plates.yaml).
  VolumeU8 m(Dims{48, 48, 40}, 0);
  slab(m, 4, 5, 4);
  slab(m, 30, 5, 4);
  cylinder(m, 15.0, 15.0, 2.2, 9, 30);
  cylinder(m, 32.0, 30.0, 2.2, 9, 30);
  const Mixed x = mixed_skeleton(m, 24);
  const auto r = rods_plates_elements(m, x.skeleton, x.distance);
  EXPECT_EQ(r.indices.ints("plates")[0], 2);
  EXPECT_EQ(r.indices.ints("rods")[0], 2);
  EXPECT_EQ(r.indices.ints("rod_plate_junctions")[0], 4);
  // Every object voxel is in an element; the class volume agrees with the element's class.
  const auto& cls = r.table.strings("class");
  const auto& vox = r.table.ints("voxels");
  int64_t sum = 0;
  for (auto v : vox) sum += v;
  EXPECT_EQ(sum, count(m));
  for (int64_t i = 0; i < m.size(); ++i) {
    if (!m[i]) {
      EXPECT_EQ(r.elements[i], 0);
      continue;
    }
    ASSERT_GT(r.elements[i], 0);
    EXPECT_EQ(r.classes[i], cls[static_cast<size_t>(r.elements[i] - 1)] == "plate" ? 2 : 1);
  }
  // The middle of a rod is rod, the middle of a plate far from the rods is plate.
  EXPECT_EQ(r.classes(15, 15, 20), 1);
  EXPECT_EQ(r.classes(40, 8, 6), 2);
  // Indices: the fractions add up, rods are about 4.4 thick and about 21 long.
  EXPECT_NEAR(r.indices.reals("rBV_BV")[0] + r.indices.reals("pBV_BV")[0], 1.0, 1e-12);
  EXPECT_NEAR(r.indices.reals("BV_TV")[0], static_cast<double>(count(m)) / static_cast<double>(m.size()), 1e-12);
  EXPECT_NEAR(r.indices.reals("rod_thickness")[0], 4.4, 1.5);
  EXPECT_GT(r.indices.reals("rod_length")[0], 15.0);
  EXPECT_LT(r.indices.reals("rod_length")[0], 28.0);
  EXPECT_NEAR(r.indices.reals("plate_thickness")[0], 5.0, 1.5);
}

TEST(RodsPlatesElements, SmallSurfaceFragmentIsARodAndIsolatedBlockIsAClusterElement) {
  VolumeU8 s(Dims{20, 20, 20}, 0);
  // A 3x3 surface patch with a thickness of 6: sqrt(9) < 2 x 6, so it is a rod.
  thin_plate(s, 5, 4, 7);
  // A solid 2x2x2 block (only junction voxels: the dual cube's 3-cell).
  for (int64_t z = 12; z < 14; ++z)
    for (int64_t y = 12; y < 14; ++y)
      for (int64_t x = 12; x < 14; ++x) s(x, y, z) = 1;
  VolumeF32 d(s.grid(), 3.0f);
  const auto r = rods_plates_elements(s, s, d);
  ASSERT_EQ(r.table.rows(), 2);
  EXPECT_EQ(r.table.strings("kind")[0], "surface");
  EXPECT_EQ(r.table.strings("kind")[1], "cluster");
  EXPECT_EQ(r.indices.ints("rods")[0], 2);
  EXPECT_EQ(r.indices.ints("plates")[0], 0);
  // A lower aspect makes the patch a plate.
  RodsPlatesElementOptions o;
  o.plate_aspect = 0.4;
  const auto r2 = rods_plates_elements(s, s, d, o);
  EXPECT_EQ(r2.indices.ints("plates")[0], 1);
  EXPECT_EQ(r2.classes(5, 5, 5), 2);
}

TEST(RodsPlatesElements, ResultDoesNotDependOnThreads) {
  VolumeU8 m(Dims{40, 40, 36}, 0);
  slab(m, 3, 5, 3);
  slab(m, 27, 5, 3);
  cylinder(m, 12.0, 14.0, 2.0, 8, 27);
  cylinder(m, 28.0, 26.0, 2.5, 8, 27);
  const Mixed x = mixed_skeleton(m, 24);
  RodsPlatesElementOptions one, four;
  one.threads = 1;
  four.threads = 4;
  const auto a = rods_plates_elements(m, x.skeleton, x.distance, one);
  const auto b = rods_plates_elements(m, x.skeleton, x.distance, four);
  for (int64_t i = 0; i < m.size(); ++i) ASSERT_EQ(a.elements[i], b.elements[i]);
  EXPECT_EQ(a.table.to_csv(), b.table.to_csv());
  EXPECT_EQ(a.indices.to_csv(), b.indices.to_csv());
}

TEST(RodsPlatesElements, ModulePortsUnitsAndErrors) {
  VolumeU8 s(Dims{32, 32, 24}, 0);
  thin_plate(s, 4, 4, 28);
  thin_rod(s, 10, 10, 5, 18);
  Grid g = s.grid();
  g.spacing = {0.5, 0.5, 0.5};
  g.unit = "mm";
  auto skel = std::make_shared<VolumeU8>(g, 0);
  for (int64_t i = 0; i < s.size(); ++i) (*skel)[i] = s[i];
  auto dist = std::make_shared<VolumeF32>(g, 0.25f);  // a plate one voxel (0.5 mm) thick
  const auto r = run_module(names::rods_plates_elements, {{"mask", skel}, {"skeleton", skel}, {"distance", dist}});
  const auto idx = r.get<Table>("indices");
  EXPECT_EQ(idx->ints("plates")[0], 1);
  EXPECT_EQ(idx->ints("rods")[0], 1);
  EXPECT_EQ(idx->column("plate_area").unit, "mm²");
  EXPECT_DOUBLE_EQ(idx->reals("plate_thickness")[0], 0.5);
  EXPECT_DOUBLE_EQ(idx->reals("plate_area")[0], 24.0 * 24.0 * 0.25);  // volume / thickness
  EXPECT_EQ(idx->column("rod_length").unit, "mm");
  EXPECT_EQ(r.get<Table>("table")->column("volume").unit, "mm³");
  EXPECT_EQ(r.get<VolumeI32>("elements")->grid().unit, "mm");
  EXPECT_EQ(r.get<VolumeU8>("classes")->at_or(10, 10, 10, 0), 1);
  EXPECT_TRUE(r.warnings.empty());

  // A distance on another grid names the input.
  auto small = std::make_shared<VolumeF32>(Dims{8, 8, 8}, 1.0f);
  try {
    run_module(names::rods_plates_elements, {{"mask", skel}, {"skeleton", skel}, {"distance", small}});
    FAIL() << "expected InputError";
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("'distance'"), std::string::npos) << e.what();
  }
  // An empty skeleton warns and gives empty tables.
  auto empty = std::make_shared<VolumeU8>(g, 0);
  const auto re = run_module(names::rods_plates_elements, {{"mask", skel}, {"skeleton", empty}, {"distance", dist}});
  ASSERT_EQ(re.warnings.size(), 1u);
  EXPECT_EQ(re.get<Table>("table")->rows(), 0);
  EXPECT_EQ(re.get<Table>("indices")->ints("rods")[0], 0);
}

TEST(RodsPlatesElements, InclinedPlateIsOnePlate) {
  // A slab 5 voxels thick whose mid-plane is inclined (normal (1, 1, 1)/sqrt 3): its digital plate
  // skeleton is a staircase of voxels, still one surface patch and one plate.
  const int64_t n = 48;
  VolumeU8 m(Dims{n, n, n}, 0);
  const double c = (n - 1) * 1.5, s3 = std::sqrt(3.0);
  for (int64_t z = 0; z < n; ++z)
    for (int64_t y = 0; y < n; ++y)
      for (int64_t x = 0; x < n; ++x) {
        const double h = (static_cast<double>(x + y + z) - c) / s3;
        const double r2 = (x - 23.5) * (x - 23.5) + (y - 23.5) * (y - 23.5) + (z - 23.5) * (z - 23.5) - h * h;
        if (std::abs(h) <= 2.5 && r2 <= 18.0 * 18.0) m(x, y, z) = 1;
      }
  const Mixed x = mixed_skeleton(m, 24);
  const auto r = rods_plates_elements(m, x.skeleton, x.distance);
  EXPECT_EQ(r.indices.ints("plates")[0], 1);
  EXPECT_EQ(r.indices.ints("rods")[0], 0);
  EXPECT_DOUBLE_EQ(r.indices.reals("pBV_BV")[0], 1.0);
  // Thickness about 5, area about that of the disk of radius 18 (volume / thickness).
  EXPECT_NEAR(r.indices.reals("plate_thickness")[0], 5.0, 0.6);
  EXPECT_NEAR(r.indices.reals("plate_area")[0], 3.14159 * 18.0 * 18.0, 0.15 * 3.14159 * 18.0 * 18.0);
}
