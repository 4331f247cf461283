// geometry.mesh_smooth, geometry.mesh_decimate, geometry.isosurface: decimation to 2 % keeps a curved
// plate within one voxel of the undecimated mesh (Hausdorff, both directions, brute force), fixed
// vertices stay where they are with their lines attached, smoothing keeps topology and reduces the
// voxel staircase, the iso-surface is closed and has more triangles than the skeleton's mesh.
#include "geometry/mesh_filters.hpp"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <map>
#include <numbers>
#include <set>

#include "geometry/names.hpp"
#include "geometry/skeleton_to_graph.hpp"
#include "geometry/skeleton_to_mesh.hpp"
#include "skel/error.hpp"
#include "skel/run_module.hpp"

using namespace skel;
using namespace skel::geometry;

namespace {

using P = std::array<double, 3>;
P sub(P a, P b) { return {a[0] - b[0], a[1] - b[1], a[2] - b[2]}; }
double dot(P a, P b) { return a[0] * b[0] + a[1] * b[1] + a[2] * b[2]; }
P to_p(const Mesh::Point& q) { return {q[0], q[1], q[2]}; }

// Distance from p to triangle abc (closest point by regions, Ericson 5.1.5).
double point_triangle(P p, P a, P b, P c) {
  const P ab = sub(b, a), ac = sub(c, a), ap = sub(p, a);
  auto len = [&](P q) { return std::sqrt(dot(sub(p, q), sub(p, q))); };
  auto at = [&](P o, P d, double t) { return P{o[0] + t * d[0], o[1] + t * d[1], o[2] + t * d[2]}; };
  const double d1 = dot(ab, ap), d2 = dot(ac, ap);
  if (d1 <= 0 && d2 <= 0) return len(a);
  const P bp = sub(p, b);
  const double d3 = dot(ab, bp), d4 = dot(ac, bp);
  if (d3 >= 0 && d4 <= d3) return len(b);
  const double vc = d1 * d4 - d3 * d2;
  if (vc <= 0 && d1 >= 0 && d3 <= 0) return len(at(a, ab, d1 / (d1 - d3)));
  const P cp = sub(p, c);
  const double d5 = dot(ab, cp), d6 = dot(ac, cp);
  if (d6 >= 0 && d5 <= d6) return len(c);
  const double vb = d5 * d2 - d1 * d6;
  if (vb <= 0 && d2 >= 0 && d6 <= 0) return len(at(a, ac, d2 / (d2 - d6)));
  const double va = d3 * d6 - d5 * d4;
  if (va <= 0 && (d4 - d3) >= 0 && (d5 - d6) >= 0) return len(at(b, sub(c, b), (d4 - d3) / ((d4 - d3) + (d5 - d6))));
  const double denom = 1.0 / (va + vb + vc), v = vb * denom, w = vc * denom;
  return len(P{a[0] + ab[0] * v + ac[0] * w, a[1] + ab[1] * v + ac[1] * w, a[2] + ab[2] * v + ac[2] * w});
}

// Largest distance from a triangle vertex of `from` to the triangles of `to`.
double one_sided_hausdorff(const Mesh& from, const Mesh& to) {
  std::set<int64_t> vs;
  for (const auto& t : from.triangles) vs.insert(t.begin(), t.end());
  double worst = 0.0;
  for (int64_t v : vs) {
    double best = 1e300;
    for (const auto& t : to.triangles)
      best = std::min(best, point_triangle(to_p(from.points[v]), to_p(to.points[t[0]]), to_p(to.points[t[1]]),
                                           to_p(to.points[t[2]])));
    worst = std::max(worst, best);
  }
  return worst;
}

double wave(double x) { return 8.0 + 4.0 * std::sin(2.0 * std::numbers::pi * x / 40.0); }

// A one-voxel-thick corrugated plate z = round(wave(x)), with a rod standing on it at (30, 20).
VolumeU8 corrugated_plate(bool rod) {
  VolumeU8 v({62, 42, 24}, 0);
  for (int64_t y = 1; y < 41; ++y)
    for (int64_t x = 1; x < 61; ++x) v(x, y, static_cast<int64_t>(std::lround(wave(static_cast<double>(x))))) = 1;
  if (rod) {
    const auto z0 = std::lround(wave(30.0));
    for (int64_t z = z0 + 1; z < 23; ++z) v(30, 20, z) = 1;
  }
  return v;
}

std::map<std::pair<int64_t, int64_t>, int> edge_uses(const Mesh& m) {
  std::map<std::pair<int64_t, int64_t>, int> uses;
  for (const auto& t : m.triangles)
    for (int a = 0; a < 3; ++a) ++uses[{std::min(t[a], t[(a + 1) % 3]), std::max(t[a], t[(a + 1) % 3])}];
  return uses;
}

}  // namespace

