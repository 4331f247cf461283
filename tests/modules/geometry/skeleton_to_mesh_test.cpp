// geometry.skeleton_to_mesh (thesis §3.1.3): each triangle made once, plates give a connected
// 2-manifold with boundary, a closed shell a closed surface with χ = 2, lines give polylines, the
// improved cases 13/14/18 enclose no volume, and the mesh equals a brute-force construction over all
// dual cubes on random inputs.
#include "geometry/skeleton_to_mesh.hpp"

#include <gtest/gtest.h>

#include <algorithm>
#include <bit>
#include <functional>
#include <map>
#include <random>
#include <set>

#include "geometry/names.hpp"
#include "geometry/skeleton_to_graph.hpp"
#include "io/graph_io.hpp"
#include "io/mesh_io.hpp"
#include "io/volume_format.hpp"
#include "skel/transform.hpp"
#include "skel/run_module.hpp"
#include "skel/union_find.hpp"

using namespace skel;
using namespace skel::geometry;

namespace {

using Edge = std::pair<int64_t, int64_t>;
Edge edge(int64_t a, int64_t b) { return a < b ? Edge{a, b} : Edge{b, a}; }

// Triangles per undirected edge.
std::map<Edge, int> edge_uses(const Mesh& m) {
  std::map<Edge, int> uses;
  for (const auto& t : m.triangles)
    for (int a = 0; a < 3; ++a) ++uses[edge(t[a], t[(a + 1) % 3])];
  return uses;
}

// Components of the triangles (joined through shared vertices).
int64_t triangle_components(const Mesh& m) {
  UnionFind uf(m.vertex_count());
  std::vector<uint8_t> used(m.vertex_count(), 0);
  for (const auto& t : m.triangles) {
    uf.unite(t[0], t[1]);
    uf.unite(t[0], t[2]);
    used[t[0]] = used[t[1]] = used[t[2]] = 1;
  }
  std::set<int64_t> roots;
  for (int64_t v = 0; v < m.vertex_count(); ++v)
    if (used[v]) roots.insert(uf.find(v));
  return static_cast<int64_t>(roots.size());
}

// χ = V - E + F of the triangles (vertices and edges used by triangles).
int64_t euler(const Mesh& m) {
  std::set<int64_t> vs;
  for (const auto& t : m.triangles) vs.insert(t.begin(), t.end());
  return static_cast<int64_t>(vs.size()) - static_cast<int64_t>(edge_uses(m).size()) + m.triangle_count();
}

// No two triangles with the same vertex set, neither by id nor by position.
void expect_each_triangle_once(const Mesh& m) {
  std::set<std::array<int64_t, 3>> by_id;
  std::set<std::array<Mesh::Point, 3>> by_pos;
  for (const auto& t : m.triangles) {
    std::array<int64_t, 3> s = t;
    std::sort(s.begin(), s.end());
    EXPECT_TRUE(s[0] != s[1] && s[1] != s[2]) << "degenerate triangle";
    EXPECT_TRUE(by_id.insert(s).second) << "triangle made twice: " << s[0] << " " << s[1] << " " << s[2];
    std::array<Mesh::Point, 3> p{m.points[t[0]], m.points[t[1]], m.points[t[2]]};
    std::sort(p.begin(), p.end());
    EXPECT_TRUE(by_pos.insert(p).second) << "two triangles at the same place";
  }
}

VolumeU8 random_volume(int64_t n, uint32_t seed, double p) {
  VolumeU8 v({n, n, n}, 0, {0.5, 1.0, 2.0}, {1.0, -2.0, 0.25});
  std::mt19937 rng(seed);
  std::bernoulli_distribution b(p);
  for (int64_t i = 0; i < v.size(); ++i) v[i] = b(rng) ? 1 : 0;
  return v;
}

// Brute force: every dual cube (each at all of its positions), every triangle of its template
// (reduced or not), deduplicated by the positions of its corners; sorted position triples with the
// class of each (all voxels of the triangle's 2-cell 2-manifold or 2-boundary).
std::vector<std::pair<std::array<Mesh::Point, 3>, int>> brute_force(const VolumeU8& v, bool improved) {
  const VolumeU8 cls = classify_manifold(v, 1);
  auto fg = [&](int64_t x, int64_t y, int64_t z) {
    return x >= 0 && y >= 0 && z >= 0 && x < v.nx() && y < v.ny() && z < v.nz() && v(x, y, z) != 0;
  };
  auto pt = [&](double x, double y, double z) {
    const Vec3 p = v.grid().position(x, y, z);
    return Mesh::Point{static_cast<float>(p[0]), static_cast<float>(p[1]), static_cast<float>(p[2])};
  };
  std::map<std::array<Mesh::Point, 3>, int> out;
  for (int64_t z = -1; z < v.nz(); ++z)
    for (int64_t y = -1; y < v.ny(); ++y)
      for (int64_t x = -1; x < v.nx(); ++x) {
        int cfg = 0, surf = 0;
        for (int k = 0; k < 8; ++k) {
          const int64_t X = x + (k & 1), Y = y + (k >> 1 & 1), Z = z + (k >> 2 & 1);
          if (!fg(X, Y, Z)) continue;
          cfg |= 1 << k;
          const auto c = static_cast<ManifoldType>(cls(X, Y, Z));
          if (c == ManifoldType::surface || c == ManifoldType::surface_edge) surf |= 1 << k;
        }
        const auto& tpl = mesh_cube_template(cfg, improved);
        for (const auto& t : tpl.triangles) {
          std::array<Mesh::Point, 3> p;
          for (int a = 0; a < 3; ++a) {
            const int c = t.v[a];
            if (c < kFaceCentre) {
              p[a] = pt(x + (c & 1), y + (c >> 1 & 1), z + (c >> 2 & 1));
            } else if (c < kInterior) {
              const int f = c - kFaceCentre;
              double d[3] = {x + 0.5, y + 0.5, z + 0.5};
              d[f / 2] = static_cast<double>((f / 2 == 0 ? x : f / 2 == 1 ? y : z) + f % 2);
              p[a] = pt(d[0], d[1], d[2]);
            } else {
              const uint8_t mask = tpl.interior[c - kInterior];
              double s[3] = {0, 0, 0};
              for (int q = 0; q < 8; ++q)
                if (mask >> q & 1) {
                  s[0] += static_cast<double>(x + (q & 1));
                  s[1] += static_cast<double>(y + (q >> 1 & 1));
                  s[2] += static_cast<double>(z + (q >> 2 & 1));
                }
              const double cnt = std::popcount(static_cast<unsigned>(mask));
              p[a] = pt(s[0] / cnt, s[1] / cnt, s[2] / cnt);
            }
          }
          std::sort(p.begin(), p.end());
          out[p] = (t.voxels & ~surf) == 0 ? 1 : 0;
        }
      }
  return {out.begin(), out.end()};
}

// Brute force: the 1-cells of all dual cubes that bound no 2-cell of any dual cube, as sorted
// position pairs.
std::vector<std::array<Mesh::Point, 2>> brute_force_bare(const VolumeU8& v) {
  auto fg = [&](int64_t x, int64_t y, int64_t z) {
    return x >= 0 && y >= 0 && z >= 0 && x < v.nx() && y < v.ny() && z < v.nz() && v(x, y, z) != 0;
  };
  std::set<std::array<Mesh::Point, 2>> all, bounded;
  for (int64_t z = -1; z < v.nz(); ++z)
    for (int64_t y = -1; y < v.ny(); ++y)
      for (int64_t x = -1; x < v.nx(); ++x) {
        int cfg = 0;
        for (int k = 0; k < 8; ++k)
          if (fg(x + (k & 1), y + (k >> 1 & 1), z + (k >> 2 & 1))) cfg |= 1 << k;
        const auto& e = dual_cube_table()[cfg];
        uint32_t in_cells = 0;
        for (const auto& c : e.cells2) in_cells |= c.edges;
        for (int p = 0; p < 28; ++p) {
          if (!(e.edges >> p & 1)) continue;
          std::array<Mesh::Point, 2> seg;
          for (int a = 0; a < 2; ++a) {
            const int c = dual_cube_pair(p)[a];
            const Vec3 q = v.grid().position(x + (c & 1), y + (c >> 1 & 1), z + (c >> 2 & 1));
            seg[a] = {static_cast<float>(q[0]), static_cast<float>(q[1]), static_cast<float>(q[2])};
          }
          std::sort(seg.begin(), seg.end());
          all.insert(seg);
          if (in_cells >> p & 1) bounded.insert(seg);
        }
      }
  std::vector<std::array<Mesh::Point, 2>> out;
  for (const auto& s : all)
    if (!bounded.count(s)) out.push_back(s);
  return out;
}

std::vector<std::array<Mesh::Point, 2>> mesh_segments(const Mesh& m) {
  std::vector<std::array<Mesh::Point, 2>> out;
  for (int64_t l = 0; l < m.line_count(); ++l)
    for (int64_t i = m.line_offsets[l]; i + 1 < m.line_offsets[l + 1]; ++i) {
      std::array<Mesh::Point, 2> s{m.points[m.line_vertices[i]], m.points[m.line_vertices[i + 1]]};
      std::sort(s.begin(), s.end());
      out.push_back(s);
    }
  std::sort(out.begin(), out.end());
  return out;
}

std::vector<std::pair<std::array<Mesh::Point, 3>, int>> mesh_triangles(const Mesh& m) {
  const auto& cls = Mesh::attribute<int32_t>(m.triangle_attributes, "manifold");
  std::vector<std::pair<std::array<Mesh::Point, 3>, int>> out;
  for (int64_t t = 0; t < m.triangle_count(); ++t) {
    std::array<Mesh::Point, 3> p{m.points[m.triangles[t][0]], m.points[m.triangles[t][1]], m.points[m.triangles[t][2]]};
    std::sort(p.begin(), p.end());
    out.emplace_back(p, cls[t]);
  }
  std::sort(out.begin(), out.end());
  return out;
}

// χ of a dual cube's own complex (its corners, centres, 1-cells and all template triangles) and
// whether some triangle edge is used by no other triangle of the cube.
int cube_euler(int cfg, bool improved) {
  const auto& tpl = mesh_cube_template(cfg, improved);
  std::set<int> verts;
  std::set<std::pair<int, int>> edges;
  for (int k = 0; k < 8; ++k)
    if (cfg >> k & 1) verts.insert(k);
  const auto& e = dual_cube_table()[cfg];
  for (int p = 0; p < 28; ++p)
    if (e.edges >> p & 1) edges.insert({dual_cube_pair(p)[0], dual_cube_pair(p)[1]});
  for (const auto& t : tpl.triangles)
    for (int a = 0; a < 3; ++a) {
      verts.insert(t.v[a]);
      const int u = t.v[a], w = t.v[(a + 1) % 3];
      edges.insert({std::min(u, w), std::max(u, w)});
    }
  return static_cast<int>(verts.size()) - static_cast<int>(edges.size()) + static_cast<int>(tpl.triangles.size());
}

}  // namespace

