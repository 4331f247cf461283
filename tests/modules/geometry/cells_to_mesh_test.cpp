// Grid cell skeleton geometry (thesis §3.2): cell classes, simple and detailed meshes (each triangle
// once, a plate gives a connected 2-manifold with boundary, a closed shell a closed surface), and the
// graph of the one-dimensional part.
#include <gtest/gtest.h>

#include <algorithm>
#include <map>
#include <set>

#include "../thinning/shapes.hpp"
#include "geometry/cells_to_mesh.hpp"
#include "skel/union_find.hpp"
#include "thinning/grid_cell.hpp"

namespace skel {
namespace {

using geometry::CellGeometry;
using geometry::ManifoldType;

// A closed rectangle of 2-cells in the plane kz = 4: lattice corners x0..x1, y0..y1.
GridCells plate(int64_t x0, int64_t x1, int64_t y0, int64_t y1) {
  GridCells c(Grid(Dims{12, 12, 4}, {0.5, 0.5, 0.5}, {1, 2, 3}));
  for (int64_t ky = 2 * y0; ky <= 2 * y1; ++ky)
    for (int64_t kx = 2 * x0; kx <= 2 * x1; ++kx) c.set(kx, ky, 4, true);
  return c;
}

struct MeshTopology {
  int64_t duplicates = 0, components = 0, euler = 0, boundary_edges = 0, nonmanifold_edges = 0;
};

MeshTopology mesh_topology(const Mesh& m) {
  MeshTopology t;
  std::set<std::array<int64_t, 3>> seen;
  std::map<std::pair<int64_t, int64_t>, int> edges;
  UnionFind uf(m.vertex_count());
  std::set<int64_t> used;
  for (const auto& tri : m.triangles) {
    std::array<int64_t, 3> s = tri;
    std::sort(s.begin(), s.end());
    if (!seen.insert(s).second) ++t.duplicates;
    for (int i = 0; i < 3; ++i) {
      const int64_t a = tri[static_cast<size_t>(i)], b = tri[static_cast<size_t>((i + 1) % 3)];
      ++edges[{std::min(a, b), std::max(a, b)}];
      uf.unite(a, b);
      used.insert(a);
    }
  }
  for (const auto& [e, n] : edges) {
    if (n == 1) ++t.boundary_edges;
    if (n > 2) ++t.nonmanifold_edges;
  }
  std::set<int64_t> roots;
  for (int64_t v : used) roots.insert(uf.find(v));
  t.components = static_cast<int64_t>(roots.size());
  t.euler = static_cast<int64_t>(used.size()) - static_cast<int64_t>(edges.size()) + m.triangle_count();
  return t;
}

TEST(CellsToMesh, ClassifiesCellsOfAPlate) {
  const GridCells c = plate(2, 6, 3, 8);
  EXPECT_EQ(geometry::classify_cell(c, 8, 10, 4), ManifoldType::surface);       // interior 0-cell
  EXPECT_EQ(geometry::classify_cell(c, 4, 10, 4), ManifoldType::surface_edge);  // border 0-cell
  EXPECT_EQ(geometry::classify_cell(c, 4, 6, 4), ManifoldType::surface_edge);   // corner 0-cell
  EXPECT_EQ(geometry::classify_cell(c, 9, 10, 4), ManifoldType::surface);       // interior 1-cell
  EXPECT_EQ(geometry::classify_cell(c, 4, 11, 4), ManifoldType::surface_edge);  // border 1-cell
  EXPECT_EQ(geometry::classify_cell(c, 9, 11, 4), ManifoldType::surface);       // 2-cell
  EXPECT_EQ(geometry::classify_cell(c, 9, 11, 6), ManifoldType::background);
  // A bare 1-cell attached to the plate's interior: its 0-cell becomes a 1-x-junction.
  GridCells d = c;
  d.set(8, 10, 5, true);
  d.set(8, 10, 6, true);
  EXPECT_EQ(geometry::classify_cell(d, 8, 10, 4), ManifoldType::line_junction);
  EXPECT_EQ(geometry::classify_cell(d, 8, 10, 5), ManifoldType::line);
  EXPECT_EQ(geometry::classify_cell(d, 8, 10, 6), ManifoldType::line_end);
}

TEST(CellsToMesh, PlateIsAConnectedManifoldWithBoundary) {
  const GridCells c = plate(2, 6, 3, 8);  // 4 x 5 2-cells
  for (auto g : {CellGeometry::simple, CellGeometry::detailed}) {
    geometry::CellsToMeshOptions o;
    o.geometry = g;
    const Mesh m = geometry::cells_to_mesh(c, o);
    EXPECT_TRUE(m.check_invariants().empty());
    const int per = g == CellGeometry::simple ? 2 : 18;
    EXPECT_EQ(m.triangle_count(), 20 * per);
    EXPECT_EQ(m.line_count(), 0);
    const MeshTopology t = mesh_topology(m);
    EXPECT_EQ(t.duplicates, 0);
    EXPECT_EQ(t.components, 1);
    EXPECT_EQ(t.euler, 1);  // a disk
    EXPECT_EQ(t.nonmanifold_edges, 0);
    EXPECT_EQ(t.boundary_edges, g == CellGeometry::simple ? 18 : 54);
    for (int32_t v : Mesh::attribute<int32_t>(m.triangle_attributes, "manifold")) EXPECT_EQ(v, 1);
    for (int32_t v : Mesh::attribute<int32_t>(m.vertex_attributes, "fixed")) EXPECT_EQ(v, 0);
  }
  // Simple geometry: vertices at the voxel corners, origin + (p - 0.5) spacing.
  const Mesh m = geometry::cells_to_mesh(c);
  EXPECT_EQ(m.vertex_count(), 5 * 6);
  EXPECT_FLOAT_EQ(m.points[0][0], 1.0f + (2 - 0.5f) * 0.5f);
  EXPECT_FLOAT_EQ(m.points[0][1], 2.0f + (3 - 0.5f) * 0.5f);
  EXPECT_FLOAT_EQ(m.points[0][2], 3.0f + (2 - 0.5f) * 0.5f);
}

TEST(CellsToMesh, ClosedShellGivesAClosedSurface) {
  VolumeU8 shell(Dims{17, 17, 17}, 0);
  test::add_ball(shell, 8, 8, 8, 7.0);
  test::add_ball(shell, 8, 8, 8, 3.5, 0);
  const GridCells s = thinning::thin_grid_cells(shell, test::chamfer345(shell)).skeleton;
  const Mesh m = geometry::cells_to_mesh(s);
  const MeshTopology t = mesh_topology(m);
  EXPECT_EQ(t.duplicates, 0);
  EXPECT_EQ(t.components, 1);
  EXPECT_EQ(t.boundary_edges, 0);
  EXPECT_EQ(t.euler, 2);
  EXPECT_EQ(m.triangle_count(), 2 * s.counts()[2]);
}

// A ring with a tail: lines only, the junction vertex marked fixed; its graph has one loop edge and
// one tail edge between a node of degree 3 and a node of degree 1.
VolumeU8 ring_with_tail() {
  VolumeU8 m = test::torus(28, 7, 2.2);
  test::add_capsule(m, {13.5 + 6.5, 13.5, 13.5}, {26, 13.5, 13.5}, 2.2);
  return m;
}

TEST(CellsToMesh, RingWithTailGivesLinesAndAGraph) {
  const VolumeU8 v = ring_with_tail();
  thinning::GridCellThinningOptions o;
  o.end_point_length = 3;
  const GridCells s = thinning::thin_grid_cells(v, test::chamfer345(v), nullptr, o).skeleton;
  ASSERT_EQ(s.counts()[2], 0);
  ASSERT_EQ(s.euler(), 0);
  const Mesh m = geometry::cells_to_mesh(s);
  EXPECT_EQ(m.triangle_count(), 0);
  EXPECT_EQ(m.line_count(), s.counts()[1]);
  const auto& fixed = Mesh::attribute<int32_t>(m.vertex_attributes, "fixed");
  EXPECT_EQ(std::count(fixed.begin(), fixed.end(), 1), 1);
  const auto& lm = Mesh::attribute<int32_t>(m.line_attributes, "manifold");
  EXPECT_EQ(std::count(lm.begin(), lm.end(), 0), 3);  // the three segments at the junction
  // Detailed geometry: three segments per 1-cell, the middle one all-manifold.
  geometry::CellsToMeshOptions d;
  d.geometry = CellGeometry::detailed;
  const Mesh md = geometry::cells_to_mesh(s, d);
  EXPECT_EQ(md.line_count(), 3 * s.counts()[1]);
  const auto& dm = Mesh::attribute<int32_t>(md.line_attributes, "manifold");
  EXPECT_EQ(std::count(dm.begin(), dm.end(), 0), 3);

  const SpatialGraph g = geometry::cells_to_graph(s);
  EXPECT_TRUE(g.check_invariants().empty());
  ASSERT_EQ(g.node_count(), 2);
  ASSERT_EQ(g.edge_count(), 2);
  std::vector<int64_t> deg = g.degrees();
  std::sort(deg.begin(), deg.end());
  EXPECT_EQ(deg, (std::vector<int64_t>{1, 3}));
  int loops = 0;
  int64_t points = 0;
  for (const auto& e : g.edges) {
    loops += e.node0 == e.node1;
    points += static_cast<int64_t>(e.points.size()) - 1;
  }
  EXPECT_EQ(loops, 1);
  EXPECT_EQ(points, s.counts()[1]);  // every 1-cell is one polyline segment
  const auto& cls = g.node_labels.at("manifold");
  EXPECT_EQ(std::count(cls.begin(), cls.end(), static_cast<int32_t>(ManifoldType::line_junction)), 1);
  EXPECT_EQ(std::count(cls.begin(), cls.end(), static_cast<int32_t>(ManifoldType::line_end)), 1);
  EXPECT_EQ(g.unit, v.unit());
}

TEST(CellsToGraph, RingWithoutNodeIsOneLoop) {
  const VolumeU8 v = test::torus(24, 7, 2.5);
  const GridCells s = thinning::thin_grid_cells(v, test::chamfer345(v)).skeleton;
  const SpatialGraph g = geometry::cells_to_graph(s);
  ASSERT_EQ(g.node_count(), 1);
  ASSERT_EQ(g.edge_count(), 1);
  EXPECT_EQ(g.edges[0].node0, g.edges[0].node1);
  EXPECT_EQ(static_cast<int64_t>(g.edges[0].points.size()) - 1, s.counts()[1]);
  EXPECT_NEAR(g.edge_attributes.at("length")[0], static_cast<float>(s.counts()[1]), 1e-3);
}

}  // namespace
}  // namespace skel
