#include "geometry/skeleton_to_graph.hpp"

#include <gtest/gtest.h>

#include <bit>
#include <map>
#include <random>
#include <set>

#include "../graph/graph_test_util.hpp"

using namespace skel::geometry;

using namespace skel;
using skel::test::draw_line;
using skel::test::draw_square_ring;

namespace {

SpatialGraph to_graph(const VolumeU8& v, int threads = 1) {
  SkeletonToGraphOptions o;
  o.threads = threads;
  auto g = skeleton_to_graph(v, nullptr, o).graph;
  EXPECT_TRUE(g.check_invariants().empty());
  return g;
}

std::vector<int64_t> sorted_degrees(const SpatialGraph& g) {
  auto d = g.degrees();
  std::sort(d.begin(), d.end());
  return d;
}

SkeletonToGraphOptions want_manifold() {
  SkeletonToGraphOptions o;
  o.want_manifold = true;
  return o;
}
SkeletonToGraphOptions bad_kernel() {
  SkeletonToGraphOptions o;
  o.smooth_passes = 1;
  o.smooth_kernel = 1;
  return o;
}

uint8_t cls(ManifoldType t) { return static_cast<uint8_t>(t); }

}  // namespace

TEST(DualCubeTable, EveryConfigurationIsAContractibleComplex) {
  const auto& t = dual_cube_table();
  ASSERT_EQ(t.size(), 256u);
  int with3 = 0;
  for (int c = 1; c < 256; ++c) {
    const auto& e = t[c];
    // χ after the 2-cells is 1 (contractible) or 2 (closed sphere, filled by the 3-cell).
    EXPECT_TRUE(e.euler == 1 || e.euler == 2) << "config " << c << " chi " << e.euler;
    EXPECT_EQ(e.cell3, e.euler == 2);
    with3 += e.cell3;
    // The 1-skeleton connects every object corner (fig. 3.6 rules keep 26-connectivity).
    std::array<int, 8> comp{};
    for (int k = 0; k < 8; ++k) comp[k] = k;
    auto root = [&](int k) {
      while (comp[k] != k) k = comp[k];
      return k;
    };
    for (int p = 0; p < 28; ++p)
      if (e.edges >> p & 1) comp[root(dual_cube_pair(p)[0])] = root(dual_cube_pair(p)[1]);
    int roots = 0;
    for (int k = 0; k < 8; ++k) roots += (c >> k & 1) && root(k) == k;
    EXPECT_EQ(roots, 1) << "config " << c;
    // Reduced edges are a subset, and never on a face with a coordinate fixed at 1.
    EXPECT_EQ(e.reduced_edges & ~e.edges, 0u);
  }
  EXPECT_EQ(t[0].edges, 0u);
  EXPECT_EQ(t[255].cells2.size(), 6u);  // full cube: six face squares and a 3-cell
  EXPECT_TRUE(t[255].cell3);
  EXPECT_GT(with3, 1);
  // Fig. 3.5: six voxels (corners 0 and 3 missing): seven 1-cells, three 2-cells, one 3-cell.
  const auto& f35 = t[255 & ~(1 | 8)];
  EXPECT_EQ(std::popcount(f35.edges), 7);
  EXPECT_EQ(f35.cells2.size(), 3u);
  EXPECT_TRUE(f35.cell3);
  // Rule 3: two body-diagonal voxels alone are joined; with a third voxel they are not directly.
  EXPECT_EQ(std::popcount(t[1 | 128].edges), 1);
  EXPECT_EQ(t[1 | 128 | 2].edges & (1u << 6), 0u);  // pair (0,7) has index 6
  EXPECT_EQ(dual_cube_pair(6), (std::array<int, 2>{0, 7}));
}