TEST(SkeletonToMesh, PlateIsConnectedManifoldWithBoundary) {
  VolumeU8 v({12, 10, 5}, 0);
  for (int64_t y = 1; y < 9; ++y)
    for (int64_t x = 1; x < 11; ++x) v(x, y, 2) = 1;
  const Mesh m = skeleton_to_mesh(v);
  EXPECT_TRUE(m.check_invariants().empty());
  // 7 x 9 unit squares, each a fan of 4 triangles around its centre.
  EXPECT_EQ(m.triangle_count(), 7 * 9 * 4);
  EXPECT_EQ(m.line_count(), 0);
  expect_each_triangle_once(m);
  int boundary = 0;
  for (const auto& [e, uses] : edge_uses(m)) {
    EXPECT_TRUE(uses == 1 || uses == 2) << e.first << "-" << e.second << " in " << uses << " triangles";
    boundary += uses == 1;
  }
  EXPECT_EQ(boundary, 2 * (9 + 7));
  EXPECT_EQ(triangle_components(m), 1);
  EXPECT_EQ(euler(m), 1);  // a disk
  for (int32_t c : Mesh::attribute<int32_t>(m.triangle_attributes, "manifold")) EXPECT_EQ(c, 1);
  for (int32_t f : Mesh::attribute<int32_t>(m.vertex_attributes, "fixed")) EXPECT_EQ(f, 0);
}

