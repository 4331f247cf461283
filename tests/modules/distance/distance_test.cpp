// Distance transforms against brute-force references: Euclidean DT, feature transform and seeded
// distance = min over all background (seed) voxels; chamfer = Dijkstra on the 26-graph; chamfer b(p) =
// a literal padded-array implementation of the thesis raster scans.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <limits>
#include <optional>
#include <queue>
#include <random>
#include <vector>

#include "distance/distance.hpp"

namespace skel::distance {
namespace {

constexpr uint32_t OUT32 = kOutside32;

VolumeU8 random_mask(std::mt19937& rng, Dims dims, double p_object, Vec3 spacing = {1, 1, 1}) {
  VolumeU8 m(dims, 0, spacing);
  std::bernoulli_distribution obj(p_object);
  std::uniform_int_distribution<int> val(1, 255);
  for (auto& v : m) v = obj(rng) ? static_cast<uint8_t>(val(rng)) : 0;
  return m;
}

Dims random_dims(std::mt19937& rng, int max_n = 9) {
  std::uniform_int_distribution<int64_t> d(1, max_n);
  return {d(rng), d(rng), d(rng)};
}

struct BruteResult {
  std::vector<double> sq;        // squared physical distance
  std::vector<uint32_t> nearest;  // index or OUT32
};

// min over every site (background voxel, or the one-voxel ring outside the array when `ring`); ties
// go to the lexicographically smallest (z, y, x), ring coordinates being -1 or n.
template <class IsSite>
BruteResult brute_force(const Grid& g, IsSite is_site, bool ring) {
  const int64_t nx = g.dims[0], ny = g.dims[1], nz = g.dims[2];
  BruteResult r;
  r.sq.assign(static_cast<size_t>(g.voxel_count()), std::numeric_limits<double>::infinity());
  r.nearest.assign(static_cast<size_t>(g.voxel_count()), OUT32);
  for (int64_t z = 0; z < nz; ++z)
    for (int64_t y = 0; y < ny; ++y)
      for (int64_t x = 0; x < nx; ++x) {
        const size_t i = static_cast<size_t>(g.index(x, y, z));
        for (int64_t qz = -1; qz <= nz; ++qz)
          for (int64_t qy = -1; qy <= ny; ++qy)
            for (int64_t qx = -1; qx <= nx; ++qx) {
              const bool inside = g.contains(qx, qy, qz);
              if (inside ? !is_site(g.index(qx, qy, qz)) : !ring) continue;
              const double dx = static_cast<double>(x - qx) * g.spacing[0];
              const double dy = static_cast<double>(y - qy) * g.spacing[1];
              const double dz = static_cast<double>(z - qz) * g.spacing[2];
              const double d = dx * dx + dy * dy + dz * dz;
              if (d < r.sq[i]) {
                r.sq[i] = d;
                r.nearest[i] = inside ? static_cast<uint32_t>(g.index(qx, qy, qz)) : OUT32;
              }
            }
      }
  return r;
}

void expect_close(double expected, double got, const char* what, int64_t i) {
  if (std::isinf(expected)) {
    EXPECT_TRUE(std::isinf(got)) << what << " voxel " << i;
  } else {
    EXPECT_NEAR(expected, got, 1e-5 * (1.0 + expected)) << what << " voxel " << i;
  }
}

TEST(Euclidean, EqualsBruteForceIsotropic) {
  std::mt19937 rng(1);
  for (int trial = 0; trial < 150; ++trial) {
    const bool border = trial % 3 == 2;
    const double s = trial % 4 == 3 ? 0.5 : 1.0;
    VolumeU8 m = random_mask(rng, random_dims(rng), 0.3 + 0.65 * (trial % 5) / 4.0, {s, s, s});
    const uint8_t* md = m.data();
    BruteResult ref = brute_force(m.grid(), [&](int64_t i) { return md[i] == 0; }, !border);
    EuclideanOptions o;
    o.border_is_object = border;
    o.threads = 2;
    VolumeF32 d = euclidean(m, o);
    o.squared = true;
    VolumeF32 d2 = euclidean(m, o);
    DistanceOptions fo;
    fo.border_is_object = border;
    VolumeU32 ft = feature_transform_as<uint32_t>(m, fo);
    for (int64_t i = 0; i < m.size(); ++i) {
      expect_close(std::sqrt(ref.sq[static_cast<size_t>(i)]), d[i], "distance", i);
      expect_close(ref.sq[static_cast<size_t>(i)], d2[i], "squared", i);
      // isotropic: squared distances are exact integers (times s^2), ties follow the documented rule
      EXPECT_EQ(ref.nearest[static_cast<size_t>(i)], ft[i]) << "trial " << trial << " voxel " << i;
    }
  }
}

TEST(Euclidean, EqualsBruteForceAnisotropic) {
  std::mt19937 rng(2);
  std::uniform_real_distribution<double> sp(0.3, 3.0);
  for (int trial = 0; trial < 120; ++trial) {
    const bool border = trial % 3 == 2;
    const Vec3 spacing{sp(rng), sp(rng), trial % 2 ? 2.0 : sp(rng)};
    VolumeU8 m = random_mask(rng, random_dims(rng), 0.4 + 0.55 * (trial % 4) / 3.0, spacing);
    const uint8_t* md = m.data();
    BruteResult ref = brute_force(m.grid(), [&](int64_t i) { return md[i] == 0; }, !border);
    EuclideanOptions o;
    o.border_is_object = border;
    VolumeF32 d = euclidean(m, o);
    DistanceOptions fo;
    fo.border_is_object = border;
    VolumeU32 ft = feature_transform_as<uint32_t>(m, fo);
    const Grid& g = m.grid();
    for (int64_t i = 0; i < m.size(); ++i) {
      const double e = std::sqrt(ref.sq[static_cast<size_t>(i)]);
      expect_close(e, d[i], "distance", i);
      // the chosen feature is a background voxel at the minimal distance (ties may differ in the
      // last bits of floating point, so only the distance is compared)
      const int64_t x = i % g.dims[0], y = (i / g.dims[0]) % g.dims[1], z = i / (g.dims[0] * g.dims[1]);
      if (ft[i] == OUT32) {
        const int64_t dist_out[3] = {std::min(x + 1, g.dims[0] - x), std::min(y + 1, g.dims[1] - y),
                                     std::min(z + 1, g.dims[2] - z)};
        double best = std::numeric_limits<double>::infinity();
        if (!border)
          for (int a = 0; a < 3; ++a) best = std::min(best, static_cast<double>(dist_out[a]) * g.spacing[a]);
        expect_close(e, best, "outside feature", i);
      } else {
        ASSERT_LT(ft[i], static_cast<uint32_t>(m.size()));
        EXPECT_EQ(0, m[ft[i]]);
        const int64_t f = ft[i];
        const double dx = static_cast<double>(x - f % g.dims[0]) * g.spacing[0];
        const double dy = static_cast<double>(y - (f / g.dims[0]) % g.dims[1]) * g.spacing[1];
        const double dz = static_cast<double>(z - f / (g.dims[0] * g.dims[1])) * g.spacing[2];
        expect_close(e, std::sqrt(dx * dx + dy * dy + dz * dz), "feature distance", i);
      }
    }
  }
}

// Rows wider than the column blocks of the y and z passes (16 and 64 columns): several blocks per row,
// the last one partial; distances, squared distances, feature transform and seeded distances against
// brute force for both border conventions, isotropic and anisotropic, 1 and 2 threads.
TEST(Euclidean, EqualsBruteForceOnRowsWiderThanTheColumnBlocks) {
  std::mt19937 rng(11);
  std::uniform_int_distribution<int64_t> wide(65, 150), narrow(1, 6);
  for (int trial = 0; trial < 12; ++trial) {
    const bool border = trial % 2 == 1;
    const Vec3 spacing = trial % 3 == 2 ? Vec3{0.7, 1.3, 2.0} : Vec3{1.5, 1.5, 1.5};
    const Dims dims{wide(rng), narrow(rng), trial < 2 ? 1 : narrow(rng) + 2};
    VolumeU8 m = random_mask(rng, dims, trial % 4 == 3 ? 0.97 : 0.75, spacing);
    const uint8_t* md = m.data();
    const BruteResult ref = brute_force(m.grid(), [&](int64_t i) { return md[i] == 0; }, !border);
    for (int threads : {1, 2}) {
      EuclideanOptions o;
      o.border_is_object = border;
      o.threads = threads;
      const VolumeF32 d = euclidean(m, o);
      o.squared = true;
      const VolumeF32 d2 = euclidean(m, o);
      DistanceOptions fo;
      fo.border_is_object = border;
      fo.threads = threads;
      const VolumeU32 ft = feature_transform_as<uint32_t>(m, fo);
      for (int64_t i = 0; i < m.size(); ++i) {
        expect_close(std::sqrt(ref.sq[static_cast<size_t>(i)]), d[i], "distance", i);
        expect_close(ref.sq[static_cast<size_t>(i)], d2[i], "squared", i);
        if (spacing[0] == spacing[2]) {
          EXPECT_EQ(ref.nearest[static_cast<size_t>(i)], ft[i]) << "trial " << trial;
        }
      }
      SeededOptions so;
      so.threads = threads;
      VolumeU8 seeds(m.dims(), 0, spacing);  // the background as seeds: sparse
      for (int64_t i = 0; i < m.size(); ++i) seeds[i] = md[i] == 0;
      const VolumeF32 sd = seeded(seeds, so);
      const BruteResult sref = brute_force(m.grid(), [&](int64_t i) { return md[i] == 0; }, false);
      for (int64_t i = 0; i < m.size(); ++i) expect_close(std::sqrt(sref.sq[static_cast<size_t>(i)]), sd[i], "seeded", i);
    }
  }
}

// Sparse masks (a few object voxels, many rows of a column block without any, rows of the x pass with
// one short run or none): the x pass writes runs into a cleared row, the column passes neither copy,
// convert nor write back rows without a non-zero value. Distances, squared distances and the feature
// transform against brute force, both border conventions, 1 and 2 threads.
TEST(Euclidean, EqualsBruteForceOnSparseMasksWithEmptyRows) {
  std::mt19937 rng(12);
  std::uniform_int_distribution<int64_t> wide(66, 140), narrow(2, 6);
  for (int trial = 0; trial < 16; ++trial) {
    const bool border = trial % 2 == 1;
    const Vec3 spacing = trial % 4 == 3 ? Vec3{0.8, 1.1, 1.7} : Vec3{1, 1, 1};
    const Dims dims{wide(rng), narrow(rng), narrow(rng) + 1};
    VolumeU8 m = random_mask(rng, dims, trial % 3 == 0 ? 0.02 : 0.08, spacing);
    // and one short object bar along z in the last column block, so that blocks with and without
    // object rows alternate
    for (int64_t z = 0; z + 1 < dims[2]; ++z) m(dims[0] - 2, dims[1] / 2, z) = 1;
    const uint8_t* md = m.data();
    const BruteResult ref = brute_force(m.grid(), [&](int64_t i) { return md[i] == 0; }, !border);
    for (int threads : {1, 2}) {
      EuclideanOptions o;
      o.border_is_object = border;
      o.threads = threads;
      const VolumeF32 d = euclidean(m, o);
      o.squared = true;
      const VolumeF32 d2 = euclidean(m, o);
      DistanceOptions fo;
      fo.border_is_object = border;
      fo.threads = threads;
      const VolumeU32 ft = feature_transform_as<uint32_t>(m, fo);
      for (int64_t i = 0; i < m.size(); ++i) {
        expect_close(std::sqrt(ref.sq[static_cast<size_t>(i)]), d[i], "distance", i);
        expect_close(ref.sq[static_cast<size_t>(i)], d2[i], "squared", i);
        if (spacing[0] == spacing[2]) {
          EXPECT_EQ(ref.nearest[static_cast<size_t>(i)], ft[i]) << "trial " << trial << " voxel " << i;
        } else if (ft[i] != OUT32) {
          EXPECT_EQ(0, md[ft[i]]) << "trial " << trial << " voxel " << i;
        }
      }
    }
  }
}

TEST(Seeded, EqualsBruteForce) {
  std::mt19937 rng(3);
  std::uniform_real_distribution<double> sp(0.5, 2.0);
  for (int trial = 0; trial < 100; ++trial) {
    const Vec3 spacing = trial % 2 ? Vec3{1, 1, 1} : Vec3{sp(rng), sp(rng), sp(rng)};
    VolumeU8 seeds = random_mask(rng, random_dims(rng), trial % 5 == 0 ? 0.0 : 0.08, spacing);
    const uint8_t* sd = seeds.data();
    BruteResult ref = brute_force(seeds.grid(), [&](int64_t i) { return sd[i] != 0; }, false);
    SeededOptions o;
    o.threads = 2;
    VolumeF32 d = seeded(seeds, o);
    for (int64_t i = 0; i < seeds.size(); ++i) expect_close(std::sqrt(ref.sq[static_cast<size_t>(i)]), d[i], "seeded", i);
  }
}

// Dijkstra over the 26-graph of the array plus (border background) the ring around it as sources.
std::vector<uint64_t> dijkstra(const VolumeU8& m, const ChamferWeights& w, bool border_is_object) {
  const int64_t nx = m.nx() + 2, ny = m.ny() + 2, nz = m.nz() + 2;
  const uint64_t INF = std::numeric_limits<uint64_t>::max();
  std::vector<uint64_t> d(static_cast<size_t>(nx * ny * nz), INF);
  auto pid = [&](int64_t x, int64_t y, int64_t z) { return x + 1 + nx * (y + 1 + ny * (z + 1)); };
  using Item = std::pair<uint64_t, int64_t>;
  std::priority_queue<Item, std::vector<Item>, std::greater<>> q;
  for (int64_t z = -1; z <= m.nz(); ++z)
    for (int64_t y = -1; y <= m.ny(); ++y)
      for (int64_t x = -1; x <= m.nx(); ++x) {
        const bool inside = m.grid().contains(x, y, z);
        if (inside ? m(x, y, z) == 0 : !border_is_object) {
          d[static_cast<size_t>(pid(x, y, z))] = 0;
          q.push({0, pid(x, y, z)});
        }
      }
  while (!q.empty()) {
    auto [dv, p] = q.top();
    q.pop();
    if (dv != d[static_cast<size_t>(p)]) continue;
    const int64_t x = p % nx - 1, y = (p / nx) % ny - 1, z = p / (nx * ny) - 1;
    for (int dz = -1; dz <= 1; ++dz)
      for (int dy = -1; dy <= 1; ++dy)
        for (int dx = -1; dx <= 1; ++dx) {
          const int k = (dx != 0) + (dy != 0) + (dz != 0);
          if (k == 0) continue;
          const int64_t X = x + dx, Y = y + dy, Z = z + dz;
          if (!m.grid().contains(X, Y, Z)) continue;  // paths run through the array
          uint64_t wt = k == 3 ? w.vertex
                        : k == 1 ? (dx ? w.face_x : dy ? w.face_y : w.face_z)
                                 : (dz == 0 ? w.edge_xy : dy == 0 ? w.edge_xz : w.edge_yz);
          const size_t t = static_cast<size_t>(pid(X, Y, Z));
          if (dv + wt < d[t]) {
            d[t] = dv + wt;
            q.push({d[t], pid(X, Y, Z)});
          }
        }
  }
  std::vector<uint64_t> out(static_cast<size_t>(m.size()));
  for (int64_t z = 0; z < m.nz(); ++z)
    for (int64_t y = 0; y < m.ny(); ++y)
      for (int64_t x = 0; x < m.nx(); ++x) out[static_cast<size_t>(m.index(x, y, z))] = d[static_cast<size_t>(pid(x, y, z))];
  return out;
}

template <class T>
void expect_chamfer_equals_dijkstra(const VolumeU8& m, const ChamferOptions& o, const Volume<T>& c) {
  const ChamferWeights w = o.derive_from_spacing ? chamfer_weights_from_spacing(m.spacing(), o.spacing_scale) : o.weights;
  std::vector<uint64_t> ref = dijkstra(m, w, o.border_is_object);
  for (int64_t i = 0; i < m.size(); ++i) {
    const uint64_t e = ref[static_cast<size_t>(i)] == std::numeric_limits<uint64_t>::max()
                           ? std::numeric_limits<T>::max()
                           : ref[static_cast<size_t>(i)];
    ASSERT_EQ(e, c[i]) << "voxel " << i;
  }
}

TEST(Chamfer, EqualsDijkstra345) {
  std::mt19937 rng(4);
  for (int trial = 0; trial < 200; ++trial) {
    ChamferOptions o;
    o.border_is_object = trial % 3 == 2;
    o.threads = 1 + trial % 4;  // any thread budget gives the same result
    VolumeU8 m = random_mask(rng, random_dims(rng, 11), 0.5 + 0.49 * (trial % 5) / 4.0);
    DataPtr d = chamfer(m, o);
    auto c = std::dynamic_pointer_cast<const VolumeU16>(d);
    ASSERT_TRUE(c);
    expect_chamfer_equals_dijkstra(m, o, *c);
  }
}

TEST(Chamfer, EqualsDijkstraOnSparseMasksWithEmptyRows) {
  // Few object voxels: most rows are empty (written by the row fast path, skipped backwards), rows
  // of 33..70 voxels take the 32-byte row test and its tail; uint16 and uint32 outputs.
  std::mt19937 rng(12);
  std::uniform_int_distribution<int64_t> len(33, 70), side(2, 9);
  for (int trial = 0; trial < 40; ++trial) {
    ChamferOptions o;
    o.border_is_object = trial % 2 == 1;
    const VolumeU8 m = random_mask(rng, {len(rng), side(rng), side(rng)}, 0.01 + 0.01 * (trial % 5));
    auto c = std::dynamic_pointer_cast<const VolumeU16>(chamfer(m, o));
    ASSERT_TRUE(c);
    expect_chamfer_equals_dijkstra(m, o, *c);
    o.weights = ChamferWeights::isotropic(6000, 8400, 10200);
    if (chamfer_output_bits(m.grid(), o) == 32) {
      auto c32 = std::dynamic_pointer_cast<const VolumeU32>(chamfer(m, o));
      ASSERT_TRUE(c32);
      expect_chamfer_equals_dijkstra(m, o, *c32);
    }
  }
}

TEST(Chamfer, EqualsDijkstraAnisotropicDerivedWeights) {
  std::mt19937 rng(5);
  std::uniform_real_distribution<double> sp(0.5, 3.0);
  for (int trial = 0; trial < 100; ++trial) {
    ChamferOptions o;
    o.border_is_object = trial % 3 == 2;
    o.derive_from_spacing = true;
    VolumeU8 m = random_mask(rng, random_dims(rng, 10), 0.6 + 0.39 * (trial % 4) / 3.0, {sp(rng), sp(rng), sp(rng)});
    VolumeU32 c = chamfer_as<uint32_t>(m, o);
    expect_chamfer_equals_dijkstra(m, o, c);
  }
}

TEST(Chamfer, DerivedWeights) {
  EXPECT_EQ(ChamferWeights::isotropic(3, 4, 5), chamfer_weights_from_spacing({2, 2, 2}));
  const ChamferWeights w = chamfer_weights_from_spacing({1, 1, 2.5});
  EXPECT_EQ(3u, w.face_x);
  EXPECT_EQ(8u, w.face_z);   // round(3 * 2.5 = 7.5)
  EXPECT_EQ(4u, w.edge_xy);  // round(3 * sqrt 2)
  EXPECT_EQ(8u, w.edge_xz);  // round(3 * sqrt(7.25) = 8.08)
  EXPECT_EQ(9u, w.vertex);   // round(3 * sqrt(8.25) = 8.62)
  EXPECT_THROW(chamfer_weights_from_spacing({1, 0, 1}), InputError);
}

TEST(Chamfer, OutputTypeSelection) {
  ChamferOptions o;
  // 5000 x 2 x 2, border background: bound 3 * 1 (the y/z border is one voxel away) -> uint16
  EXPECT_EQ(16, chamfer_output_bits(Grid({5000, 2, 2}), o));
  o.border_is_object = true;
  EXPECT_EQ(uint64_t{3 * 4999 + 3 + 3}, chamfer_upper_bound(Grid({5000, 2, 2}), o));
  EXPECT_EQ(16, chamfer_output_bits(Grid({5000, 2, 2}), o));
  EXPECT_EQ(32, chamfer_output_bits(Grid({30000, 2, 2}), o));
  // large weights on a small grid: uint32, and values are exact (compared with Dijkstra)
  o.weights = ChamferWeights::isotropic(6000, 8400, 10200);
  VolumeU8 m({12, 11, 13}, 1);
  m(0, 0, 0) = 0;
  m(5, 6, 7) = 0;
  DataPtr d = chamfer(m, o);
  auto c = std::dynamic_pointer_cast<const VolumeU32>(d);
  ASSERT_TRUE(c) << d->type_id();
  expect_chamfer_equals_dijkstra(m, o, *c);
  EXPECT_GT(*std::max_element(c->begin(), c->end()), 65535u);
  EXPECT_THROW(chamfer_as<uint16_t>(m, o), InputError);
}

TEST(Chamfer, EmptyAndFullMasks) {
  ChamferOptions o;
  VolumeU8 empty({7, 5, 6}, 0);
  auto c = std::dynamic_pointer_cast<const VolumeU16>(chamfer(empty, o));
  ASSERT_TRUE(c);
  for (auto v : *c) EXPECT_EQ(0, v);
  VolumeU8 full({7, 5, 6}, 1);
  c = std::dynamic_pointer_cast<const VolumeU16>(chamfer(full, o));
  EXPECT_EQ(3, (*c)(0, 2, 3));
  EXPECT_EQ(9, (*c)(3, 2, 2));  // 3 steps from every side in x, y and z
  o.border_is_object = true;
  c = std::dynamic_pointer_cast<const VolumeU16>(chamfer(full, o));
  for (auto v : *c) EXPECT_EQ(65535, v);
  ChamferNearest n = chamfer_nearest(full, o);
  auto nn = std::dynamic_pointer_cast<const VolumeU32>(n.nearest);
  ASSERT_TRUE(nn);
  for (auto v : *nn) EXPECT_EQ(OUT32, v);
}

// ChamferOptions::narrow: the uint8 scans equal the uint16 result voxel for voxel where every value
// is below 255 (random masks, rows long enough for the SIMD path and their tails, border as object,
// anisotropic weights); a value of 255 or more (a thick object, or large weights) gives the uint16
// output instead, equal to chamfer without `narrow`.
TEST(Chamfer, NarrowEqualsUint16WhereEveryValueFitsElseFallsBack) {
  std::mt19937 rng(21);
  std::uniform_int_distribution<int64_t> len(1, 70), side(1, 12);
  int narrowed = 0, widened = 0;
  for (int trial = 0; trial < 120; ++trial) {
    ChamferOptions o;
    o.border_is_object = trial % 4 == 3;
    if (trial % 5 == 4) o.weights = ChamferWeights::isotropic(20, 28, 35);
    if (trial % 7 == 6) o.weights = ChamferWeights::isotropic(200, 280, 345);  // saturates at once
    const VolumeU8 m = random_mask(rng, {len(rng), side(rng), side(rng)}, 0.3 + 0.69 * (trial % 6) / 5.0);
    const VolumeU16 wide = chamfer_as<uint16_t>(m, o);
    const bool fits = std::all_of(wide.begin(), wide.end(), [](uint16_t v) { return v < 255; });
    const std::optional<VolumeU8> d8 = chamfer_u8(m, o);
    ASSERT_EQ(fits, d8.has_value()) << "trial " << trial;
    o.narrow = true;
    const DataPtr d = chamfer(m, o);
    if (fits) {
      ++narrowed;
      auto c = std::dynamic_pointer_cast<const VolumeU8>(d);
      ASSERT_TRUE(c) << "trial " << trial << " " << d->type_id();
      for (int64_t i = 0; i < m.size(); ++i) ASSERT_EQ(wide[i], (*c)[i]) << "trial " << trial << " voxel " << i;
      for (int64_t i = 0; i < m.size(); ++i) ASSERT_EQ(wide[i], (*d8)[i]) << "trial " << trial << " voxel " << i;
    } else {
      ++widened;
      auto c = std::dynamic_pointer_cast<const VolumeU16>(d);
      ASSERT_TRUE(c) << "trial " << trial << " " << d->type_id();
      EXPECT_TRUE(*c == wide) << "trial " << trial;
    }
  }
  EXPECT_GT(narrowed, 40);
  EXPECT_GE(widened, 10);
}

TEST(Chamfer, NarrowOnAThickObjectFallsBackAtTheFirstValueOf255) {
  // A full 180 x 180 x 3 slab in x-y with the border as background: values up to 3 * 90 = 270 (> 254)
  // in x-y, but z is only 3 thick: no value exceeds 6 (two face steps out in z) -> fits.
  ChamferOptions o;
  o.narrow = true;
  VolumeU8 slab({180, 180, 3}, 1);
  auto c8 = std::dynamic_pointer_cast<const VolumeU8>(chamfer(slab, o));
  ASSERT_TRUE(c8);
  EXPECT_EQ(6, *std::max_element(c8->begin(), c8->end()));
  // A cube of 172: the centre is 86 face steps (258) from the border: uint16, equal to the plain run.
  VolumeU8 cube({172, 172, 172}, 1);
  DataPtr d = chamfer(cube, o);
  auto c16 = std::dynamic_pointer_cast<const VolumeU16>(d);
  ASSERT_TRUE(c16) << d->type_id();
  EXPECT_EQ(258, (*c16)(85, 85, 85));
  EXPECT_FALSE(chamfer_u8(cube, o).has_value());
  // A cube of 168: the centre is 84 face steps (252): fits in uint8.
  VolumeU8 cube2({168, 168, 168}, 1);
  auto c8b = std::dynamic_pointer_cast<const VolumeU8>(chamfer(cube2, o));
  ASSERT_TRUE(c8b);
  EXPECT_EQ(252, (*c8b)(83, 83, 83));
  o.narrow = false;
  const VolumeU16 plain = chamfer_as<uint16_t>(cube2, o);
  for (int64_t i = 0; i < plain.size(); ++i) ASSERT_EQ(plain[i], (*c8b)[i]) << "voxel " << i;
}

// Literal padded-array version of the two raster scans of thesis §2.3.1 / §2.3.2 carrying b(p).
struct BpRef {
  std::vector<uint32_t> d, b;
};
BpRef chamfer_bp_reference(const VolumeU8& m, const ChamferWeights& w, bool border_is_object) {
  const int64_t nx = m.nx() + 2, ny = m.ny() + 2, nz = m.nz() + 2;
  const uint32_t INF = 65535;
  std::vector<uint32_t> d(static_cast<size_t>(nx * ny * nz)), b(d.size(), OUT32);
  auto P = [&](int64_t x, int64_t y, int64_t z) { return static_cast<size_t>(x + nx * (y + ny * z)); };
  for (int64_t z = 0; z < nz; ++z)
    for (int64_t y = 0; y < ny; ++y)
      for (int64_t x = 0; x < nx; ++x) {
        const bool inside = x > 0 && y > 0 && z > 0 && x < nx - 1 && y < ny - 1 && z < nz - 1;
        if (inside) {
          const bool obj = m(x - 1, y - 1, z - 1) > 0;
          d[P(x, y, z)] = obj ? INF : 0;
          b[P(x, y, z)] = obj ? OUT32 : static_cast<uint32_t>(m.index(x - 1, y - 1, z - 1));
        } else {
          d[P(x, y, z)] = border_is_object ? INF : 0;
        }
      }
  struct Off {
    int dx, dy, dz;
  };
  std::vector<Off> mask;  // forward mask in the documented order
  for (int dy = -1; dy <= 1; ++dy)
    for (int dx = -1; dx <= 1; ++dx) mask.push_back({dx, dy, -1});
  for (int dx = -1; dx <= 1; ++dx) mask.push_back({dx, -1, 0});
  mask.push_back({-1, 0, 0});
  auto weight = [&](const Off& o) -> uint32_t {
    const int k = (o.dx != 0) + (o.dy != 0) + (o.dz != 0);
    if (k == 3) return w.vertex;
    if (k == 1) return o.dx ? w.face_x : o.dy ? w.face_y : w.face_z;
    return o.dz == 0 ? w.edge_xy : o.dy == 0 ? w.edge_xz : w.edge_yz;
  };
  auto relax = [&](int64_t x, int64_t y, int64_t z, int sign) {
    if (m(x - 1, y - 1, z - 1) == 0) return;
    for (const Off& o : mask) {
      const size_t q = P(x + sign * o.dx, y + sign * o.dy, z + sign * o.dz);
      if (d[q] == INF) continue;
      if (d[q] + weight(o) < d[P(x, y, z)]) {
        d[P(x, y, z)] = d[q] + weight(o);
        b[P(x, y, z)] = b[q];
      }
    }
  };
  for (int64_t z = 1; z < nz - 1; ++z)
    for (int64_t y = 1; y < ny - 1; ++y)
      for (int64_t x = 1; x < nx - 1; ++x) relax(x, y, z, +1);
  for (int64_t z = nz - 2; z >= 1; --z)
    for (int64_t y = ny - 2; y >= 1; --y)
      for (int64_t x = nx - 2; x >= 1; --x) relax(x, y, z, -1);
  BpRef r;
  for (int64_t z = 0; z < m.nz(); ++z)
    for (int64_t y = 0; y < m.ny(); ++y)
      for (int64_t x = 0; x < m.nx(); ++x) {
        r.d.push_back(d[P(x + 1, y + 1, z + 1)]);
        r.b.push_back(b[P(x + 1, y + 1, z + 1)]);
      }
  return r;
}

TEST(ChamferNearest, EqualsThesisReference) {
  std::mt19937 rng(7);
  for (int trial = 0; trial < 200; ++trial) {
    ChamferOptions o;
    o.border_is_object = trial % 3 == 2;
    VolumeU8 m = random_mask(rng, random_dims(rng, 11), 0.5 + 0.49 * (trial % 5) / 4.0);
    ChamferNearest n = chamfer_nearest(m, o);
    auto d = std::dynamic_pointer_cast<const VolumeU16>(n.distance);
    auto b = std::dynamic_pointer_cast<const VolumeU32>(n.nearest);
    ASSERT_TRUE(d && b);
    BpRef ref = chamfer_bp_reference(m, o.weights, o.border_is_object);
    auto plain = std::dynamic_pointer_cast<const VolumeU16>(chamfer(m, o));
    for (int64_t i = 0; i < m.size(); ++i) {
      ASSERT_EQ(ref.d[static_cast<size_t>(i)], (*d)[i]) << "trial " << trial << " voxel " << i;
      ASSERT_EQ(ref.b[static_cast<size_t>(i)], (*b)[i]) << "trial " << trial << " voxel " << i;
      ASSERT_EQ((*plain)[i], (*d)[i]);
      if ((*b)[i] != OUT32) {
        EXPECT_EQ(0, m[(*b)[i]]);  // b(p) is a background voxel
      }
    }
  }
}

VolumeU8 rods(Dims dims) {
  VolumeU8 m(dims, 0);
  for (int64_t z = 0; z < dims[2]; ++z)
    for (int64_t y = 0; y < dims[1]; ++y)
      for (int64_t x = 0; x < dims[0]; ++x) {
        const bool rx = (y % 17 - 8) * (y % 17 - 8) + (z % 19 - 9) * (z % 19 - 9) < 30;
        const bool ry = (x % 13 - 6) * (x % 13 - 6) + (z % 23 - 11) * (z % 23 - 11) < 20;
        const bool plate = (x + 2 * y + 3 * z) % 41 < 4;
        m(x, y, z) = (rx || ry || plate) ? 1 : 0;
      }
  return m;
}

TEST(Chamfer, EqualsDijkstraOnLongerRows) {
  // rows long enough for the vectorised (8 voxels per step) path, including row tails
  for (int64_t nx : {37, 64, 71}) {
    VolumeU8 m = rods({nx, 29, 23});
    for (bool border : {false, true}) {
      ChamferOptions o;
      o.border_is_object = border;
      auto c = std::dynamic_pointer_cast<const VolumeU16>(chamfer(m, o));
      ASSERT_TRUE(c);
      expect_chamfer_equals_dijkstra(m, o, *c);
      ChamferNearest n = chamfer_nearest(m, o);
      EXPECT_TRUE(*c == *std::dynamic_pointer_cast<const VolumeU16>(n.distance));
    }
  }
}

TEST(Threads, IdenticalFor1_2_4) {
  VolumeU8 m = rods({53, 47, 41});
  m.set_spacing({0.7, 1.0, 1.3});
  VolumeU8 iso = rods({53, 47, 41});
  for (const VolumeU8* v : {&m, &iso}) {
    EuclideanOptions o;
    o.threads = 1;
    VolumeF32 e1 = euclidean(*v, o);
    DistanceOptions fo;
    fo.threads = 1;
    VolumeU32 f1 = feature_transform_as<uint32_t>(*v, fo);
    SeededOptions so;
    so.threads = 1;
    VolumeF32 s1 = seeded(*v, so);
    for (int t : {2, 4}) {
      o.threads = fo.threads = so.threads = t;
      EXPECT_TRUE(e1 == euclidean(*v, o));
      EXPECT_TRUE(f1 == feature_transform_as<uint32_t>(*v, fo));
      EXPECT_TRUE(s1 == seeded(*v, so));
    }
  }
}

TEST(Threads, ChamferIdenticalForAnyThreadCount) {
  std::mt19937 rng(11);
  for (const Dims& dims : {Dims{53, 47, 41}, Dims{70, 3, 9}, Dims{16, 16, 1}, Dims{5, 40, 2}}) {
    VolumeU8 m = random_mask(rng, dims, 0.93);
    for (bool border : {false, true}) {
      ChamferOptions o;
      o.border_is_object = border;
      o.threads = 1;
      const VolumeU16 c16 = chamfer_as<uint16_t>(m, o);
      const VolumeU32 c32 = chamfer_as<uint32_t>(m, o);
      for (int t : {2, 3, 4, 7}) {
        o.threads = t;
        EXPECT_TRUE(c16 == chamfer_as<uint16_t>(m, o)) << t << " threads, border " << border;
        EXPECT_TRUE(c32 == chamfer_as<uint32_t>(m, o)) << t << " threads, border " << border;
      }
    }
  }
}

TEST(Euclidean, EmptyAndFullMasks) {
  VolumeU8 empty({6, 7, 5}, 0);
  VolumeF32 d = euclidean(empty);
  for (float v : d) EXPECT_EQ(0.0f, v);
  VolumeU32 f = feature_transform_as<uint32_t>(empty);
  for (int64_t i = 0; i < f.size(); ++i) EXPECT_EQ(static_cast<uint32_t>(i), f[i]);
  VolumeU8 full({6, 7, 5}, 1, {1.0, 2.0, 1.5});
  d = euclidean(full);
  EXPECT_FLOAT_EQ(1.0f, d(0, 3, 2));
  EXPECT_FLOAT_EQ(3.0f, d(2, 3, 2));  // x: 3 voxels to x = -1 or 6, z: 3 * 1.5, y: 4 * 2
  f = feature_transform_as<uint32_t>(full);
  for (uint32_t v : f) EXPECT_EQ(OUT32, v);
  EuclideanOptions o;
  o.border_is_object = true;
  d = euclidean(full, o);
  for (float v : d) EXPECT_TRUE(std::isinf(v));
  VolumeF32 s = seeded(empty);
  for (float v : s) EXPECT_TRUE(std::isinf(v));
}

}  // namespace
}  // namespace skel::distance
