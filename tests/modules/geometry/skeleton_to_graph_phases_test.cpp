// The phases of skeleton_to_graph on their own (skeleton_to_graph_phases.hpp): voxel classification,
// 1-cells, junction collapse and nodes, chains, tunnel loops and isolated loops.
#include "geometry/skeleton_to_graph_phases.hpp"

#include <gtest/gtest.h>

#include <algorithm>
#include <vector>

using namespace skel;
using namespace skel::geometry;
using namespace skel::geometry::detail;

namespace {

constexpr auto kLine = static_cast<uint8_t>(ManifoldType::line);
constexpr auto kEnd = static_cast<uint8_t>(ManifoldType::line_end);
constexpr auto kLineJunction = static_cast<uint8_t>(ManifoldType::line_junction);

// A T in the plane z = 1 of 9x7x3: the bar x = 0..6 at y = 1 and the stem (3, 2..4).
VolumeU8 t_shape() {
  VolumeU8 v(Dims{9, 7, 3}, 0);
  for (int x = 0; x <= 6; ++x) v(x, 1, 1) = 1;
  for (int y = 2; y <= 4; ++y) v(3, y, 1) = 1;
  return v;
}

SkeletonVoxels phases_1_2(const VolumeU8& v, int threads = 1) {
  SkeletonVoxels sv = collect_voxels(v, threads, {});
  classify_voxels(sv, threads, {});
  connect_one_cells(sv, threads, {});
  return sv;
}

int64_t id_of(const SkeletonVoxels& sv, const VolumeU8& v, int64_t x, int64_t y, int64_t z) {
  const auto it = std::lower_bound(sv.vox.begin(), sv.vox.end(), v.index(x, y, z));
  EXPECT_TRUE(it != sv.vox.end() && *it == v.index(x, y, z));
  return it - sv.vox.begin();
}

std::vector<int64_t> neighbours(const SkeletonVoxels& sv, int64_t i) {
  std::vector<int64_t> r(sv.adj.begin() + sv.off[i], sv.adj.begin() + sv.off[i + 1]);
  std::sort(r.begin(), r.end());
  return r;
}

int64_t root(const std::vector<int64_t>& parent, int64_t i) {
  while (parent[i] != i) i = parent[i];
  return i;
}

}  // namespace

TEST(SkeletonToGraphPhases, VoxelsAreCollectedInRasterOrder) {
  const VolumeU8 v = t_shape();
  const SkeletonVoxels sv = collect_voxels(v, 2, {});
  std::vector<int64_t> expect;
  for (int64_t i = 0; i < v.size(); ++i)
    if (v[i]) expect.push_back(i);
  EXPECT_EQ(sv.vox, expect);
  // id_from finds a later voxel from any earlier id.
  for (int64_t i = 0; i < sv.size(); ++i)
    for (int64_t j = i; j < sv.size(); ++j) EXPECT_EQ(sv.id_from(i, sv.vox[j]), j);
}

TEST(SkeletonToGraphPhases, ClassifiesEndLineAndJunctionVoxels) {
  const VolumeU8 v = t_shape();
  const SkeletonVoxels sv = phases_1_2(v);
  ASSERT_EQ(sv.size(), 10);
  for (int64_t i = 0; i < sv.size(); ++i) {
    const int64_t idx = sv.vox[i], x = idx % 9, y = idx / 9 % 7;
    uint8_t expect = kLine;
    if ((x == 0 || x == 6) && y == 1) expect = kEnd;
    if (x == 3 && y == 4) expect = kEnd;
    if (x == 3 && y == 1) expect = kLineJunction;  // three bare 1-cells
    EXPECT_EQ(sv.cls[i], expect) << x << "," << y;
  }
  // A 2x2 square: four 1-cells around one 2-cell, each voxel on the square's edge.
  VolumeU8 sq(Dims{4, 4, 3}, 0);
  sq(1, 1, 1) = sq(2, 1, 1) = sq(1, 2, 1) = sq(2, 2, 1) = 1;
  const SkeletonVoxels s2 = phases_1_2(sq);
  for (uint8_t c : s2.cls) EXPECT_EQ(c, static_cast<uint8_t>(ManifoldType::surface_edge));
}