TEST(SkeletonToMesh, DiagonalPlateIsConnectedManifold) {
  // A plate along x = y (voxels 18-connected across the diagonal): 2-cells through the cube interiors.
  VolumeU8 v({10, 10, 6}, 0);
  for (int64_t z = 1; z < 5; ++z)
    for (int64_t i = 1; i < 9; ++i) v(i, i, z) = 1;
  const Mesh m = skeleton_to_mesh(v);
  EXPECT_GT(m.triangle_count(), 0);
  expect_each_triangle_once(m);
  for (const auto& [e, uses] : edge_uses(m)) EXPECT_TRUE(uses == 1 || uses == 2);
  EXPECT_EQ(triangle_components(m), 1);
  EXPECT_EQ(euler(m), 1);
}

TEST(SkeletonToMesh, ClosedShellIsClosedSurfaceWithEulerTwo) {
  VolumeU8 v({10, 9, 8}, 0, {0.5, 0.5, 1.0});
  for (int64_t z = 1; z < 7; ++z)
    for (int64_t y = 1; y < 8; ++y)
      for (int64_t x = 1; x < 9; ++x)
        if (x == 1 || x == 8 || y == 1 || y == 7 || z == 1 || z == 6) v(x, y, z) = 1;
  const Mesh m = skeleton_to_mesh(v);
  EXPECT_GT(m.triangle_count(), 0);
  EXPECT_EQ(m.line_count(), 0);
  expect_each_triangle_once(m);
  for (const auto& [e, uses] : edge_uses(m)) EXPECT_EQ(uses, 2) << e.first << "-" << e.second;
  EXPECT_EQ(triangle_components(m), 1);
  EXPECT_EQ(euler(m), 2);
}