TEST(DualCubeTable, EachOneCellIsGeneratedExactlyOnce) {
  // Every 6-, 18- and 26-adjacent voxel pair in a random volume is produced by exactly one reduced
  // dual cube when it is a 1-cell: compare against per-cube full tables.
  std::mt19937 rng(7);
  VolumeU8 v({6, 5, 4}, 0);
  for (auto& x : v) x = (rng() % 3 == 0);
  const auto& t = dual_cube_table();
  std::map<std::pair<int64_t, int64_t>, int> reduced, full;
  for (int64_t z = -1; z < v.nz(); ++z)
    for (int64_t y = -1; y < v.ny(); ++y)
      for (int64_t x = -1; x < v.nx(); ++x) {
        int cfg = 0;
        for (int k = 0; k < 8; ++k)
          if (v.at_or(x + (k & 1), y + (k >> 1 & 1), z + (k >> 2 & 1), 0)) cfg |= 1 << k;
        for (int p = 0; p < 28; ++p) {
          auto [a, b] = dual_cube_pair(p);
          const int64_t ia = (x + (a & 1)) + 100 * ((y + (a >> 1 & 1)) + 100 * (z + (a >> 2 & 1)));
          const int64_t ib = (x + (b & 1)) + 100 * ((y + (b >> 1 & 1)) + 100 * (z + (b >> 2 & 1)));
          if (t[cfg].edges >> p & 1) full[{ia, ib}] = 1;
          if (t[cfg].reduced_edges >> p & 1) ++reduced[{ia, ib}];
        }
      }
  EXPECT_EQ(reduced.size(), full.size());
  for (auto& [k, c] : reduced) EXPECT_EQ(c, 1);
}

TEST(SkeletonToGraph, TorusIsOneLoop) {
  VolumeU8 v({20, 20, 7}, 0);
  // A digital circle (26-connected) of radius 7.
  for (int a = 0; a < 720; ++a) {
    const double t = a * M_PI / 360.0;
    v(std::lround(10 + 7 * std::cos(t)), std::lround(10 + 7 * std::sin(t)), 3) = 1;
  }
  auto r = skeleton_to_graph(v, nullptr, want_manifold());
  const auto& g = r.graph;
  EXPECT_TRUE(g.check_invariants().empty());
  ASSERT_EQ(g.edge_count(), 1);
  ASSERT_EQ(g.node_count(), 1);
  EXPECT_EQ(g.edges[0].node0, g.edges[0].node1);
  EXPECT_EQ(g.degrees()[0], 2);
  EXPECT_EQ(g.cyclomatic_number(), 1);
  int64_t line = 0, vox = 0;
  for (int64_t i = 0; i < v.size(); ++i) {
    vox += v[i];
    line += r.manifold[i] == cls(ManifoldType::line);
  }
  EXPECT_EQ(line, vox);
  EXPECT_EQ(static_cast<int64_t>(g.edges[0].points.size()), vox + 1);
}

TEST(SkeletonToGraph, PlusOfTwoRodsIsOneNodeOfDegreeFour) {
  VolumeU8 v({11, 11, 3}, 0);
  draw_line(v, {0, 5, 1}, {10, 5, 1});
  draw_line(v, {5, 0, 1}, {5, 10, 1});
  auto r = skeleton_to_graph(v, nullptr, want_manifold());
  const auto& g = r.graph;
  EXPECT_EQ(sorted_degrees(g), (std::vector<int64_t>{1, 1, 1, 1, 4}));
  EXPECT_EQ(g.edge_count(), 4);
  EXPECT_EQ(r.manifold(5, 5, 1), cls(ManifoldType::line_junction));
  EXPECT_EQ(r.manifold(0, 5, 1), cls(ManifoldType::line_end));
  EXPECT_EQ(r.manifold(2, 5, 1), cls(ManifoldType::line));
  for (int64_t e = 0; e < g.edge_count(); ++e) EXPECT_DOUBLE_EQ(g.edge_length(e), 5.0);
  EXPECT_DOUBLE_EQ(g.total_length(), 20.0);
}