TEST(SkeletonToGraphPhases, OneCellsFollowTheDualCubeRules) {
  const VolumeU8 v = t_shape();
  const SkeletonVoxels sv = phases_1_2(v);
  // A tree: nine 1-cells. The stem's first voxel (3,2) touches (2,1) and (4,1) diagonally, but (3,1)
  // shares their squares, so only (3,1)-(3,2) is a 1-cell.
  EXPECT_EQ(sv.off.back(), 18);
  const int64_t j = id_of(sv, v, 3, 1, 1);
  std::vector<int64_t> expect = {id_of(sv, v, 2, 1, 1), id_of(sv, v, 4, 1, 1), id_of(sv, v, 3, 2, 1)};
  std::sort(expect.begin(), expect.end());
  EXPECT_EQ(neighbours(sv, j), expect);
  EXPECT_EQ(neighbours(sv, id_of(sv, v, 3, 2, 1)),
            (std::vector<int64_t>{id_of(sv, v, 3, 1, 1), id_of(sv, v, 3, 3, 1)}));
  EXPECT_EQ(neighbours(sv, id_of(sv, v, 0, 1, 1)), (std::vector<int64_t>{id_of(sv, v, 1, 1, 1)}));
  // A diagonal pair alone in its square is a 1-cell.
  VolumeU8 d(Dims{4, 4, 4}, 0);
  d(1, 1, 1) = d(2, 2, 1) = 1;
  const SkeletonVoxels sd = phases_1_2(d);
  EXPECT_EQ(neighbours(sd, 0), (std::vector<int64_t>{1}));
  // The same adjacency for any thread count.
  const SkeletonVoxels s4 = phases_1_2(v, 4);
  EXPECT_EQ(s4.off, sv.off);
  EXPECT_EQ(s4.adj, sv.adj);
}

TEST(SkeletonToGraphPhases, JunctionCollapseJoinsNodeVoxelsOnly) {
  // A 2x2 square (four surface-edge voxels) with a tail of three voxels from (3,2).
  VolumeU8 v(Dims{8, 5, 3}, 0);
  v(1, 1, 1) = v(2, 1, 1) = v(1, 2, 1) = v(2, 2, 1) = 1;
  for (int x = 3; x <= 5; ++x) v(x, 2, 1) = 1;
  const SkeletonVoxels sv = phases_1_2(v);
  std::vector<int64_t> parent = collapse_junctions(sv);
  const int64_t r = root(parent, id_of(sv, v, 1, 1, 1));
  for (auto [x, y] : {std::pair{2, 1}, std::pair{1, 2}, std::pair{2, 2}}) EXPECT_EQ(root(parent, id_of(sv, v, x, y, 1)), r);
  // Chain voxels stay alone.
  for (int x = 3; x <= 5; ++x) EXPECT_EQ(root(parent, id_of(sv, v, x, 2, 1)), id_of(sv, v, x, 2, 1));

  // Nodes: the collapsed square (at its centroid) and the tail's end.
  GraphBuild b = make_nodes(sv, parent, false);
  ASSERT_EQ(b.graph.node_count(), 2);
  EXPECT_EQ(b.graph.positions[0], (Vec3{1.5, 1.5, 1.0}));
  EXPECT_EQ(b.graph.positions[1], (Vec3{5.0, 2.0, 1.0}));
  EXPECT_EQ(b.node_of[id_of(sv, v, 2, 2, 1)], 0);
  EXPECT_EQ(b.node_of[id_of(sv, v, 5, 2, 1)], 1);
  EXPECT_EQ(b.node_of[id_of(sv, v, 4, 2, 1)], -1);
  EXPECT_EQ(b.node_kind[0], static_cast<int32_t>(ManifoldType::line_junction));  // (2,2): square + tail
  EXPECT_EQ(b.node_kind[1], static_cast<int32_t>(kEnd));

  // The chain: square node, (3,2), (4,2), end node.
  trace_chains(sv, b);
  ASSERT_EQ(b.graph.edge_count(), 1);
  const GraphEdge& e = b.graph.edges[0];
  EXPECT_EQ(e.node0, 0);
  EXPECT_EQ(e.node1, 1);
  EXPECT_EQ(e.points, (std::vector<Vec3>{{1.5, 1.5, 1.0}, {3, 2, 1}, {4, 2, 1}, {5, 2, 1}}));
  EXPECT_TRUE(b.point_rad.empty());
}