TEST(SkeletonToMesh, LinesGiveLinesAndNoTriangles) {
  VolumeU8 v({20, 12, 12}, 0, {2.0, 2.0, 2.0});
  for (int64_t x = 2; x < 18; ++x) v(x, 5, 5) = 1;       // straight rod
  for (int64_t i = 0; i < 6; ++i) v(10 + i, 6 + i, 5 + (i % 2)) = 1;  // a branch off it (26-steps)
  const Mesh m = skeleton_to_mesh(v);
  EXPECT_EQ(m.triangle_count(), 0);
  EXPECT_EQ(m.line_count(), 3);  // two halves of the rod and the branch, broken at the junction
  EXPECT_TRUE(m.check_invariants().empty());
  int64_t segs = 0;
  for (int64_t l = 0; l < m.line_count(); ++l) segs += m.line_offsets[l + 1] - m.line_offsets[l] - 1;
  EXPECT_EQ(segs, m.vertex_count() - 1);  // a tree
  const auto& fixed = Mesh::attribute<int32_t>(m.vertex_attributes, "fixed");
  EXPECT_EQ(std::count(fixed.begin(), fixed.end(), 1), 1);  // the 1-x-junction voxel
  EXPECT_FLOAT_EQ(m.points[0][0], 4.0f);  // physical units
}

TEST(SkeletonToMesh, RodOnPlateMarksJunctionFixed) {
  VolumeU8 v({12, 12, 12}, 0);
  for (int64_t y = 2; y < 10; ++y)
    for (int64_t x = 2; x < 10; ++x) v(x, y, 3) = 1;
  for (int64_t z = 4; z < 10; ++z) v(6, 6, z) = 1;
  const Mesh m = skeleton_to_mesh(v);
  EXPECT_EQ(m.line_count(), 1);
  expect_each_triangle_once(m);
  const auto& fixed = Mesh::attribute<int32_t>(m.vertex_attributes, "fixed");
  const auto& cls = Mesh::attribute<int32_t>(m.vertex_attributes, "manifold");
  ASSERT_EQ(std::count(fixed.begin(), fixed.end(), 1), 1);
  const int64_t j = std::find(fixed.begin(), fixed.end(), 1) - fixed.begin();
  EXPECT_EQ(cls[j], static_cast<int32_t>(ManifoldType::line_junction));
  EXPECT_EQ(m.points[j], (Mesh::Point{6, 6, 3}));
  EXPECT_EQ(m.line_vertices.front() == j || m.line_vertices.back() == j, true);
  const auto& tcls = Mesh::attribute<int32_t>(m.triangle_attributes, "manifold");
  EXPECT_GT(std::count(tcls.begin(), tcls.end(), 0), 0);  // the triangles at the junction
  EXPECT_GT(std::count(tcls.begin(), tcls.end(), 1), 0);
}