TEST(SkeletonToGraph, TwoRingsTouchingAreOneNodeOfDegreeFour) {
  // Fig. 2.21 (right): two rings meeting in one voxel, in perpendicular planes ...
  {
    VolumeU8 v({9, 9, 9}, 0);
    draw_square_ring(v, {2, 4, 1}, 0, 1, 5);  // xy-plane, voxel (4,4,1) mid of its lower side
    draw_square_ring(v, {4, 0, 1}, 1, 2, 5);  // yz-plane through x = 4, (4,4,1) on its side
    auto g = to_graph(v);
    EXPECT_EQ(sorted_degrees(g), (std::vector<int64_t>{4}));
    EXPECT_EQ(g.edge_count(), 2);
    EXPECT_EQ(g.cyclomatic_number(), 2);
  }
  // ... and in one plane, touching at a corner voxel.
  {
    VolumeU8 v({12, 12, 3}, 0);
    draw_square_ring(v, {1, 1, 1}, 0, 1, 5);
    draw_square_ring(v, {5, 5, 1}, 0, 1, 5);
    auto g = to_graph(v);
    EXPECT_EQ(sorted_degrees(g), (std::vector<int64_t>{4}));
    EXPECT_EQ(g.cyclomatic_number(), 2);
  }
}

TEST(SkeletonToGraph, JunctionClustersCollapseToOneNode) {
  // Fig. 3.10: a complex junction (a 2x2x2 block, a 3x3 plate) collapses to one node.
  {
    VolumeU8 v({13, 13, 13}, 0);
    for (int z = 5; z <= 6; ++z)
      for (int y = 5; y <= 6; ++y)
        for (int x = 5; x <= 6; ++x) v(x, y, z) = 1;
    draw_line(v, {0, 5, 5}, {4, 5, 5});
    draw_line(v, {7, 6, 6}, {12, 6, 6});
    draw_line(v, {5, 0, 6}, {5, 4, 6});
    draw_line(v, {6, 7, 5}, {6, 12, 5});
    draw_line(v, {5, 6, 0}, {5, 6, 4});
    auto r = skeleton_to_graph(v, nullptr, want_manifold());
    EXPECT_EQ(sorted_degrees(r.graph), (std::vector<int64_t>{1, 1, 1, 1, 1, 5}));
    const auto& p = r.graph.positions;
    const auto d = r.graph.degrees();
    for (int64_t i = 0; i < r.graph.node_count(); ++i) {
      if (d[i] == 5) {
        EXPECT_EQ(p[i], (Vec3{5.5, 5.5, 5.5}));
      }
    }
    EXPECT_EQ(r.manifold(5, 5, 5), cls(ManifoldType::line_junction));
  }
  {
    VolumeU8 v({15, 15, 3}, 0);
    for (int y = 6; y <= 8; ++y)
      for (int x = 6; x <= 8; ++x) v(x, y, 1) = 1;
    draw_line(v, {0, 7, 1}, {5, 7, 1});
    draw_line(v, {9, 7, 1}, {14, 7, 1});
    draw_line(v, {7, 0, 1}, {7, 5, 1});
    draw_line(v, {7, 9, 1}, {7, 14, 1});
    auto r = skeleton_to_graph(v, nullptr, want_manifold());
    EXPECT_EQ(sorted_degrees(r.graph), (std::vector<int64_t>{1, 1, 1, 1, 4}));
    EXPECT_EQ(r.manifold(7, 7, 1), cls(ManifoldType::surface));
    EXPECT_EQ(r.manifold(6, 6, 1), cls(ManifoldType::surface_edge));
    EXPECT_EQ(r.graph.cyclomatic_number(), 0);
  }
  // Staircase (18-adjacent steps) meeting a straight rod: no spurious loop at the junction.
  {
    VolumeU8 v({12, 12, 3}, 0);
    draw_line(v, {0, 0, 1}, {6, 6, 1});
    draw_line(v, {6, 6, 1}, {6, 11, 1});
    draw_line(v, {6, 6, 1}, {11, 6, 1});
    auto g = to_graph(v);
    EXPECT_EQ(sorted_degrees(g), (std::vector<int64_t>{1, 1, 1, 3}));
    EXPECT_EQ(g.cyclomatic_number(), 0);
  }
}

