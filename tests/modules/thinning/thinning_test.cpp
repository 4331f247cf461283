// Distance ordered homotopic thinning: topological invariants, shapes, end points, determinism.
#include <gtest/gtest.h>

#include <cstdio>
#include <random>

#include "distance/distance.hpp"
#include "shapes.hpp"
#include "synthetic/network.hpp"
#include "thinning/thinning.hpp"
#include "analysis/topology.hpp"
#include "thinning/local_topology.hpp"

using namespace skel::thinning;
using namespace skel::analysis;

namespace skel {
namespace {

ThinningOptions opts(ThinningVariant v, int l, int threads = 1) {
  ThinningOptions o;
  o.variant = v;
  o.end_point_length = l;
  o.threads = threads;
  return o;
}

int neighbours_in(const VolumeU8& s, int64_t x, int64_t y, int64_t z) {
  return __builtin_popcount(neighbourhood_at(s, x, y, z));
}

struct SkeletonCheck {
  int64_t voxels = 0, end_points = 0, simple_left = 0, outside_object = 0;
};

// Checks that every skeleton voxel is object, and counts end points and simple voxels that are
// neither locked nor end points.
SkeletonCheck check_skeleton(const VolumeU8& object, const VolumeU8& skel, const VolumeU8* locked = nullptr) {
  SkeletonCheck c;
  for (int64_t z = 0; z < skel.nz(); ++z)
    for (int64_t y = 0; y < skel.ny(); ++y)
      for (int64_t x = 0; x < skel.nx(); ++x) {
        if (!skel(x, y, z)) continue;
        ++c.voxels;
        if (!object(x, y, z)) ++c.outside_object;
        const uint32_t nb = neighbourhood_at(skel, x, y, z);
        const bool end = __builtin_popcount(nb) == 1;
        c.end_points += end;
        if (is_simple(nb) && !end && !(locked && (*locked)(x, y, z))) ++c.simple_left;
      }
  return c;
}

void expect_same_topology(const VolumeU8& object, const VolumeU8& skel, const std::string& what) {
  const TopologyNumbers a = topology(object), b = topology(skel);
  EXPECT_EQ(a.components, b.components) << what;
  EXPECT_EQ(a.cavities, b.cavities) << what;
  EXPECT_EQ(a.euler, b.euler) << what;
  EXPECT_EQ(a.tunnels, b.tunnels) << what;
}

TEST(Thinning, InvariantsOnRandomBlobs) {
  for (uint32_t seed = 1; seed <= 6; ++seed) {
    const VolumeU8 m = test::random_blobs(28, seed, 0.47 + 0.01 * (seed % 4), 2);
    const VolumeU32 d = test::chamfer345(m);
    for (auto v : {ThinningVariant::Basic, ThinningVariant::Smooth})
      for (int l : {0, 1, 3}) {
        const ThinningResult r = thin_doht(m, d, nullptr, opts(v, l));
        const std::string what = "seed " + std::to_string(seed) + " l " + std::to_string(l) +
                                 (v == ThinningVariant::Basic ? " basic" : " smooth");
        expect_same_topology(m, r.skeleton, what);
        const SkeletonCheck c = check_skeleton(m, r.skeleton);
        EXPECT_EQ(c.outside_object, 0) << what;
        EXPECT_EQ(c.simple_left, 0) << what;
        if (l == 0) {
          EXPECT_EQ(c.end_points, 0) << what;
        }
        EXPECT_EQ(c.voxels, r.stats.skeleton_voxels) << what;
        EXPECT_LT(c.voxels, r.stats.object_voxels / 4) << what;
      }
  }
}

// Thesis ch. 4 objects (synthetic.network): rods, plates, spheres and mixtures, clean and noisy.
TEST(Thinning, InvariantsOnSyntheticNetworks) {
  for (const char* shape : {"rods", "plates", "spheres", "mixed"})
    for (double noise : {0.0, 0.6}) {
      synthetic::NetworkOptions no;
      no.shape = parse_enum<synthetic::Shape>(shape, "shape");
      no.size = {64, 64, 64};
      no.noise = noise;
      no.seed = 7;
      no.threads = 2;
      const VolumeU8 m = synthetic::make_network(no).mask;
      const VolumeU32 d = test::chamfer345(m);
      const TopologyNumbers tm = topology(m);
      for (auto v : {ThinningVariant::Basic, ThinningVariant::Smooth})
        for (int l : {0, 2}) {
          const ThinningResult r = thin_doht(m, d, nullptr, opts(v, l, 2));
          const std::string what = std::string(shape) + " noise " + std::to_string(noise) + " l " +
                                   std::to_string(l) + (v == ThinningVariant::Basic ? " basic" : " smooth");
          const TopologyNumbers ts = topology(r.skeleton);
          EXPECT_EQ(ts.components, tm.components) << what;
          EXPECT_EQ(ts.cavities, tm.cavities) << what;
          EXPECT_EQ(ts.euler, tm.euler) << what;
          const SkeletonCheck c = check_skeleton(m, r.skeleton);
          EXPECT_EQ(c.outside_object, 0) << what;
          EXPECT_EQ(c.simple_left, 0) << what;
          EXPECT_LT(c.voxels, tm.object_voxels / 5) << what;
        }
      std::printf("%s noise %.1f: %lld voxels, components %lld cavities %lld tunnels %lld\n", shape, noise,
                  static_cast<long long>(tm.object_voxels), static_cast<long long>(tm.components),
                  static_cast<long long>(tm.cavities), static_cast<long long>(tm.tunnels));
    }
}

TEST(Thinning, IdenticalForAnyThreadCount) {
  const VolumeU8 m = test::random_blobs(40, 5, 0.48, 2);
  const VolumeU32 d = test::chamfer345(m);
  VolumeF32 df(m.dims(), 0.0f);
  for (int64_t i = 0; i < m.size(); ++i) df[i] = std::sqrt(static_cast<float>(d[i]));
  for (auto v : {ThinningVariant::Basic, ThinningVariant::Smooth}) {
    const ThinningResult r1 = thin_doht(m, df, nullptr, opts(v, 2, 1));
    for (int t : {2, 4}) {
      const ThinningResult rt = thin_doht(m, df, nullptr, opts(v, 2, t));
      EXPECT_TRUE(rt.skeleton == r1.skeleton) << t << " threads";
      EXPECT_EQ(rt.stats.tests, r1.stats.tests);
    }
  }
}

TEST(Thinning, Uint8AndUint16ChamferPrioritiesGiveTheSameSkeleton) {
  // distance::chamfer with `narrow` gives uint8 distances equal to the uint16 ones: thin_doht ranks
  // both into the same levels, so the skeleton and every statistic are the same (random blobs and
  // the rods/plates phantoms, both variants, 1 and 2 threads).
  std::vector<VolumeU8> masks;
  for (uint32_t seed = 1; seed <= 4; ++seed) masks.push_back(test::random_blobs(36, seed, 0.46 + 0.01 * seed, 2));
  for (const char* shape : {"rods", "plates"}) {
    synthetic::NetworkOptions no;
    no.shape = parse_enum<synthetic::Shape>(shape, "shape");
    no.size = {72, 64, 56};
    no.seed = 3;
    no.threads = 2;
    masks.push_back(synthetic::make_network(no).mask);
  }
  for (size_t k = 0; k < masks.size(); ++k) {
    const VolumeU8& m = masks[k];
    distance::ChamferOptions co;
    const DataPtr d16 = distance::chamfer(m, co);
    co.narrow = true;
    const DataPtr d8 = distance::chamfer(m, co);
    ASSERT_TRUE(std::dynamic_pointer_cast<const VolumeU16>(d16));
    ASSERT_TRUE(std::dynamic_pointer_cast<const VolumeU8>(d8)) << d8->type_id();
    for (auto v : {ThinningVariant::Basic, ThinningVariant::Smooth})
      for (int t : {1, 2}) {
        const std::string what = "mask " + std::to_string(k) + (v == ThinningVariant::Basic ? " basic " : " smooth ") +
                                 std::to_string(t) + " threads";
        const ThinningResult a = thin_doht(m, *d16, nullptr, opts(v, 2, t));
        const ThinningResult b = thin_doht(m, *d8, nullptr, opts(v, 2, t));
        EXPECT_TRUE(a.skeleton == b.skeleton) << what;
        EXPECT_EQ(a.stats.priority_levels, b.stats.priority_levels) << what;
        EXPECT_EQ(a.stats.tests, b.stats.tests) << what;
        EXPECT_EQ(a.stats.removed, b.stats.removed) << what;
        EXPECT_EQ(a.stats.sub_iterations, b.stats.sub_iterations) << what;
        EXPECT_GT(a.stats.removed, 0) << what;
        expect_same_topology(m, b.skeleton, what);
      }
  }
}

TEST(Thinning, InPlaceGivesTheSameSkeletonAndStatistics) {
  // thin_doht_in_place thins in the mask's own buffer (the state is written after the scan that
  // reads the mask's neighbours): the same skeleton and statistics as thin_doht, with and without
  // locks, for a float and an integer priority, on a mask whose object voxels are not all 1.
  VolumeU8 m = test::random_blobs(40, 5, 0.48, 2);
  for (int64_t i = 0; i < m.size(); i += 3)
    if (m[i]) m[i] = 255;
  const VolumeU32 d = test::chamfer345(m);
  VolumeF32 df(m.dims(), 0.0f);
  for (int64_t i = 0; i < m.size(); ++i) df[i] = std::sqrt(static_cast<float>(d[i]));
  VolumeU8 locks(m.dims(), 0);
  for (int64_t i = 0; i < m.size(); i += 97) locks[i] = 1;
  for (auto v : {ThinningVariant::Basic, ThinningVariant::Smooth})
    for (int t : {1, 2})
      for (const VolumeU8* lk : {static_cast<const VolumeU8*>(nullptr), static_cast<const VolumeU8*>(&locks)})
        for (const DataObject* pr : {static_cast<const DataObject*>(&df), static_cast<const DataObject*>(&d)}) {
          const ThinningResult ref = thin_doht(m, *pr, lk, opts(v, 2, t));
          VolumeU8 buf = m;
          const ThinningResult ip = thin_doht_in_place(buf, *pr, lk, opts(v, 2, t));
          EXPECT_EQ(ip.skeleton.size(), 0);
          EXPECT_TRUE(buf == ref.skeleton) << t << " threads";
          EXPECT_EQ(ip.stats.tests, ref.stats.tests);
          EXPECT_EQ(ip.stats.removed, ref.stats.removed);
          EXPECT_EQ(ip.stats.skeleton_voxels, ref.stats.skeleton_voxels);
          EXPECT_EQ(ip.stats.locked_voxels, ref.stats.locked_voxels);
          EXPECT_GT(ref.stats.removed, 0);
        }
  VolumeU8 self = m;
  EXPECT_THROW((void)thin_doht_in_place(self, df, &self, opts(ThinningVariant::Smooth, 2, 1)), Error);
}

TEST(Thinning, CylinderBecomesCentredLine) {
  VolumeU8 m(Dims{48, 17, 17}, 0);
  test::add_cylinder_x(m, 4, 43, 8, 8, 5.2);
  const VolumeU32 d = test::chamfer345(m);
  for (auto v : {ThinningVariant::Basic, ThinningVariant::Smooth}) {
    const ThinningResult r = thin_doht(m, d, nullptr, opts(v, 2));
    const SkeletonCheck c = check_skeleton(m, r.skeleton);
    EXPECT_EQ(c.end_points, 2);
    expect_same_topology(m, r.skeleton, "cylinder");
    int64_t xmin = 1000, xmax = -1;
    for (int64_t z = 0; z < m.nz(); ++z)
      for (int64_t y = 0; y < m.ny(); ++y)
        for (int64_t x = 0; x < m.nx(); ++x) {
          if (!r.skeleton(x, y, z)) continue;
          EXPECT_LE(std::abs(y - 8), 1);
          EXPECT_LE(std::abs(z - 8), 1);
          EXPECT_LE(neighbours_in(r.skeleton, x, y, z), 2);  // one voxel wide
          xmin = std::min(xmin, x);
          xmax = std::max(xmax, x);
        }
    EXPECT_EQ(c.voxels, xmax - xmin + 1);  // one voxel per x: a line along the axis
    EXPECT_GE(xmax - xmin, 40 - 2 * 6);
    std::printf("cylinder: %lld voxels, x %lld..%lld\n", static_cast<long long>(c.voxels),
                static_cast<long long>(xmin), static_cast<long long>(xmax));
    const ThinningResult r0 = thin_doht(m, d, nullptr, opts(v, 0));
    EXPECT_EQ(r0.stats.skeleton_voxels, 1);
  }
}

TEST(Thinning, TorusBecomesClosedLoop) {
  const VolumeU8 m = test::torus(32, 9, 3.5);
  const VolumeU32 d = test::chamfer345(m);
  for (auto v : {ThinningVariant::Basic, ThinningVariant::Smooth}) {
    const ThinningResult r = thin_doht(m, d, nullptr, opts(v, 2));
    const TopologyNumbers t = topology(r.skeleton);
    EXPECT_EQ(t, (TopologyNumbers{t.object_voxels, 1, 0, 0, 1}));
    // A closed curve: every voxel's neighbours form exactly two 26-components.
    for (int64_t z = 0; z < m.nz(); ++z)
      for (int64_t y = 0; y < m.ny(); ++y)
        for (int64_t x = 0; x < m.nx(); ++x)
          if (r.skeleton(x, y, z)) {
            EXPECT_EQ(object_components26(neighbourhood_at(r.skeleton, x, y, z)), 2);
            EXPECT_LE(std::abs(z - 15.5), 1.0);
          }
    EXPECT_EQ(check_skeleton(m, r.skeleton).end_points, 0);
    std::printf("torus loop: %lld voxels\n", static_cast<long long>(t.object_voxels));
  }
}

TEST(Thinning, HollowSphereBecomesClosedSurface) {
  VolumeU8 m(Dims{30, 30, 30}, 0);
  test::add_ball(m, 14.5, 14.5, 14.5, 12.5);
  test::add_ball(m, 14.5, 14.5, 14.5, 6.5, 0);
  const VolumeU32 d = test::chamfer345(m);
  for (auto v : {ThinningVariant::Basic, ThinningVariant::Smooth}) {
    const ThinningResult r = thin_doht(m, d, nullptr, opts(v, 0));
    const TopologyNumbers t = topology(r.skeleton);
    EXPECT_EQ(t, (TopologyNumbers{t.object_voxels, 1, 1, 2, 0}));
    EXPECT_EQ(r.stats.interior_voxels, 0);
    const SkeletonCheck c = check_skeleton(m, r.skeleton);
    EXPECT_EQ(c.simple_left, 0);
    // A thin surface: far fewer voxels than the shell, at least the area of the inner sphere.
    EXPECT_LT(c.voxels, r.stats.object_voxels / 3);
    EXPECT_GT(c.voxels, 4 * 3.14 * 6.5 * 6.5);
    std::printf("hollow sphere: %lld of %lld voxels\n", static_cast<long long>(c.voxels),
                static_cast<long long>(r.stats.object_voxels));
  }
}

TEST(Thinning, SolidBallBecomesOneVoxel) {
  VolumeU8 m(Dims{25, 25, 25}, 0);
  test::add_ball(m, 12, 12, 12, 10.3);
  const VolumeU32 d = test::chamfer345(m);
  for (auto v : {ThinningVariant::Basic, ThinningVariant::Smooth}) {
    const ThinningResult r = thin_doht(m, d, nullptr, opts(v, 0));
    ASSERT_EQ(r.stats.skeleton_voxels, 1);
    int64_t x = -1, y = -1, z = -1;
    for (int64_t k = 0; k < m.size(); ++k)
      if (r.skeleton[k]) {
        x = k % 25;
        y = (k / 25) % 25;
        z = k / 625;
      }
    EXPECT_LE(std::abs(x - 12) + std::abs(y - 12) + std::abs(z - 12), 3);  // near the centre
  }
}

TEST(Thinning, LockedVoxelsStay) {
  const VolumeU8 m = test::random_blobs(24, 11, 0.48, 2);
  const VolumeU32 d = test::chamfer345(m);
  VolumeU8 locked(m.dims(), 0);
  std::mt19937 rng(5);
  int64_t n_locked = 0;
  for (int64_t i = 0; i < m.size(); ++i)
    if (m[i] && rng() % 50 == 0) {
      locked[i] = 1;
      ++n_locked;
    }
  for (auto v : {ThinningVariant::Basic, ThinningVariant::Smooth}) {
    const ThinningResult r = thin_doht(m, d, &locked, opts(v, 0));
    for (int64_t i = 0; i < m.size(); ++i)
      if (locked[i]) {
        ASSERT_EQ(r.skeleton[i], 1);
      }
    EXPECT_EQ(r.stats.locked_voxels, n_locked);
    expect_same_topology(m, r.skeleton, "locked");
    EXPECT_EQ(check_skeleton(m, r.skeleton, &locked).simple_left, 0);
  }
}

// Thesis fig. 2.23: a contractible configuration without simple voxels. Thinning stops (no loop),
// keeps the topology and reports the configuration as stuck.
TEST(Thinning, LockedConfigurationIsReported) {
  for (int w : {1, 2}) {
    const VolumeU8 m = test::bing_house(w);
    EXPECT_EQ(topology(m), (TopologyNumbers{topology(m).object_voxels, 1, 0, 1, 0}));
    const VolumeU32 d = test::chamfer345(m);
    for (auto v : {ThinningVariant::Basic, ThinningVariant::Smooth})
      for (int l : {0, 2}) {
        const ThinningResult r = thin_doht(m, d, nullptr, opts(v, l));
        expect_same_topology(m, r.skeleton, "bing");
        EXPECT_EQ(check_skeleton(m, r.skeleton).simple_left, 0);
        EXPECT_GT(r.stats.skeleton_voxels, 1);
        EXPECT_EQ(r.stats.stuck_components, 1);
        EXPECT_EQ(r.stats.stuck_voxels, r.stats.skeleton_voxels);
      }
  }
  // A contractible object that thins to a single voxel is not reported.
  VolumeU8 ball(Dims{15, 15, 15}, 0);
  test::add_ball(ball, 7, 7, 7, 5.5);
  EXPECT_EQ(thin_doht(ball, test::chamfer345(ball), nullptr, opts(ThinningVariant::Smooth, 0)).stats.stuck_components, 0);
}

int count_end_points(const VolumeU8& s) {
  int c = 0;
  for (int64_t z = 0; z < s.nz(); ++z)
    for (int64_t y = 0; y < s.ny(); ++y)
      for (int64_t x = 0; x < s.nx(); ++x)
        if (s(x, y, z) && neighbours_in(s, x, y, z) == 1) ++c;
  return c;
}

// Thesis fig. 4.1: on rods with surface noise, l = 1 keeps spurs, l >= 2 keeps exactly the end
// points of the clean phantom (its four free branches).
TEST(Thinning, EndPointImportanceSuppressesNoiseSpurs) {
  const VolumeU8 clean = test::rods_clean();
  VolumeU8 noisy = clean;
  std::mt19937 rng(3);
  int bumps = 0;
  for (int k = 0; k < 20000 && bumps < 250; ++k) {
    const int64_t x = rng() % 64, y = rng() % 64, z = rng() % 64;
    if (!clean(x, y, z)) continue;
    const uint32_t nb = neighbourhood_at(clean, x, y, z);
    const uint32_t faces = (1u << neighbour_bit(1, 0, 0)) | (1u << neighbour_bit(-1, 0, 0)) |
                           (1u << neighbour_bit(0, 1, 0)) | (1u << neighbour_bit(0, -1, 0)) |
                           (1u << neighbour_bit(0, 0, 1)) | (1u << neighbour_bit(0, 0, -1));
    if ((nb & faces) == faces) continue;  // centre bumps on surface voxels
    // Euler change of the bump, measured on a crop around it (windows away from the bump do not change).
    auto crop = [&](const VolumeU8& v) {
      VolumeU8 c(Dims{15, 15, 15}, 0);
      for (int64_t k = 0; k < c.size(); ++k)
        c[k] = v.at_or(x - 7 + k % 15, y - 7 + (k / 15) % 15, z - 7 + k / 225, 0);
      return c;
    };
    VolumeU8 trial = noisy;
    const double ox = static_cast<double>(rng() % 3) - 1.0, oy = static_cast<double>(rng() % 3) - 1.0,
                 oz = static_cast<double>(rng() % 3) - 1.0, r = 1.0 + static_cast<double>(rng() % 2) * 0.5;
    test::add_ball(trial, static_cast<double>(x) + ox, static_cast<double>(y) + oy, static_cast<double>(z) + oz, r);
    if (topology(crop(trial)).euler != topology(crop(noisy)).euler) continue;  // no new loops or cavities
    noisy = std::move(trial);
    ++bumps;
  }
  ASSERT_GE(bumps, 200);
  expect_same_topology(clean, noisy, "noisy phantom");
  const VolumeU32 dc = test::chamfer345(clean), dn = test::chamfer345(noisy);
  for (auto v : {ThinningVariant::Basic, ThinningVariant::Smooth}) {
    const int clean_ends = count_end_points(thin_doht(clean, dc, nullptr, opts(v, 2)).skeleton);
    EXPECT_EQ(clean_ends, 4);
    EXPECT_EQ(count_end_points(thin_doht(clean, dc, nullptr, opts(v, 1)).skeleton), 4);
    const int noisy1 = count_end_points(thin_doht(noisy, dn, nullptr, opts(v, 1)).skeleton);
    EXPECT_GE(noisy1, clean_ends + 2) << "l = 1 keeps spurs";
    for (int l : {2, 3, 5}) {
      const ThinningResult r = thin_doht(noisy, dn, nullptr, opts(v, l));
      EXPECT_EQ(count_end_points(r.skeleton), clean_ends) << "l = " << l;
      expect_same_topology(noisy, r.skeleton, "noisy rods");
    }
    EXPECT_EQ(count_end_points(thin_doht(noisy, dn, nullptr, opts(v, 0)).skeleton), 0);
    std::printf("%s: clean %d end points; noisy l=1: %d\n", v == ThinningVariant::Basic ? "basic" : "smooth",
                clean_ends, noisy1);
  }
}

// Smooth DOHT on a box shell with an even wall thickness (two-voxel layers of equal distance in the
// middle, fig. 2.15): the closed surface lies in the middle two layers and is one voxel thick.
TEST(Thinning, SmoothSurfaceIsCentred) {
  VolumeU8 m(Dims{26, 26, 26}, 0);
  for (int64_t z = 1; z < 25; ++z)
    for (int64_t y = 1; y < 25; ++y)
      for (int64_t x = 1; x < 25; ++x) {
        const bool inner = x >= 5 && y >= 5 && z >= 5 && x < 21 && y < 21 && z < 21;
        m(x, y, z) = inner ? 0 : 1;  // walls 4 voxels thick: layers 1..4, middle layers 2 and 3
      }
  const VolumeU32 d = test::chamfer345(m);
  const ThinningResult r = thin_doht(m, d, nullptr, opts(ThinningVariant::Smooth, 0));
  const TopologyNumbers t = topology(r.skeleton);
  EXPECT_EQ(t, (TopologyNumbers{t.object_voxels, 1, 1, 2, 0}));
  EXPECT_EQ(r.stats.interior_voxels, 0);
  int64_t off_centre = 0;
  for (int64_t z = 0; z < 26; ++z)
    for (int64_t y = 0; y < 26; ++y)
      for (int64_t x = 0; x < 26; ++x) {
        if (!r.skeleton(x, y, z)) continue;
        // depth of the voxel inside the wall it belongs to (1 = outer layer, 4 = inner layer)
        const int64_t depth = std::min({x, y, z, 25 - x, 25 - y, 25 - z});
        if (depth < 2 || depth > 3) ++off_centre;
      }
  EXPECT_EQ(off_centre, 0);
  std::printf("box shell surface: %lld voxels\n", static_cast<long long>(t.object_voxels));
}

TEST(Thinning, RejectsBadInputs) {
  VolumeU8 m(Dims{4, 4, 4}, 1);
  VolumeU8 p(Dims{4, 4, 5}, 1);
  EXPECT_THROW(thin_doht(m, p), InputError);
  VolumeF32 nan(Dims{4, 4, 4}, std::nanf(""));
  EXPECT_THROW(thin_doht(m, nan), InputError);
  ThinningOptions o;
  o.end_point_length = -1;
  EXPECT_THROW(thin_doht(m, m, nullptr, o), InputError);
  EXPECT_THROW(parse_enum<ThinningVariant>("fast", "variant"), InputError);
  VolumeU8 empty(Dims{5, 5, 5}, 0);
  EXPECT_EQ(thin_doht(empty, empty).stats.skeleton_voxels, 0);
}

}  // namespace
}  // namespace skel
