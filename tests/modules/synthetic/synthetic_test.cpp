// Synthetic phantoms: reproducible from the seed, independent of the thread count, sensible object
// fractions per shape, and a vessel network whose mask has exactly the topology of its ground-truth
// graph (one 26-component, no cavities, tunnels = cyclomatic number), with consistent tables.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <map>
#include <string>
#include <vector>

#include "synthetic/network.hpp"
#include "synthetic/vessel_tree.hpp"

using namespace skel;
using namespace skel::synthetic;

namespace {

double fraction(const VolumeU8& m) {
  int64_t c = 0;
  for (auto v : m) c += v != 0;
  return static_cast<double>(c) / static_cast<double>(m.size());
}

// Components of the voxels equal to `value` (object: non-zero) by BFS with 26- or 6-adjacency; with
// `interior_only`, only those that do not touch the volume border are counted (cavities).
int64_t count_components(const VolumeU8& m, bool object, bool conn26, bool interior_only) {
  const int64_t nx = m.nx(), ny = m.ny(), nz = m.nz();
  std::vector<uint8_t> seen(static_cast<size_t>(m.size()), 0);
  std::vector<int64_t> queue;
  int64_t count = 0;
  for (int64_t s = 0; s < m.size(); ++s) {
    if ((m[s] != 0) != object || seen[static_cast<size_t>(s)]) continue;
    bool border = false;
    seen[static_cast<size_t>(s)] = 1;
    queue.assign(1, s);
    for (size_t head = 0; head < queue.size(); ++head) {
      const int64_t i = queue[head];
      const int64_t x = i % nx, y = (i / nx) % ny, z = i / (nx * ny);
      border = border || x == 0 || y == 0 || z == 0 || x == nx - 1 || y == ny - 1 || z == nz - 1;
      for (int dz = -1; dz <= 1; ++dz)
        for (int dy = -1; dy <= 1; ++dy)
          for (int dx = -1; dx <= 1; ++dx) {
            const int nonzero = (dx != 0) + (dy != 0) + (dz != 0);
            if (nonzero == 0 || (!conn26 && nonzero > 1)) continue;
            const int64_t X = x + dx, Y = y + dy, Z = z + dz;
            if (!m.grid().contains(X, Y, Z)) continue;
            const int64_t j = m.index(X, Y, Z);
            if ((m[j] != 0) != object || seen[static_cast<size_t>(j)]) continue;
            seen[static_cast<size_t>(j)] = 1;
            queue.push_back(j);
          }
    }
    if (!interior_only || !border) ++count;
  }
  return count;
}

// Euler characteristic of the object with 26-adjacency: that of the union of the closed unit cubes
// at the object voxels, V − E + F − C of the cubical complex.
int64_t euler_26(const VolumeU8& m) {
  auto at = [&](int64_t x, int64_t y, int64_t z) -> int64_t { return m.at_or(x, y, z, 0) != 0; };
  int64_t v = 0, e = 0, f = 0, c = 0;
  for (int64_t z = 0; z <= m.nz(); ++z)
    for (int64_t y = 0; y <= m.ny(); ++y)
      for (int64_t x = 0; x <= m.nx(); ++x) {
        // The lattice vertex at the lower corner of voxel (x, y, z) and the cells starting there.
        const int64_t a000 = at(x - 1, y - 1, z - 1), a100 = at(x, y - 1, z - 1), a010 = at(x - 1, y, z - 1),
                      a110 = at(x, y, z - 1), a001 = at(x - 1, y - 1, z), a101 = at(x, y - 1, z),
                      a011 = at(x - 1, y, z), a111 = at(x, y, z);
        v += a000 | a100 | a010 | a110 | a001 | a101 | a011 | a111;
        e += (a100 | a110 | a101 | a111) + (a010 | a110 | a011 | a111) + (a001 | a101 | a011 | a111);
        f += (a110 | a111) + (a101 | a111) + (a011 | a111);
        c += a111;
      }
  return v - e + f - c;
}

struct Topo {
  int64_t components, cavities, tunnels;
};
Topo topology_of(const VolumeU8& m) {
  const int64_t comps = count_components(m, true, true, false);
  const int64_t cav = count_components(m, false, false, true);
  return {comps, cav, comps + cav - euler_26(m)};
}

// Brute-force check of the topology helper on objects of known topology.
TEST(SyntheticTestHelpers, TopologyOfKnownObjects) {
  VolumeU8 ring({9, 9, 3}, 0);
  for (int64_t y = 1; y < 8; ++y)
    for (int64_t x = 1; x < 8; ++x)
      if (x == 1 || x == 7 || y == 1 || y == 7) ring(x, y, 1) = 1;
  const Topo t = topology_of(ring);
  EXPECT_EQ(t.components, 1);
  EXPECT_EQ(t.cavities, 0);
  EXPECT_EQ(t.tunnels, 1);
  VolumeU8 shell({7, 7, 7}, 0);
  for (int64_t z = 1; z < 6; ++z)
    for (int64_t y = 1; y < 6; ++y)
      for (int64_t x = 1; x < 6; ++x) shell(x, y, z) = (x == 3 && y == 3 && z == 3) ? 0 : 1;
  const Topo s = topology_of(shell);
  EXPECT_EQ(s.components, 1);
  EXPECT_EQ(s.cavities, 1);
  EXPECT_EQ(s.tunnels, 0);
  VolumeU8 diagonal({4, 4, 4}, 0);
  diagonal(0, 0, 0) = diagonal(1, 1, 1) = diagonal(3, 3, 3) = 1;
  EXPECT_EQ(topology_of(diagonal).components, 2);
}

TEST(Network, ReproducibleAndThreadIndependent) {
  for (const char* shape : {"rods", "plates", "spheres", "mixed"}) {
    NetworkOptions o;
    o.shape = parse_enum<synthetic::Shape>(shape, "shape");
    o.size = {50, 41, 37};
    o.noise = 0.3;
    o.threads = 1;
    const auto a = make_network(o);
    o.threads = 3;
    const auto b = make_network(o);
    o.threads = 2;
    const auto b2 = make_network(o);
    EXPECT_TRUE(a.image == b.image) << shape;
    EXPECT_TRUE(a.mask == b.mask) << shape;
    EXPECT_TRUE(a.image == b2.image) << shape;
    o.seed = 2;
    const auto c = make_network(o);
    EXPECT_FALSE(a.mask == c.mask) << shape;
  }
}

TEST(Network, ObjectFractionsAndShapeTopology) {
  struct Expect {
    const char* shape;
    double lo, hi;
  };
  for (const Expect& ex : {Expect{"rods", 0.03, 0.10}, Expect{"plates", 0.08, 0.25}, Expect{"spheres", 0.015, 0.08},
                           Expect{"mixed", 0.03, 0.15}}) {
    NetworkOptions o;
    o.shape = parse_enum<synthetic::Shape>(ex.shape, "shape");
    o.size = {96, 96, 96};
    o.threads = 2;
    const auto r = make_network(o);
    const double f = fraction(r.mask);
    EXPECT_GE(f, ex.lo) << ex.shape;
    EXPECT_LE(f, ex.hi) << ex.shape;
    // Smoothing a 0/1 drawing with a normalised kernel keeps the image in [0, 1].
    const auto [mn, mx] = std::minmax_element(r.image.begin(), r.image.end());
    EXPECT_GE(*mn, 0.0f) << ex.shape;
    EXPECT_LE(*mx, 1.0f + 1e-5f) << ex.shape;
    const Topo t = topology_of(r.mask);
    const std::string shape = ex.shape;
    if (shape == "spheres") {
      // Separate solid balls: many components, each simply connected.
      EXPECT_GE(t.components, 30);
      EXPECT_EQ(t.tunnels, 0);
      EXPECT_EQ(t.cavities, 0);
    } else {
      // Networks: loops through rods, and through plate holes and walls.
      EXPECT_GE(t.tunnels, shape == "rods" ? 20 : 3) << shape;
      EXPECT_LE(t.components, 3) << shape;
    }
  }
}

TEST(Network, MaskIsThresholdedImageAndNoiseIsBounded) {
  NetworkOptions o;
  o.size = {40, 40, 40};
  const auto clean = make_network(o);
  o.noise = 0.5;
  o.threshold = 0.4;
  const auto noisy = make_network(o);
  double max_diff = 0;
  for (int64_t i = 0; i < noisy.image.size(); ++i) {
    EXPECT_EQ(noisy.mask[i], noisy.image[i] > 0.4f ? 1 : 0);
    max_diff = std::max(max_diff, static_cast<double>(std::abs(noisy.image[i] - clean.image[i])));
  }
  EXPECT_GT(max_diff, 0.05);
  EXPECT_LE(max_diff, 0.6 * 0.5 + 1e-5);
  // Physical spacing is carried by both outputs.
  o.spacing = {2.0, 1.0, 0.5};
  const auto s = make_network(o);
  EXPECT_EQ(s.image.spacing(), (Vec3{2.0, 1.0, 0.5}));
  EXPECT_EQ(s.mask.spacing(), (Vec3{2.0, 1.0, 0.5}));
}

TEST(Network, InvalidOptionsAreInputErrors) {
  NetworkOptions o;
  o.size = {16, 16, 16};
  o.shape = static_cast<synthetic::Shape>(99);
  EXPECT_THROW(make_network(o), InputError);
  o.shape = synthetic::Shape::rods;
  o.noise = 1.5;
  EXPECT_THROW(make_network(o), InputError);
  o.noise = 0;
  o.radius = 20;
  EXPECT_THROW(make_network(o), InputError);
  o.radius = 2;
  o.threshold = 1.0;
  EXPECT_THROW(make_network(o), InputError);
  o.threshold = 0.5;
  o.size = {16, -1, 16};
  EXPECT_THROW(make_network(o), InputError);
}

TEST(VesselTree, MaskTopologyEqualsTheGroundTruth) {
  for (uint64_t seed : {1u, 2u, 3u, 4u}) {
    VesselTreeOptions o;
    o.seed = seed;
    o.threads = 2;
    const auto r = make_vessel_tree(o);
    const auto& g = r.truth;
    EXPECT_TRUE(g.check_invariants().empty()) << seed;
    EXPECT_EQ(g.connected_components(), 1) << seed;
    EXPECT_GE(g.cyclomatic_number(), 3) << seed;
    const Topo t = topology_of(r.mask);
    EXPECT_EQ(t.components, 1) << seed;
    EXPECT_EQ(t.cavities, 0) << seed;
    EXPECT_EQ(t.tunnels, g.cyclomatic_number()) << seed;
    // Every edge midpoint lies inside the mask.
    for (const auto& e : g.edges) {
      const Vec3 a = e.points.front(), b = e.points.back();
      EXPECT_EQ(r.mask.at_or(std::llround((a[0] + b[0]) / 2), std::llround((a[1] + b[1]) / 2), std::llround((a[2] + b[2]) / 2), 0), 1)
          << seed;
    }
  }
}

TEST(VesselTree, GroundTruthTablesAreConsistent) {
  VesselTreeOptions o;
  o.seed = 5;
  const auto r = make_vessel_tree(o);
  const Table& nodes = r.nodes;
  const Table& edges = r.edges;
  ASSERT_EQ(nodes.rows(), r.truth.node_count());
  ASSERT_EQ(edges.rows(), r.truth.edge_count());
  const auto& nid = nodes.ints("id");
  const auto& deg = nodes.ints("degree");
  const auto& kind = nodes.strings("kind");
  const auto& x = nodes.reals("x");
  const auto& y = nodes.reals("y");
  const auto& z = nodes.reals("z");
  const auto& eid = edges.ints("id");
  const auto& n0 = edges.ints("node0");
  const auto& n1 = edges.ints("node1");
  const auto& len = edges.reals("length");
  const auto& rad = edges.reals("radius");
  const auto& tree = edges.strings("tree");
  std::vector<int64_t> counted(static_cast<size_t>(nodes.rows()), 0);
  std::map<std::string, int64_t> trees;
  double total = 0;
  for (int64_t e = 0; e < edges.rows(); ++e) {
    const auto E = static_cast<size_t>(e);
    EXPECT_EQ(eid[E], e);
    ASSERT_GE(n0[E], 0);
    ASSERT_LT(n0[E], nodes.rows());
    ASSERT_GE(n1[E], 0);
    ASSERT_LT(n1[E], nodes.rows());
    EXPECT_NE(n0[E], n1[E]);
    ++counted[static_cast<size_t>(n0[E])];
    ++counted[static_cast<size_t>(n1[E])];
    const auto a = static_cast<size_t>(n0[E]), b = static_cast<size_t>(n1[E]);
    EXPECT_NEAR(len[E], std::sqrt((x[a] - x[b]) * (x[a] - x[b]) + (y[a] - y[b]) * (y[a] - y[b]) + (z[a] - z[b]) * (z[a] - z[b])), 1e-9);
    EXPECT_GE(rad[E], o.min_radius - 1e-9);
    EXPECT_LE(rad[E], o.root_radius + 1e-9);
    // Branch points are kept apart: every vessel is longer than 3 of its radii.
    EXPECT_GT(len[E], 3 * rad[E]);
    ++trees[tree[E]];
    total += len[E];
  }
  EXPECT_EQ(trees.size(), 3u);
  EXPECT_GT(trees["artery"], 0);
  EXPECT_GT(trees["vein"], 0);
  EXPECT_GT(trees["capillary"], 0);
  int64_t branch = 0, end = 0, roots = 0;
  for (int64_t n = 0; n < nodes.rows(); ++n) {
    const auto N = static_cast<size_t>(n);
    EXPECT_EQ(nid[N], n);
    EXPECT_EQ(deg[N], counted[N]) << n;
    if (kind[N] == "root") {
      ++roots;
      EXPECT_GE(deg[N], 1);
    } else if (kind[N] == "branch") {
      EXPECT_GE(deg[N], 3) << n;
    } else if (kind[N] == "end") {
      EXPECT_EQ(deg[N], 1) << n;
    } else {
      EXPECT_EQ(kind[N], "junction");
      EXPECT_EQ(deg[N], 2) << n;
    }
    branch += deg[N] >= 3;
    end += deg[N] == 1;
  }
  EXPECT_EQ(roots, o.roots);
  EXPECT_EQ(r.branch_points, branch);
  EXPECT_EQ(r.end_points, end);
  EXPECT_NEAR(r.total_length, total, 1e-9 * total);
  EXPECT_NEAR(r.truth.total_length(), total, 1e-9 * total);
}

TEST(VesselTree, ReproducibleThreadIndependentAndPhysical) {
  VesselTreeOptions o;
  o.size = {96, 80, 64};
  o.noise = 0.2;
  o.threads = 1;
  const auto a = make_vessel_tree(o);
  o.threads = 3;
  const auto b = make_vessel_tree(o);
  EXPECT_TRUE(a.mask == b.mask);
  EXPECT_TRUE(a.image == b.image);
  EXPECT_EQ(a.edges.to_csv(), b.edges.to_csv());
  o.seed = 9;
  const auto c = make_vessel_tree(o);
  EXPECT_FALSE(a.mask == c.mask);
  // Isotropic spacing 2: the same voxels, every length and radius doubled.
  o.seed = 1;
  o.noise = 0;
  const auto unit = make_vessel_tree(o);
  o.spacing = {2, 2, 2};
  const auto twice = make_vessel_tree(o);
  EXPECT_EQ(std::vector<uint8_t>(unit.mask.begin(), unit.mask.end()), std::vector<uint8_t>(twice.mask.begin(), twice.mask.end()));
  EXPECT_NEAR(twice.total_length, 2 * unit.total_length, 1e-9 * unit.total_length);
  EXPECT_NEAR(twice.edges.reals("radius")[0], 2 * unit.edges.reals("radius")[0], 1e-12);
}

TEST(VesselTree, InvalidOptionsAreInputErrors) {
  VesselTreeOptions o;
  o.roots = 1;
  EXPECT_THROW(make_vessel_tree(o), InputError);
  o.roots = 4;
  o.min_radius = 0.5;
  EXPECT_THROW(make_vessel_tree(o), InputError);
}

}  // namespace