TEST(SkeletonToGraphPhases, ChainsCarryTheRadius) {
  const VolumeU8 v = t_shape();
  SkeletonVoxels sv = phases_1_2(v);
  VolumeF32 dist(v.grid(), 0.0f);
  for (int64_t i = 0; i < v.size(); ++i) dist[i] = static_cast<float>(i % 9);  // x
  read_radius(sv, dist, 2.0);
  std::vector<int64_t> parent = collapse_junctions(sv);
  GraphBuild b = make_nodes(sv, parent, true);
  EXPECT_EQ(b.graph.node_count(), 4);  // three ends, one junction
  trace_chains(sv, b);
  ASSERT_EQ(b.graph.edge_count(), 3);
  ASSERT_EQ(b.point_rad.size(), 3u);
  for (size_t e = 0; e < 3; ++e) {
    ASSERT_EQ(b.point_rad[e].size(), b.graph.edges[e].points.size());
    for (size_t k = 0; k < b.point_rad[e].size(); ++k)
      EXPECT_EQ(b.point_rad[e][k], static_cast<float>(2.0 * b.graph.edges[e].points[k][0]));
  }
}

TEST(SkeletonToGraphPhases, IsolatedLoopGetsANodeAtItsFirstVoxel) {
  // The 3x3 ring around (2,2): eight 1-manifold voxels, no node voxel.
  VolumeU8 v(Dims{5, 5, 3}, 0);
  for (int y = 1; y <= 3; ++y)
    for (int x = 1; x <= 3; ++x)
      if (x != 2 || y != 2) v(x, y, 1) = 1;
  const SkeletonVoxels sv = phases_1_2(v);
  for (uint8_t c : sv.cls) EXPECT_EQ(c, kLine);
  std::vector<int64_t> parent = collapse_junctions(sv);
  GraphBuild b = make_nodes(sv, parent, false);
  EXPECT_EQ(b.graph.node_count(), 0);
  trace_chains(sv, b);
  tunnel_loops(sv, b);
  EXPECT_EQ(b.graph.edge_count(), 0);
  isolated_loops(sv, b);
  ASSERT_EQ(b.graph.node_count(), 1);
  EXPECT_EQ(b.graph.positions[0], (Vec3{1, 1, 1}));
  ASSERT_EQ(b.graph.edge_count(), 1);
  EXPECT_EQ(b.graph.edges[0].node0, 0);
  EXPECT_EQ(b.graph.edges[0].node1, 0);
  EXPECT_EQ(b.graph.edges[0].points.size(), 9u);  // the eight voxels and back to the first
  EXPECT_EQ(b.node_kind, (std::vector<int32_t>{kLine}));
}

TEST(SkeletonToGraphPhases, TunnelInACollapsedComponentBecomesALoopEdge) {
  // Four junction voxels on a diamond around (5,5) (face-diagonal 1-cells around an empty centre),
  // each with a branch: one collapsed component with a tunnel.
  VolumeU8 v(Dims{11, 11, 5}, 0);
  for (int k = 0; k <= 4; ++k) {
    v(5, k, 2) = v(k, 5, 2) = 1;
    v(6 + k, 5, 2) = v(5, 6 + k, 2) = 1;
  }
  const SkeletonVoxels sv = phases_1_2(v);
  for (auto [x, y] : {std::pair{5, 4}, std::pair{4, 5}, std::pair{6, 5}, std::pair{5, 6}})
    EXPECT_EQ(sv.cls[id_of(sv, v, x, y, 2)], kLineJunction);
  std::vector<int64_t> parent = collapse_junctions(sv);
  GraphBuild b = make_nodes(sv, parent, false);
  // Nodes in the order of their first voxel: the end (5,0), the cluster (from (5,4)), three ends.
  ASSERT_EQ(b.graph.node_count(), 5);
  EXPECT_EQ(b.graph.positions[0], (Vec3{5, 0, 2}));
  EXPECT_EQ(b.graph.positions[1], (Vec3{5, 5, 2}));
  trace_chains(sv, b);
  EXPECT_EQ(b.graph.edge_count(), 4);
  for (const auto& e : b.graph.edges) EXPECT_NE(e.node0, e.node1);
  tunnel_loops(sv, b);
  ASSERT_EQ(b.graph.edge_count(), 5);
  const GraphEdge& loop = b.graph.edges[4];
  EXPECT_EQ(loop.node0, 1);
  EXPECT_EQ(loop.node1, 1);
  ASSERT_EQ(loop.points.size(), 6u);  // node, the four ring voxels, node
  std::vector<Vec3> ring(loop.points.begin() + 1, loop.points.end() - 1);
  std::sort(ring.begin(), ring.end());
  EXPECT_EQ(ring, (std::vector<Vec3>{{4, 5, 2}, {5, 4, 2}, {5, 6, 2}, {6, 5, 2}}));
  // Nothing left for isolated_loops.
  isolated_loops(sv, b);
  EXPECT_EQ(b.graph.edge_count(), 5);
}