TEST(SkeletonToMesh, ImprovedCasesEncloseNoVolume) {
  int special = 0;
  for (int cfg = 1; cfg < 256; ++cfg) {
    const auto& e = dual_cube_table()[cfg];
    // Components of the cube's 1-skeleton.
    std::array<int, 8> comp{};
    for (int k = 0; k < 8; ++k) comp[k] = k;
    std::function<int(int)> root = [&](int k) { return comp[k] == k ? k : comp[k] = root(comp[k]); };
    for (int p = 0; p < 28; ++p)
      if (e.edges >> p & 1) comp[root(dual_cube_pair(p)[0])] = root(dual_cube_pair(p)[1]);
    int ncomp = 0;
    for (int k = 0; k < 8; ++k) ncomp += (cfg >> k & 1) && root(k) == k;
    SCOPED_TRACE(cfg);
    if (!e.cell3) {
      EXPECT_EQ(cube_euler(cfg, true), ncomp);
      EXPECT_EQ(cube_euler(cfg, false), ncomp);
    } else if (cfg == 255) {
      EXPECT_EQ(cube_euler(cfg, true), 2);  // case 21 keeps its volume
    } else {
      ++special;
      EXPECT_EQ(cube_euler(cfg, false), 2);  // the plain triangulation encloses the 3-cell
      EXPECT_EQ(cube_euler(cfg, true), 1);   // the improved one is contractible
    }
  }
  // Members of case 13 (2 tetrahedra), 14 (8: a body diagonal and its direction), 18 (12: a face and
  // one of its diagonals).
  EXPECT_EQ(special, 2 + 8 + 12);
}

TEST(SkeletonToMesh, MatchesBruteForceOnRandomInputs) {
  size_t segments = 0, triangles = 0, special_cubes = 0;
  for (uint32_t seed = 1; seed <= 6; ++seed)
    for (bool improved : {false, true}) {
      SCOPED_TRACE(testing::Message() << "seed " << seed << " improved " << improved);
      const VolumeU8 v = random_volume(7, seed, 0.15 + 0.05 * (seed % 3));
      SkeletonToMeshOptions o;
      o.improved = improved;
      o.threads = 1;
      const Mesh m = skeleton_to_mesh(v, o);
      EXPECT_TRUE(m.check_invariants().empty());
      expect_each_triangle_once(m);
      EXPECT_EQ(mesh_triangles(m), brute_force(v, improved));
      EXPECT_EQ(mesh_segments(m), brute_force_bare(v));
      segments += mesh_segments(m).size();
      triangles += static_cast<size_t>(m.triangle_count());
      for (int64_t z = 0; z + 1 < v.nz(); ++z)
        for (int64_t y = 0; y + 1 < v.ny(); ++y)
          for (int64_t x = 0; x + 1 < v.nx(); ++x) {
            int cfg = 0;
            for (int k = 0; k < 8; ++k)
              if (v(x + (k & 1), y + (k >> 1 & 1), z + (k >> 2 & 1))) cfg |= 1 << k;
            special_cubes += dual_cube_table()[cfg].cell3 && cfg != 255;
          }
      o.threads = 4;
      EXPECT_TRUE(skeleton_to_mesh(v, o) == m) << "thread count changes the mesh";
    }
  // The inputs exercise lines, triangles and the cases 13, 14, 18.
  EXPECT_GT(segments, 20u);
  EXPECT_GT(triangles, 100u);
  EXPECT_GT(special_cubes, 5u);
}

TEST(SkeletonToMesh, Module) {
  auto v = std::make_shared<VolumeU8>(Dims{8, 8, 4}, 0);
  for (int64_t y = 1; y < 7; ++y)
    for (int64_t x = 1; x < 7; ++x) (*v)(x, y, 1) = 1;
  auto r = run_module(names::skeleton_to_mesh, {{"skeleton", v}}, {{"improved", false}}, {.threads = 1});
  EXPECT_EQ(r.get<Mesh>("mesh")->triangle_count(), 5 * 5 * 4);
}