TEST(MeshFilters, DecimationKeepsPlateWithinOneVoxel) {
  const Mesh full = skeleton_to_mesh(corrugated_plate(true));
  ASSERT_GT(full.triangle_count(), 8000);
  MeshDecimateOptions o;
  o.keep = 0.02;
  const Mesh dec = mesh_decimate(full, o);
  EXPECT_TRUE(dec.check_invariants().empty());
  EXPECT_LE(dec.triangle_count(), full.triangle_count() * 3 / 100);
  EXPECT_GT(dec.triangle_count(), 0);
  EXPECT_LT(one_sided_hausdorff(dec, full), 1.0);
  EXPECT_LT(one_sided_hausdorff(full, dec), 1.0);
  // The 1-x-junction where the rod stands is still a surface vertex, at its place, with the rod's line.
  const auto& fixed = Mesh::attribute<int32_t>(full.vertex_attributes, "fixed");
  ASSERT_EQ(std::count(fixed.begin(), fixed.end(), 1), 1);
  const Mesh::Point j = full.points[std::find(fixed.begin(), fixed.end(), 1) - fixed.begin()];
  ASSERT_EQ(dec.line_count(), 1);
  const int64_t end0 = dec.line_vertices.front(), end1 = dec.line_vertices.back();
  const int64_t at_j = dec.points[end0] == j ? end0 : end1;
  EXPECT_EQ(dec.points[at_j], j);
  bool on_surface = false;
  for (const auto& t : dec.triangles) on_surface = on_surface || std::find(t.begin(), t.end(), at_j) != t.end();
  EXPECT_TRUE(on_surface);
  EXPECT_EQ(Mesh::attribute<int32_t>(dec.vertex_attributes, "fixed")[at_j], 1);
  EXPECT_EQ(attribute_size(dec.triangle_attributes.at("manifold")), dec.triangle_count());
}

TEST(MeshFilters, SmoothingKeepsTopologyAndFixedVertices) {
  const Mesh m = skeleton_to_mesh(corrugated_plate(true));
  const Mesh s = mesh_smooth(m);
  EXPECT_EQ(s.triangles, m.triangles);
  EXPECT_EQ(s.line_vertices, m.line_vertices);
  EXPECT_EQ(s.vertex_attributes, m.vertex_attributes);
  const auto& fixed = Mesh::attribute<int32_t>(m.vertex_attributes, "fixed");
  double dev_before = 0, dev_after = 0;
  int64_t moved = 0, n = 0;
  const auto& cls = Mesh::attribute<int32_t>(m.vertex_attributes, "manifold");
  for (int64_t v = 0; v < m.vertex_count(); ++v) {
    if (fixed[v]) {
      EXPECT_EQ(s.points[v], m.points[v]);
    }
    moved += s.points[v] != m.points[v];
    const double dz = s.points[v][2] - m.points[v][2];
    EXPECT_LT(std::abs(dz), 1.0);
    if (cls[v] == static_cast<int32_t>(ManifoldType::surface) && m.points[v][2] < 20) {  // the plate's inside
      dev_before += std::abs(m.points[v][2] - wave(m.points[v][0]));
      dev_after += std::abs(s.points[v][2] - wave(s.points[v][0]));
      ++n;
    }
  }
  EXPECT_GT(moved, m.vertex_count() / 2);
  ASSERT_GT(n, 1000);
  EXPECT_LT(dev_after, 0.8 * dev_before);  // the voxel staircase is smoothed towards the wave
}

TEST(MeshFilters, IsosurfaceIsClosedAndHasMoreTrianglesThanSkeletonMesh) {
  VolumeU8 ball({16, 16, 16}, 0, {0.5, 0.5, 0.5});
  for (int64_t z = 0; z < 16; ++z)
    for (int64_t y = 0; y < 16; ++y)
      for (int64_t x = 0; x < 16; ++x)
        if ((x - 7) * (x - 7) + (y - 7) * (y - 7) + (z - 15) * (z - 15) <= 36) ball(x, y, z) = 1;  // touches z = 15
  const Mesh iso = isosurface(ball);
  for (const auto& [e, uses] : edge_uses(iso)) EXPECT_EQ(uses, 2);
  std::set<int64_t> vs;
  for (const auto& t : iso.triangles) vs.insert(t.begin(), t.end());
  EXPECT_EQ(static_cast<int64_t>(vs.size()) - static_cast<int64_t>(edge_uses(iso).size()) + iso.triangle_count(), 2);
  // The thesis's claim: a plate's skeleton mesh has fewer triangles than the iso-surface of the same voxels.
  const VolumeU8 plate = corrugated_plate(false);
  EXPECT_LT(skeleton_to_mesh(plate).triangle_count(), isosurface(plate).triangle_count());
}

TEST(MeshFilters, ModulesAndErrors) {
  auto m = std::make_shared<Mesh>(skeleton_to_mesh(corrugated_plate(false)));
  auto r = run_module(names::mesh_decimate, {{"mesh", m}}, {{"keep", 0.1}}, {.threads = 1});
  EXPECT_LT(r.get<Mesh>("mesh")->triangle_count(), m->triangle_count() / 5);
  r = run_module(names::mesh_smooth, {{"mesh", m}}, {{"iterations", int64_t{5}}}, {.threads = 1});
  EXPECT_EQ(r.get<Mesh>("mesh")->triangles, m->triangles);
  auto v = std::make_shared<VolumeU8>(corrugated_plate(false));
  r = run_module(names::isosurface, {{"volume", v}}, {}, {.threads = 1});
  EXPECT_GT(r.get<Mesh>("mesh")->triangle_count(), 0);
  Mesh bad = *m;
  bad.vertex_attributes["fixed"] = std::vector<float>(bad.vertex_count(), 0.0f);
  MeshSmoothOptions so;
  EXPECT_THROW(mesh_smooth(bad, so), InputError);
  MeshDecimateOptions dopt;
  dopt.keep = 0.0;
  EXPECT_THROW(mesh_decimate(*m, dopt), InputError);
}