TEST(SkeletonToGraph, TunnelInsideAJunctionClusterBecomesALoopEdge) {
  // Four junction voxels on a diamond (face-diagonal 1-cells around an empty centre), each with a
  // branch: the cluster collapses to one node, and its tunnel survives as a loop edge.
  VolumeU8 v({11, 11, 5}, 0);
  skel::test::draw_line(v, {5, 4, 2}, {5, 0, 2});
  skel::test::draw_line(v, {4, 5, 2}, {0, 5, 2});
  skel::test::draw_line(v, {6, 5, 2}, {10, 5, 2});
  skel::test::draw_line(v, {5, 6, 2}, {5, 10, 2});
  auto r = skeleton_to_graph(v, nullptr, want_manifold());
  const auto& g = r.graph;
  EXPECT_TRUE(g.check_invariants().empty());
  EXPECT_EQ(r.manifold(5, 4, 2), cls(ManifoldType::line_junction));
  EXPECT_EQ(skel::test::topology_26_6(v).tunnels, 1);
  EXPECT_EQ(g.cyclomatic_number(), 1);
  EXPECT_EQ(sorted_degrees(g), (std::vector<int64_t>{1, 1, 1, 1, 6}));
  int loops = 0;
  for (const auto& e : g.edges)
    if (e.node0 == e.node1) {
      ++loops;
      EXPECT_EQ(e.points.size(), 6u);  // node, the four ring voxels, node
    }
  EXPECT_EQ(loops, 1);
  // A 2x2 block (filled by a 2-cell) is no tunnel: no loop edge.
  VolumeU8 b({9, 9, 3}, 0);
  skel::test::draw_line(b, {0, 4, 1}, {8, 4, 1});
  skel::test::draw_line(b, {0, 5, 1}, {8, 5, 1});
  EXPECT_EQ(skeleton_to_graph(b, nullptr, {}).graph.cyclomatic_number(), 0);
}

TEST(SkeletonToGraph, IsolatedVoxelAndPair) {
  VolumeU8 v({6, 6, 6}, 0);
  v(1, 1, 1) = 1;
  v(3, 3, 3) = 1;
  v(4, 4, 4) = 1;  // 26-adjacent pair: rule 3
  auto r = skeleton_to_graph(v, nullptr, want_manifold());
  EXPECT_EQ(r.manifold(1, 1, 1), cls(ManifoldType::point));
  EXPECT_EQ(r.manifold(3, 3, 3), cls(ManifoldType::line_end));
  EXPECT_EQ(r.graph.node_count(), 3);
  EXPECT_EQ(r.graph.edge_count(), 1);
  EXPECT_NEAR(r.graph.edge_length(0), std::sqrt(3.0), 1e-12);
}

TEST(SkeletonToGraph, CyclomaticNumberEqualsTunnelsOnRandomSkeletons) {
  // Random networks of axis-parallel rods on the even lattice: crossings are single junction voxels,
  // rods never touch side by side, so every tunnel of the voxel set is a loop of the graph.
  for (int seed = 0; seed < 40; ++seed) {
    std::mt19937 rng(seed);
    VolumeU8 v({21, 21, 21}, 0);
    const int rods = 3 + seed % 10;
    for (int s = 0; s < rods; ++s) {
      const int axis = static_cast<int>(rng() % 3);
      std::array<int64_t, 3> a{}, b{};
      for (int k = 0; k < 3; ++k) a[k] = b[k] = 2 * static_cast<int64_t>(rng() % 11);
      a[axis] = static_cast<int64_t>(rng() % 10);
      b[axis] = a[axis] + 4 + static_cast<int64_t>(rng() % 11);
      b[axis] = std::min<int64_t>(b[axis], 20);
      draw_line(v, a, b);
    }
    const auto topo = skel::test::topology_26_6(v);
    ASSERT_EQ(topo.cavities, 0);
    auto g = to_graph(v);
    EXPECT_EQ(g.connected_components(), topo.components) << "seed " << seed;
    EXPECT_EQ(g.cyclomatic_number(), topo.tunnels) << "seed " << seed;
    // Chains are maximal: no node of degree 2 except the anchors of isolated loops.
    const auto d = g.degrees();
    for (int64_t e = 0; e < g.edge_count(); ++e) {
      if (g.edges[e].node0 != g.edges[e].node1) {
        EXPECT_NE(d[g.edges[e].node0], 2) << "seed " << seed;
      }
    }
  }
}

