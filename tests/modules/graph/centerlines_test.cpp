// graph.merge_centerlines: overlapping inlet–outlet paths (VMTK centerlines) become one branch graph.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>

#include "graph/centerlines.hpp"
#include "skel/error.hpp"

using namespace skel;
using namespace skel::graph;

namespace {

// Points every `step` from a to b (a included, b excluded), with a small deterministic wobble
// across the line, as two independently traced paths have.
void sample(std::vector<Vec3>& out, const Vec3& a, const Vec3& b, double step, double wobble, int phase) {
  const double len = std::hypot(b[0] - a[0], b[1] - a[1], b[2] - a[2]);
  const int n = std::max(1, static_cast<int>(std::round(len / step)));
  for (int i = 0; i < n; ++i) {
    const double t = static_cast<double>(i) / n;
    const double w = wobble * std::sin(1.7 * (i + phase));
    out.push_back({a[0] + t * (b[0] - a[0]), a[1] + t * (b[1] - a[1]), a[2] + t * (b[2] - a[2]) + w});
  }
}

// A tree with three outlets: trunk inlet (0,0,0) -> J1 (10,0,0); J1 -> A (20,6,0); J1 -> J2 (16,-3,0);
// J2 -> B1 (24,-3,0); J2 -> B2 (21,-10,0). Three paths inlet -> A, B1, B2 with different sampling.
SpatialGraph three_paths(bool radii) {
  const Vec3 in{0, 0, 0}, j1{10, 0, 0}, a{20, 6, 0}, j2{16, -3, 0}, b1{24, -3, 0}, b2{21, -10, 0};
  SpatialGraph g;
  const std::vector<std::vector<Vec3>> legs = {{in, j1, a}, {in, j1, j2, b1}, {in, j1, j2, b2}};
  const double steps[] = {0.5, 0.7, 0.6};
  for (size_t k = 0; k < legs.size(); ++k) {
    std::vector<Vec3> pts;
    for (size_t s = 0; s + 1 < legs[k].size(); ++s) sample(pts, legs[k][s], legs[k][s + 1], steps[k], 0.05, static_cast<int>(k));
    pts.push_back(legs[k].back());
    const int64_t n0 = g.add_node(pts.front()), n1 = g.add_node(pts.back());
    g.add_edge(n0, n1, pts);
  }
  if (radii) {
    auto& r = g.ensure_point_attribute("MaximumInscribedSphereRadius");
    for (auto& e : r) std::fill(e.begin(), e.end(), 0.8f);
  }
  g.unit = "mm";
  return g;
}

}  // namespace

TEST(MergeCenterlines, ThreeOverlappingPathsBecomeFiveBranches) {
  const SpatialGraph paths = three_paths(true);
  const SpatialGraph g = merge_centerlines(paths, {});
  EXPECT_TRUE(g.check_invariants().empty());
  EXPECT_EQ(g.unit, "mm");
  ASSERT_EQ(g.edge_count(), 5);  // trunk, A, J1-J2, B1, B2
  ASSERT_EQ(g.node_count(), 6);  // inlet, two bifurcations, three outlets
  const auto deg = g.degrees();
  EXPECT_EQ(std::count(deg.begin(), deg.end(), 1), 4);
  EXPECT_EQ(std::count(deg.begin(), deg.end(), 3), 2);
  EXPECT_EQ(g.cyclomatic_number(), 0);
  // Bifurcations where the paths part: within a couple of tolerances of the true junctions (a path
  // leaves its neighbour's tube a little after the junction).
  const Vec3 truth[] = {{10, 0, 0}, {16, -3, 0}};
  for (const Vec3& t : truth) {
    double best = 1e9;
    for (int64_t n = 0; n < g.node_count(); ++n)
      if (deg[n] == 3) best = std::min(best, std::hypot(g.positions[n][0] - t[0], g.positions[n][1] - t[1], g.positions[n][2] - t[2]));
    EXPECT_LT(best, 2.0 * 0.8);
  }
  // The trunk is counted once: the branch graph is as long as the tree (not the sum of the paths).
  const double tree = 10.0 + std::hypot(10.0, 6.0) + std::hypot(6.0, 3.0) + 8.0 + std::hypot(5.0, 7.0);
  double paths_len = 0;
  for (int64_t e = 0; e < paths.edge_count(); ++e) paths_len += paths.edge_length(e);
  EXPECT_NEAR(g.total_length(), tree, 0.03 * tree);
  EXPECT_GT(paths_len, 1.5 * tree);
  ASSERT_TRUE(g.point_attributes.count("radius"));
  EXPECT_EQ(g.point_attributes.at("radius")[0].front(), 0.8f);
}

TEST(MergeCenterlines, AbsoluteToleranceWithoutRadiiAndErrors) {
  const SpatialGraph paths = three_paths(false);
  EXPECT_THROW(merge_centerlines(paths, {}), InputError);  // no radii and no tolerance
  MergeCenterlinesOptions o;
  o.tolerance = 0.8;
  const SpatialGraph g = merge_centerlines(paths, o);
  EXPECT_EQ(g.edge_count(), 5);
  EXPECT_EQ(g.node_count(), 6);
  EXPECT_FALSE(g.point_attributes.count("radius"));
  // A tolerance far below the wobble between the paths keeps them apart: three separate paths.
  o.tolerance = 1e-9;
  const SpatialGraph apart = merge_centerlines(paths, o);
  EXPECT_EQ(apart.connected_components(), 3);
  EXPECT_EQ(apart.edge_count(), 3);
  EXPECT_NEAR(apart.total_length(), [&] {
    double s = 0;
    for (int64_t e = 0; e < paths.edge_count(); ++e) s += paths.edge_length(e);
    return s;
  }(), 1e-9);
}