// Issue 19: a volume's origin and direction (here from a NRRD file) carried to the coordinates of the
// graph and mesh files, so that a centerline overlays the image in Slicer: a graph node and a mesh
// vertex at a skeleton voxel land, in the files, at that voxel's world coordinate origin +
// D·(index·spacing); in memory they stay in the axis-aligned frame, and the graph formats that store
// the direction (.vtp, .am) read back into it.
TEST(WorldCoordinates, GraphAndMeshFilesOverlayARotatedNrrdVolume) {
  VolumeU8 sk(Dims{12, 10, 8}, 0, {0.5, 1.0, 2.0}, {10.0, 20.0, 30.0});
  for (int64_t x = 2; x <= 9; ++x) sk(x, 3, 4) = 1;
  for (int64_t y = 3; y <= 8; ++y) sk(9, y, 4) = 1;
  const Direction d{0, 1, 0, 0, 0, 1, 1, 0, 0};  // voxel x → world z, y → world x, z → world y
  sk.set_direction(d);
  sk.set_unit("mm");
  const auto dir = std::filesystem::path(SKEL_BINARY_DIR) / "test_scratch" / "world_coordinates";
  std::filesystem::create_directories(dir);
  io::write_any_volume(dir / "skeleton.nrrd", sk);
  const auto read = std::dynamic_pointer_cast<const VolumeU8>(io::read_any_volume(dir / "skeleton.nrrd"));
  ASSERT_TRUE(read);
  ASSERT_EQ(read->grid().direction, d);
  const Vec3 end_voxel_world{10.0 + 3.0, 20.0 + 8.0, 30.0 + 1.0};  // voxel (2, 3, 4): D·(1, 3, 8) + origin
  EXPECT_EQ(world_position(read->grid().position(2, 3, 4), read->origin(), d), end_voxel_world);

  const SpatialGraph g = geometry::skeleton_to_graph(*read, nullptr).graph;
  auto has = [](const std::vector<Vec3>& points, const Vec3& p) {
    return std::any_of(points.begin(), points.end(), [&](const Vec3& q) {
      return std::abs(q[0] - p[0]) + std::abs(q[1] - p[1]) + std::abs(q[2] - p[2]) < 1e-5;
    });
  };
  ASSERT_TRUE(has(g.positions, read->grid().position(2, 3, 4)));  // in memory: the axis-aligned frame
  io::write_graph(g, dir / "g.swc", io::GraphFormat::swc);
  const SpatialGraph swc = io::read_graph(dir / "g.swc", io::GraphFormat::swc);
  EXPECT_TRUE(has(swc.positions, end_voxel_world));  // in the file: world coordinates
  EXPECT_TRUE(has(swc.positions, world_position(read->grid().position(9, 8, 4), read->origin(), d)));
  EXPECT_FALSE(has(swc.positions, read->grid().position(2, 3, 4)));
  for (const auto format : {io::GraphFormat::vtp, io::GraphFormat::amira}) {
    const auto file = dir / (format == io::GraphFormat::vtp ? "g.vtp" : "g.am");
    io::write_graph(g, file, format);
    const SpatialGraph back = io::read_graph(file, format);
    EXPECT_EQ(back.source_grid.direction, d);
    ASSERT_EQ(back.positions.size(), g.positions.size());
    for (size_t i = 0; i < g.positions.size(); ++i)
      for (size_t k = 0; k < 3; ++k) EXPECT_NEAR(back.positions[i][k], g.positions[i][k], 1e-5) << file;
  }

  const Mesh mesh = geometry::skeleton_to_mesh(*read);
  ASSERT_GT(mesh.vertex_count(), 0);
  io::write_mesh(mesh, dir / "m.ply", io::MeshFormat::ply);
  const Mesh ply = io::read_mesh(dir / "m.ply", io::MeshFormat::ply);
  ASSERT_EQ(ply.vertex_count(), mesh.vertex_count());
  bool end_seen = false;
  for (int64_t i = 0; i < ply.vertex_count(); ++i) {
    const auto& p = mesh.points[static_cast<size_t>(i)];
    const Vec3 w = world_position({p[0], p[1], p[2]}, read->origin(), d);
    for (size_t k = 0; k < 3; ++k) EXPECT_NEAR(ply.points[static_cast<size_t>(i)][k], w[k], 1e-4);
    end_seen = end_seen || std::abs(ply.points[static_cast<size_t>(i)][0] - end_voxel_world[0]) +
                                   std::abs(ply.points[static_cast<size_t>(i)][1] - end_voxel_world[1]) +
                                   std::abs(ply.points[static_cast<size_t>(i)][2] - end_voxel_world[2]) < 1e-4;
  }
  EXPECT_TRUE(end_seen);
}