TEST(SkeletonToGraph, CyclomaticNumberEqualsTunnelsOnRandomDigitalLines) {
  // Random 26-connected digital segments in any direction: they touch side by side, cross in
  // junction clusters and form small surfaces; tunnels inside collapsed clusters become loop edges,
  // so the graph keeps every tunnel (sets with cavities excluded: a collapsed cluster cannot keep one).
  int tested = 0;
  for (int seed = 0; seed < 40; ++seed) {
    std::mt19937 rng(seed);
    VolumeU8 v({20, 20, 20}, 0);
    const int segments = 4 + seed % 10;
    for (int s = 0; s < segments; ++s) {
      std::array<int64_t, 3> a{}, b{};
      for (int k = 0; k < 3; ++k) {
        a[k] = static_cast<int64_t>(rng() % 20);
        b[k] = static_cast<int64_t>(rng() % 20);
      }
      draw_line(v, a, b);
    }
    const auto topo = skel::test::topology_26_6(v);
    if (topo.cavities != 0) continue;
    ++tested;
    auto g = to_graph(v);
    EXPECT_EQ(g.connected_components(), topo.components) << "seed " << seed;
    EXPECT_EQ(g.cyclomatic_number(), topo.tunnels) << "seed " << seed;
  }
  EXPECT_GE(tested, 35);
}

TEST(DualCubeTable, GlobalComplexHasTheEulerCharacteristicOfTheVoxels) {
  // Glue the per-cube complexes of random voxel sets (face 2-cells shared by two cubes counted once):
  // V - E + F - C equals χ of the union of voxel cubes, as a deformation retract must (§3.1.1).
  const auto& t = dual_cube_table();
  for (int seed = 0; seed < 20; ++seed) {
    std::mt19937 rng(100 + seed);
    VolumeU8 v({7, 6, 5}, 0);
    for (auto& x : v) x = (rng() % 100) < static_cast<unsigned>(20 + 3 * seed);
    int64_t V = 0, E = 0, F = 0, C = 0;
    for (auto x : v) V += x;
    std::set<std::vector<int64_t>> faces;
    for (int64_t z = -1; z < v.nz(); ++z)
      for (int64_t y = -1; y < v.ny(); ++y)
        for (int64_t x = -1; x < v.nx(); ++x) {
          int cfg = 0;
          for (int k = 0; k < 8; ++k)
            if (v.at_or(x + (k & 1), y + (k >> 1 & 1), z + (k >> 2 & 1), 0)) cfg |= 1 << k;
          E += std::popcount(t[cfg].reduced_edges);
          C += t[cfg].cell3;
          for (const auto& c : t[cfg].cells2) {
            if (c.face < 0) {
              ++F;
              continue;
            }
            std::vector<int64_t> key;
            for (int k = 0; k < 8; ++k)
              if (c.vertices >> k & 1) key.push_back((x + (k & 1)) + 100 * ((y + (k >> 1 & 1)) + 100 * (z + (k >> 2 & 1))));
            faces.insert(key);
          }
        }
    F += static_cast<int64_t>(faces.size());
    EXPECT_EQ(V - E + F - C, skel::test::topology_26_6(v).euler) << "seed " << seed;
  }
}

TEST(SkeletonToGraph, SameResultForAnyThreadCount) {
  std::mt19937 rng(3);
  VolumeU8 v({40, 30, 20}, 0);
  for (int s = 0; s < 25; ++s)
    draw_line(v, {int64_t(rng() % 40), int64_t(rng() % 30), int64_t(rng() % 20)},
              {int64_t(rng() % 40), int64_t(rng() % 30), int64_t(rng() % 20)});
  auto g1 = to_graph(v, 1), g2 = to_graph(v, 2), g4 = to_graph(v, 4);
  ASSERT_EQ(g1.edge_count(), g2.edge_count());
  ASSERT_EQ(g1.edge_count(), g4.edge_count());
  EXPECT_EQ(g1.positions, g2.positions);
  EXPECT_EQ(g1.positions, g4.positions);
  for (int64_t e = 0; e < g1.edge_count(); ++e) {
    EXPECT_EQ(g1.edges[e].points, g2.edges[e].points);
    EXPECT_EQ(g1.edges[e].points, g4.edges[e].points);
  }
  EXPECT_EQ(classify_manifold(v, 1), classify_manifold(v, 4));
}

