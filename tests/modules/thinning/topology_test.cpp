// Simple-voxel test and topology numbers against direct brute-force references.
#include <gtest/gtest.h>

#include <array>
#include <chrono>
#include <map>
#include <random>
#include <set>
#include <thread>
#include <tuple>
#include <vector>

#include "shapes.hpp"
#include "thinning/thinning.hpp"
#include "analysis/topology.hpp"
#include "thinning/local_topology.hpp"

using namespace skel::thinning;
using namespace skel::analysis;

namespace skel {
namespace {

// Direct reference of Characterization 2 on a 3x3x3 coordinate array: flood fills with explicit
// coordinate adjacency tests, no bit tricks and no shared code with the library.
bool reference_simple(uint32_t nb) {
  int cube[3][3][3] = {};
  int k = 0;
  for (int z = 0; z < 3; ++z)
    for (int y = 0; y < 3; ++y)
      for (int x = 0; x < 3; ++x) {
        if (x == 1 && y == 1 && z == 1) continue;
        cube[z][y][x] = (nb >> k) & 1u;
        ++k;
      }
  auto in_n18 = [](int x, int y, int z) { return std::abs(x - 1) + std::abs(y - 1) + std::abs(z - 1) <= 2; };
  auto centre = [](int x, int y, int z) { return x == 1 && y == 1 && z == 1; };
  // Object 26-components in A26.
  int label[3][3][3] = {};
  int objects = 0;
  for (int z = 0; z < 3; ++z)
    for (int y = 0; y < 3; ++y)
      for (int x = 0; x < 3; ++x) {
        if (centre(x, y, z) || !cube[z][y][x] || label[z][y][x]) continue;
        ++objects;
        std::vector<std::array<int, 3>> st{{x, y, z}};
        label[z][y][x] = objects;
        while (!st.empty()) {
          auto [a, b, c] = st.back();
          st.pop_back();
          for (int e = 0; e < 3; ++e)
            for (int f = 0; f < 3; ++f)
              for (int g = 0; g < 3; ++g) {
                if (centre(g, f, e) || !cube[e][f][g] || label[e][f][g]) continue;
                if (std::abs(g - a) > 1 || std::abs(f - b) > 1 || std::abs(e - c) > 1) continue;
                label[e][f][g] = objects;
                st.push_back({g, f, e});
              }
        }
      }
  // Background 6-components in A18 that contain a 6-neighbour of the centre.
  int bl[3][3][3] = {};
  int bgs = 0;
  int comps = 0;
  for (int z = 0; z < 3; ++z)
    for (int y = 0; y < 3; ++y)
      for (int x = 0; x < 3; ++x) {
        if (centre(x, y, z) || !in_n18(x, y, z) || cube[z][y][x] || bl[z][y][x]) continue;
        ++comps;
        bool touches = false;
        std::vector<std::array<int, 3>> st{{x, y, z}};
        bl[z][y][x] = comps;
        while (!st.empty()) {
          auto [a, b, c] = st.back();
          st.pop_back();
          if (std::abs(a - 1) + std::abs(b - 1) + std::abs(c - 1) == 1) touches = true;
          for (int e = 0; e < 3; ++e)
            for (int f = 0; f < 3; ++f)
              for (int g = 0; g < 3; ++g) {
                if (centre(g, f, e) || !in_n18(g, f, e) || cube[e][f][g] || bl[e][f][g]) continue;
                if (std::abs(g - a) + std::abs(f - b) + std::abs(e - c) != 1) continue;
                bl[e][f][g] = comps;
                st.push_back({g, f, e});
              }
        }
        if (touches) ++bgs;
      }
  return objects == 1 && bgs == 1;
}

TEST(SimpleVoxel, BitOrderMatchesOffsets) {
  EXPECT_EQ(neighbour_bit(-1, -1, -1), 0);
  EXPECT_EQ(neighbour_bit(1, 1, 1), 25);
  EXPECT_EQ(neighbour_bit(1, 0, 0), 13);
  EXPECT_EQ(neighbour_bit(-1, 0, 0), 12);
  VolumeU8 m(Dims{3, 3, 3}, 0);
  m(2, 1, 1) = 1;
  EXPECT_EQ(neighbourhood_at(m, 1, 1, 1), 1u << 13);
}

TEST(SimpleVoxel, StructuredCases) {
  // Classic cases: isolated voxel, end of a line, middle of a line, interior voxel, plane voxel.
  EXPECT_FALSE(is_simple(0));
  EXPECT_TRUE(is_simple(1u << neighbour_bit(1, 0, 0)));
  EXPECT_TRUE(is_simple(1u << neighbour_bit(1, 1, 1)));
  EXPECT_FALSE(is_simple((1u << neighbour_bit(1, 0, 0)) | (1u << neighbour_bit(-1, 0, 0))));
  EXPECT_FALSE(is_simple((1u << 26) - 1));
  uint32_t plane = 0;
  for (int dy = -1; dy <= 1; ++dy)
    for (int dx = -1; dx <= 1; ++dx)
      if (dx || dy) plane |= 1u << neighbour_bit(dx, dy, 0);
  EXPECT_FALSE(is_simple(plane));  // two background sides
  uint32_t half = 0;              // the lower half-space z = -1 plus the plane z = 0
  for (int dy = -1; dy <= 1; ++dy)
    for (int dx = -1; dx <= 1; ++dx) half |= 1u << neighbour_bit(dx, dy, -1);
  EXPECT_TRUE(is_simple(half | plane));
  // All configurations with at most 3 object voxels or at most 3 background voxels, and all 2^18
  // configurations of the 18-neighbourhood with the 8 corners all background or all object.
  int64_t checked = 0, simple = 0;
  auto check = [&](uint32_t nb) {
    const bool ref = reference_simple(nb);
    ASSERT_EQ(is_simple(nb), ref) << nb;
    ASSERT_EQ(is_simple_direct(nb), ref) << nb;
    ++checked;
    simple += ref;
  };
  const uint32_t all = (1u << 26) - 1;
  for (int a = -1; a < 26; ++a)
    for (int b = a; b < 26; ++b)
      for (int c = b; c < 26; ++c) {
        uint32_t nb = 0;
        for (int v : {a, b, c})
          if (v >= 0) nb |= 1u << v;
        check(nb);
        check(all & ~nb);
      }
  uint32_t corners = 0, n18[18];
  int j = 0;
  for (int dz = -1; dz <= 1; ++dz)
    for (int dy = -1; dy <= 1; ++dy)
      for (int dx = -1; dx <= 1; ++dx) {
        const int l = std::abs(dx) + std::abs(dy) + std::abs(dz);
        if (l == 3) corners |= 1u << neighbour_bit(dx, dy, dz);
        if (l == 1 || l == 2) n18[j++] = 1u << neighbour_bit(dx, dy, dz);
      }
  for (uint32_t s = 0; s < (1u << 18); ++s) {
    uint32_t nb = 0;
    for (int k = 0; k < 18; ++k)
      if (s & (1u << k)) nb |= n18[k];
    check(nb);
    check(nb | corners);
  }
  EXPECT_GT(simple, checked / 20);
}

// >= 10^7 random neighbourhoods with object densities from 0.05 to 0.95 (so that simple and
// non-simple cases are both frequent): table, direct evaluation and the reference agree, and every
// simple neighbourhood belongs to some sub-iteration direction.
TEST(SimpleVoxel, RandomNeighbourhoodsMatchReference) {
  const int64_t total = 10'000'000;
  const int workers = 4;
  std::vector<int64_t> simple(workers, 0), mismatches(workers, 0), uncovered(workers, 0);
  std::vector<std::thread> pool;
  for (int w = 0; w < workers; ++w) {
    pool.emplace_back([&, w] {
      std::mt19937_64 rng(12345 + static_cast<uint64_t>(w));
      for (int64_t i = w; i < total; i += workers) {
        const uint64_t r = rng();
        const uint32_t density = static_cast<uint32_t>((i / workers) % 19) + 1;  // 1..19 of 20
        uint32_t nb = 0;
        uint64_t bits = rng();
        for (int k = 0; k < 26; ++k) {
          // 5-bit uniform draw per neighbour from two random words
          const uint32_t u = static_cast<uint32_t>(((k < 12 ? r : bits) >> ((k % 12) * 5)) & 31u);
          if (u * 20 < density * 32) nb |= 1u << k;
        }
        const bool ref = reference_simple(nb);
        if (is_simple(nb) != ref || is_simple_direct(nb) != ref) ++mismatches[static_cast<size_t>(w)];
        if (ref) {
          ++simple[static_cast<size_t>(w)];
          if (thinning_directions(nb) == 0) ++uncovered[static_cast<size_t>(w)];
        }
      }
    });
  }
  for (auto& t : pool) t.join();
  int64_t s = 0, mm = 0, un = 0;
  for (int w = 0; w < workers; ++w) {
    s += simple[static_cast<size_t>(w)];
    mm += mismatches[static_cast<size_t>(w)];
    un += uncovered[static_cast<size_t>(w)];
  }
  EXPECT_EQ(mm, 0);
  EXPECT_EQ(un, 0);
  EXPECT_GT(s, total / 50) << "too few simple samples for a meaningful comparison";
  std::printf("random neighbourhoods: %lld, simple: %lld\n", static_cast<long long>(total), static_cast<long long>(s));
}

// Reference topology: explicit cell counting in the doubled grid and plain flood fills.
TopologyNumbers reference_topology(const VolumeU8& m) {
  const int64_t nx = m.nx(), ny = m.ny(), nz = m.nz();
  auto obj = [&](int64_t x, int64_t y, int64_t z) { return m.at_or(x, y, z, 0) != 0; };
  TopologyNumbers t;
  // Cells of X(P): doubled coordinates c = 2p + {0,1,2}; a cell is in X(P) if any voxel whose closed
  // cube contains it is object. Its dimension is the number of odd coordinates.
  std::set<std::tuple<int64_t, int64_t, int64_t>> cells;
  for (int64_t z = 0; z < nz; ++z)
    for (int64_t y = 0; y < ny; ++y)
      for (int64_t x = 0; x < nx; ++x)
        if (obj(x, y, z)) {
          ++t.object_voxels;
          for (int c = 0; c < 27; ++c) cells.insert({2 * x + c % 3, 2 * y + (c / 3) % 3, 2 * z + c / 9});
        }
  for (const auto& [a, b, c] : cells) {
    const int dim = static_cast<int>((a & 1) + (b & 1) + (c & 1));
    t.euler += (dim % 2 == 0) ? 1 : -1;
  }
  // Components (26) and background components (6) with a padded grid.
  std::map<std::tuple<int64_t, int64_t, int64_t>, int> seen;
  for (int64_t z = -1; z <= nz; ++z)
    for (int64_t y = -1; y <= ny; ++y)
      for (int64_t x = -1; x <= nx; ++x) {
        if (seen.count({x, y, z})) continue;
        const bool o = obj(x, y, z);
        bool outside = false;
        std::vector<std::tuple<int64_t, int64_t, int64_t>> st{{x, y, z}};
        seen[{x, y, z}] = 1;
        while (!st.empty()) {
          auto [a, b, c] = st.back();
          st.pop_back();
          if (a < 0 || b < 0 || c < 0 || a >= nx || b >= ny || c >= nz) outside = true;
          for (int dz = -1; dz <= 1; ++dz)
            for (int dy = -1; dy <= 1; ++dy)
              for (int dx = -1; dx <= 1; ++dx) {
                const int l = std::abs(dx) + std::abs(dy) + std::abs(dz);
                if (l == 0 || (!o && l != 1)) continue;
                const int64_t p = a + dx, q = b + dy, r = c + dz;
                if (p < -1 || q < -1 || r < -1 || p > nx || q > ny || r > nz) continue;
                if (obj(p, q, r) != o || seen.count({p, q, r})) continue;
                seen[{p, q, r}] = 1;
                st.push_back({p, q, r});
              }
        }
        if (o) ++t.components;
        else if (!outside) ++t.cavities;
      }
  t.tunnels = t.components + t.cavities - t.euler;
  return t;
}

TEST(Topology, KnownShapes) {
  VolumeU8 one(Dims{3, 3, 3}, 0);
  one(1, 1, 1) = 1;
  EXPECT_EQ(topology(one), (TopologyNumbers{1, 1, 0, 1, 0}));
  VolumeU8 box(Dims{6, 5, 4}, 1);  // touching the array border: outside is still background
  EXPECT_EQ(topology(box), (TopologyNumbers{120, 1, 0, 1, 0}));
  VolumeU8 hollow(Dims{7, 7, 7}, 0);
  for (int64_t z = 1; z < 6; ++z)
    for (int64_t y = 1; y < 6; ++y)
      for (int64_t x = 1; x < 6; ++x) hollow(x, y, z) = (x == 3 && y == 3 && z == 3) ? 0 : 1;
  EXPECT_EQ(topology(hollow), (TopologyNumbers{124, 1, 1, 2, 0}));
  const VolumeU8 t = test::torus(24, 7, 3);
  const TopologyNumbers tt = topology(t);
  EXPECT_EQ(tt.components, 1);
  EXPECT_EQ(tt.cavities, 0);
  EXPECT_EQ(tt.euler, 0);
  EXPECT_EQ(tt.tunnels, 1);
  // A diagonal chain of voxels closing a square loop is one 26-component with one tunnel.
  VolumeU8 ring(Dims{5, 5, 3}, 0);
  for (int k = 0; k < 4; ++k) {
    ring(1 + k / 2 * 2, 1 + k % 2 * 2, 1) = 1;
  }
  ring(2, 1, 1) = 1;
  ring(1, 2, 1) = 1;
  ring(3, 2, 1) = 1;
  ring(2, 3, 1) = 1;
  EXPECT_EQ(topology(ring), (TopologyNumbers{8, 1, 0, 0, 1}));
}

TEST(Topology, RandomVolumesMatchReference) {
  for (uint32_t seed = 1; seed <= 12; ++seed) {
    const VolumeU8 m = test::random_blobs(12, seed, 0.45 + 0.01 * (seed % 6), 1);
    const TopologyNumbers ref = reference_topology(m);
    EXPECT_EQ(topology(m, {.threads = 1, .interrupter = {}}), ref) << "seed " << seed;
    EXPECT_EQ(topology(m, {.threads = 3, .interrupter = {}}), ref) << "seed " << seed;
  }
  // Uniform random voxels (many small components, tunnels and cavities), touching the border.
  std::mt19937 rng(7);
  for (int rep = 0; rep < 6; ++rep) {
    VolumeU8 m(Dims{9, 8, 7}, 0);
    for (auto& v : m) v = (rng() % 100) < 55 ? 1 : 0;
    EXPECT_EQ(topology(m), reference_topology(m)) << "rep " << rep;
  }
}

// Removing a simple voxel never changes components, cavities or Euler characteristic.
TEST(Topology, SimpleRemovalKeepsInvariants) {
  const VolumeU8 start = test::random_blobs(14, 99, 0.5, 1);
  VolumeU8 m = start;
  std::mt19937 rng(3);
  const TopologyNumbers t0 = topology(m);
  int removed = 0;
  for (int step = 0; step < 400; ++step) {
    const int64_t x = 1 + rng() % 12, y = 1 + rng() % 12, z = 1 + rng() % 12;
    if (!m(x, y, z) || !is_simple(neighbourhood_at(m, x, y, z))) continue;
    m(x, y, z) = 0;
    ++removed;
    ASSERT_EQ(topology(m).euler, t0.euler);
  }
  const TopologyNumbers t1 = topology(m);
  EXPECT_GT(removed, 20);
  EXPECT_EQ(t1.components, t0.components);
  EXPECT_EQ(t1.cavities, t0.cavities);
  EXPECT_EQ(t1.tunnels, t0.tunnels);
}

}  // namespace
}  // namespace skel