TEST(SkeletonToGraph, RadiusFromDistanceAndSpacing) {
  VolumeU8 v({10, 3, 3}, 0, {2.0, 1.0, 1.0});
  draw_line(v, {1, 1, 1}, {8, 1, 1});
  VolumeF32 d(v.grid(), 0.0f);
  for (int64_t x = 0; x < 10; ++x) d(x, 1, 1) = static_cast<float>(x);
  SkeletonToGraphOptions o;
  o.radius_scale = 0.5;
  auto g = skeleton_to_graph(v, &d, o).graph;
  EXPECT_TRUE(g.check_invariants().empty());
  ASSERT_EQ(g.edge_count(), 1);
  EXPECT_DOUBLE_EQ(g.edge_length(0), 14.0);
  const auto& r = g.point_attributes.at("radius")[0];
  ASSERT_EQ(r.size(), 8u);
  const bool forward = g.edges[0].points.front()[0] == 2.0;
  for (size_t i = 0; i < r.size(); ++i) EXPECT_FLOAT_EQ(r[i], 0.5f * float(forward ? i + 1 : 8 - i));
  VolumeF32 wrong({9, 3, 3}, 0.0f);
  EXPECT_THROW(skeleton_to_graph(v, &wrong, {}), InputError);
}

TEST(SkeletonToGraph, SmoothingKeepsEndsAndStraightLines) {
  VolumeU8 v({30, 30, 3}, 0);
  draw_line(v, {0, 0, 1}, {29, 12, 1});  // a jagged digital line
  SkeletonToGraphOptions o;
  o.smooth_passes = 3;
  o.smooth_kernel = 7;
  auto raw = skeleton_to_graph(v, nullptr, {}).graph;
  auto g = skeleton_to_graph(v, nullptr, o).graph;
  EXPECT_TRUE(g.check_invariants().empty());
  ASSERT_EQ(g.edge_count(), 1);
  EXPECT_EQ(g.edges[0].points.front(), raw.edges[0].points.front());
  EXPECT_EQ(g.edges[0].points.back(), raw.edges[0].points.back());
  EXPECT_LT(g.edge_length(0), raw.edge_length(0));
  EXPECT_GE(g.edge_length(0), std::hypot(29.0, 12.0) - 1e-9);
  EXPECT_THROW(skeleton_to_graph(v, nullptr, bad_kernel()), InputError);
}

TEST(SkeletonToGraph, EmptyAndPhysicalPositions) {
  VolumeU8 empty({5, 4, 3}, 0);
  auto e = skeleton_to_graph(empty, nullptr, want_manifold());
  EXPECT_EQ(e.graph.node_count(), 0);
  EXPECT_EQ(e.graph.edge_count(), 0);
  EXPECT_EQ(e.manifold, empty);
  // Anisotropic spacing and an origin: positions and lengths are physical.
  VolumeU8 v({7, 7, 3}, 0, {1.0, 2.0, 3.0}, {10.0, 20.0, 30.0});
  skel::test::draw_line(v, {0, 3, 1}, {6, 3, 1});
  skel::test::draw_line(v, {3, 0, 1}, {3, 6, 1});
  auto g = skeleton_to_graph(v, nullptr, {}).graph;
  EXPECT_EQ(g.source_grid, v.grid());
  const auto d = g.degrees();
  for (int64_t n = 0; n < g.node_count(); ++n) {
    if (d[n] == 4) {
      EXPECT_EQ(g.positions[n], (Vec3{13.0, 26.0, 33.0}));
    }
  }
  EXPECT_DOUBLE_EQ(g.total_length(), 6 * 1.0 + 6 * 2.0);  // x rod along spacing 1, y rod along 2
}
