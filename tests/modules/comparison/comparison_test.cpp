// comparison: skeleton distance (seeded EDT and k-d tree against brute force, shifts by one voxel),
// optimal assignment against brute force, graph matching with known deletions/additions.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <functional>
#include <limits>
#include <random>
#include <set>

#include "comparison/comparison.hpp"
#include "skel/error.hpp"

using namespace skel;
using namespace skel::comparison;

namespace {

double dist(const Vec3& a, const Vec3& b) {
  return std::sqrt((a[0] - b[0]) * (a[0] - b[0]) + (a[1] - b[1]) * (a[1] - b[1]) + (a[2] - b[2]) * (a[2] - b[2]));
}

std::vector<Vec3> voxel_points(const VolumeU8& v) {
  std::vector<Vec3> p;
  for (int64_t z = 0; z < v.nz(); ++z)
    for (int64_t y = 0; y < v.ny(); ++y)
      for (int64_t x = 0; x < v.nx(); ++x)
        if (v(x, y, z)) p.push_back(v.grid().position(static_cast<double>(x), static_cast<double>(y), static_cast<double>(z)));
  return p;
}

double brute_nearest(const Vec3& p, const std::vector<Vec3>& pts) {
  double best = std::numeric_limits<double>::infinity();
  for (const Vec3& q : pts) best = std::min(best, dist(p, q));
  return best;
}

// A skeleton-like volume: random lines along y and z and isolated points, all voxels with even
// `even_axis` coordinate and at least one voxel from the border.
VolumeU8 random_skeleton(Dims d, Vec3 spacing, uint32_t seed, int even_axis) {
  VolumeU8 v(d, 0, spacing);
  std::mt19937 rng(seed);
  auto coord = [&](int axis) {
    int64_t c = 1 + static_cast<int64_t>(rng() % static_cast<uint32_t>(d[axis] - 2));
    if (axis == even_axis) c = std::min<int64_t>(d[axis] - 2, std::max<int64_t>(2, c & ~int64_t{1}));
    return c;
  };
  for (int line = 0; line < 6; ++line) {
    int axis = static_cast<int>(rng() % 3);
    if (axis == even_axis) axis = (axis + 1) % 3;
    int64_t p[3] = {coord(0), coord(1), coord(2)};
    for (int64_t t = 1; t < d[axis] - 1; ++t) {
      p[axis] = t;
      v(p[0], p[1], p[2]) = 1;
    }
  }
  for (int k = 0; k < 20; ++k) v(coord(0), coord(1), coord(2)) = 1;
  return v;
}

VolumeU8 shifted(const VolumeU8& v, int axis) {
  VolumeU8 out(v.grid(), 0);
  for (int64_t z = 0; z < v.nz(); ++z)
    for (int64_t y = 0; y < v.ny(); ++y)
      for (int64_t x = 0; x < v.nx(); ++x)
        if (v(x, y, z)) out(x + (axis == 0), y + (axis == 1), z + (axis == 2)) = 1;
  return out;
}

SkeletonInput vol(const DataObject& d, const std::string& name) {
  SkeletonInput in;
  in.volume = &d;
  in.name = name;
  return in;
}
SkeletonInput gr(const SpatialGraph& g, const std::string& name) {
  SkeletonInput in;
  in.graph = &g;
  in.name = name;
  return in;
}

}  // namespace

TEST(SkeletonDistance, IdenticalSkeletonsGiveZeros) {
  const VolumeU8 s = random_skeleton({24, 20, 16}, {0.5, 0.7, 2.0}, 3, -1);
  for (auto method : {DistanceMethod::Transform, DistanceMethod::KdTree}) {
    SkeletonDistanceOptions o;
    o.method = method;
    o.symmetric = true;
    o.threshold = 0.0;
    const auto r = skeleton_distance(vol(s, "reference"), vol(s, "other"), o);
    EXPECT_EQ(r.method_used, method);
    for (const DistanceStatistics* st : {&r.reference.stats, &r.other.stats, &r.symmetric}) {
      EXPECT_GT(st->points, 0);
      EXPECT_EQ(st->mean, 0.0);
      EXPECT_EQ(st->median, 0.0);
      EXPECT_EQ(st->p95, 0.0);
      EXPECT_EQ(st->max, 0.0);
      EXPECT_EQ(st->changed_points, 0);
      EXPECT_EQ(st->changed_fraction, 0.0);
    }
    for (int64_t i = 0; i < s.size(); ++i) {
      ASSERT_EQ(r.reference.distance[i], 0.0f);
      ASSERT_EQ(r.reference.changed[i], 0);
    }
    EXPECT_EQ(r.table.rows(), 3);
    for (const char* c : {"mean", "median", "p95", "hausdorff", "changed_fraction"})
      for (double v : r.table.reals(c)) EXPECT_EQ(v, 0.0) << c;
  }
}

TEST(SkeletonDistance, ShiftByOneVoxelGivesTheSpacingEverywhere) {
  // Every skeleton voxel has an even coordinate along the shift axis, so its own shifted copy is the
  // nearest point of the other skeleton: the distance is exactly the spacing along that axis.
  for (int axis : {0, 2}) {
    for (Vec3 spacing : {Vec3{1, 1, 1}, Vec3{0.5, 0.7, 2.0}}) {
      SCOPED_TRACE("axis " + std::to_string(axis) + " spacing " + std::to_string(spacing[0]));
      const VolumeU8 a = random_skeleton({26, 22, 18}, spacing, 7 + static_cast<uint32_t>(axis), axis);
      const VolumeU8 b = shifted(a, axis);
      for (auto method : {DistanceMethod::Transform, DistanceMethod::KdTree}) {
        SkeletonDistanceOptions o;
        o.method = method;
        o.symmetric = true;
        o.threshold = 0.999 * spacing[static_cast<size_t>(axis)];
        const auto r = skeleton_distance(vol(a, "reference"), vol(b, "other"), o);
        const double s = spacing[static_cast<size_t>(axis)];
        for (const SideDistances* side : {&r.reference, &r.other})
          for (double v : side->values) ASSERT_NEAR(v, s, 1e-6 * s);
        EXPECT_NEAR(r.reference.stats.mean, s, 1e-6 * s);
        EXPECT_NEAR(r.reference.stats.median, s, 1e-6 * s);
        EXPECT_NEAR(r.reference.stats.p95, s, 1e-6 * s);
        EXPECT_NEAR(r.symmetric.max, s, 1e-6 * s);
        EXPECT_EQ(r.reference.stats.changed_fraction, 1.0);
        EXPECT_EQ(r.other.stats.changed_points, r.other.stats.points);
        for (int64_t i = 0; i < a.size(); ++i) {
          if (a[i]) ASSERT_NEAR(r.reference.distance[i], s, 1e-6 * s);
          else ASSERT_EQ(r.reference.distance[i], 0.0f);
          ASSERT_EQ(r.reference.changed[i], a[i]);
        }
      }
    }
  }
}

TEST(SkeletonDistance, TransformAndKdTreeEqualBruteForce) {
  for (uint32_t seed = 1; seed <= 4; ++seed) {
    const Vec3 spacing = seed % 2 ? Vec3{1, 1, 1} : Vec3{0.6, 1.1, 1.7};
    const VolumeU8 a = random_skeleton({20, 18, 14}, spacing, seed, -1);
    const VolumeU8 b = random_skeleton({20, 18, 14}, spacing, seed + 100, -1);
    const auto pa = voxel_points(a), pb = voxel_points(b);
    for (auto method : {DistanceMethod::Transform, DistanceMethod::KdTree}) {
      SkeletonDistanceOptions o;
      o.method = method;
      o.threshold = 3.0;
      const auto r = skeleton_distance(vol(a, "reference"), vol(b, "other"), o);
      ASSERT_EQ(r.reference.values.size(), pa.size());
      std::vector<double> bf;
      for (size_t i = 0; i < pa.size(); ++i) {
        bf.push_back(brute_nearest(pa[i], pb));
        ASSERT_NEAR(r.reference.values[i], bf.back(), 1e-5 * (1 + bf.back()));
      }
      // Statistics against their definitions.
      std::vector<double> sorted = bf;
      std::sort(sorted.begin(), sorted.end());
      const size_t n = sorted.size();
      EXPECT_NEAR(r.reference.stats.median, sorted[(n + 1) / 2 - 1], 1e-5);
      EXPECT_NEAR(r.reference.stats.p95, sorted[static_cast<size_t>(std::ceil(0.95 * static_cast<double>(n))) - 1], 1e-5);
      EXPECT_NEAR(r.reference.stats.max, sorted.back(), 1e-5);
      double sum = 0;
      int64_t changed = 0;
      for (double v : bf) {
        sum += v;
        changed += v > 3.0;
      }
      EXPECT_NEAR(r.reference.stats.mean, sum / static_cast<double>(n), 1e-5);
      EXPECT_EQ(r.reference.stats.changed_points, changed);
      EXPECT_DOUBLE_EQ(r.reference.stats.changed_fraction, static_cast<double>(changed) / static_cast<double>(n));
    }
  }
}

TEST(SkeletonDistance, DifferentGridsAndGraphsUseTheKdTree) {
  const VolumeU8 a = random_skeleton({20, 18, 14}, {1, 1, 1}, 11, -1);
  VolumeU8 b = random_skeleton({16, 22, 10}, {0.8, 0.9, 1.5}, 12, -1);
  b.set_origin({2.5, -1.0, 3.0});
  const auto pa = voxel_points(a), pb = voxel_points(b);
  SkeletonDistanceOptions o;
  o.symmetric = true;
  const auto r = skeleton_distance(vol(a, "reference"), vol(b, "other"), o);
  EXPECT_EQ(r.method_used, DistanceMethod::KdTree);
  for (size_t i = 0; i < pa.size(); ++i) ASSERT_NEAR(r.reference.values[i], brute_nearest(pa[i], pb), 1e-12);
  for (size_t i = 0; i < pb.size(); ++i) ASSERT_NEAR(r.other.values[i], brute_nearest(pb[i], pa), 1e-12);
  EXPECT_EQ(r.other.distance.grid(), b.grid());
  EXPECT_NEAR(r.symmetric.max, std::max(r.reference.stats.max, r.other.stats.max), 0.0);
  o.method = DistanceMethod::Transform;
  try {
    (void)skeleton_distance(vol(a, "reference"), vol(b, "other"), o);
    FAIL() << "transform on different grids must fail";
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("method"), std::string::npos);
  }
}

TEST(SkeletonDistance, GraphReferenceGetsPointAttributesAndLengthWeights) {
  // Two straight edges; the other graph is the same shifted by 2 along z.
  SpatialGraph g;
  g.add_node({0, 0, 0});
  g.add_node({10, 0, 0});
  g.add_node({10, 6, 0});
  g.add_edge(0, 1, {{0, 0, 0}, {2.5, 0, 0}, {5, 0, 0}, {10, 0, 0}});
  g.add_edge(1, 2);
  SpatialGraph h = g;
  for (auto& p : h.positions) p[2] += 2.0;
  for (auto& e : h.edges)
    for (auto& p : e.points) p[2] += 2.0;
  SkeletonDistanceOptions o;
  o.sample_spacing = 0.25;
  o.threshold = 1.0;
  o.symmetric = true;
  const auto self = skeleton_distance(gr(g, "reference"), gr(g, "other"), o);
  EXPECT_EQ(self.reference.stats.max, 0.0);
  EXPECT_EQ(self.symmetric.max, 0.0);
  const auto r = skeleton_distance(gr(g, "reference"), gr(h, "other"), o);
  ASSERT_TRUE(r.reference.is_graph);
  EXPECT_NEAR(r.reference.stats.weight, 16.0, 1e-12);  // total length
  EXPECT_NEAR(r.reference.stats.mean, 2.0, 1e-12);
  EXPECT_NEAR(r.reference.stats.changed_fraction, 1.0, 1e-12);
  const auto& d = r.reference.graph.point_attributes.at("distance");
  const auto& c = r.reference.graph.point_attributes.at("changed");
  ASSERT_EQ(d.size(), 2u);
  for (size_t e = 0; e < 2; ++e)
    for (size_t i = 0; i < d[e].size(); ++i) {
      EXPECT_NEAR(d[e][i], 2.0f, 1e-6);
      EXPECT_EQ(c[e][i], 1.0f);
    }
  EXPECT_EQ(r.reference.graph.edge_attributes.at("changed_fraction")[0], 1.0f);
  // A graph against a volume and back: a line of voxels vs. the same line as a graph.
  VolumeU8 v({12, 3, 3}, 0);
  for (int64_t x = 0; x < 12; ++x) v(x, 1, 1) = 1;
  SpatialGraph line;
  line.add_node({0, 1, 1});
  line.add_node({11, 1, 1});
  line.add_edge(0, 1);
  SkeletonDistanceOptions o2;
  o2.symmetric = true;
  const auto m = skeleton_distance(vol(v, "reference"), gr(line, "other"), o2);
  EXPECT_LE(m.symmetric.max, 0.25 + 1e-12);  // automatic spacing: half the voxel size
  o2.method = DistanceMethod::Transform;
  EXPECT_THROW((void)skeleton_distance(vol(v, "reference"), gr(line, "other"), o2), InputError);
}

TEST(SkeletonDistance, ErrorsNameThePort) {
  VolumeF32 f({4, 4, 4}, 0.0f);
  VolumeU8 u({4, 4, 4}, 0);
  try {
    (void)skeleton_distance(vol(f, "reference"), vol(u, "other"));
    FAIL();
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("reference"), std::string::npos);
  }
  SkeletonDistanceOptions o;
  o.threshold = -1;
  EXPECT_THROW((void)skeleton_distance(vol(u, "reference"), vol(u, "other"), o), InputError);
  // An empty other skeleton: infinite distances, every point changed.
  u(1, 1, 1) = 1;
  const VolumeU8 empty({4, 4, 4}, 0);
  const auto r = skeleton_distance(vol(u, "reference"), vol(empty, "other"));
  EXPECT_TRUE(std::isinf(r.reference.stats.max));
  EXPECT_EQ(r.reference.stats.changed_points, 1);
}

TEST(SkeletonDistance, ResultsDoNotDependOnThreads) {
  const VolumeU8 a = random_skeleton({40, 36, 30}, {0.6, 1.1, 1.7}, 21, -1);
  const VolumeU8 b = random_skeleton({40, 36, 30}, {0.6, 1.1, 1.7}, 22, -1);
  for (auto method : {DistanceMethod::Transform, DistanceMethod::KdTree}) {
    std::vector<SkeletonDistanceResult> rs;
    for (int t : {1, 2, 4}) {
      SkeletonDistanceOptions o;
      o.method = method;
      o.symmetric = true;
      o.threads = t;
      rs.push_back(skeleton_distance(vol(a, "reference"), vol(b, "other"), o));
    }
    for (size_t k = 1; k < rs.size(); ++k) {
      EXPECT_EQ(rs[k].reference.values, rs[0].reference.values);
      EXPECT_EQ(rs[k].other.values, rs[0].other.values);
      EXPECT_TRUE(rs[k].reference.distance == rs[0].reference.distance);
      EXPECT_TRUE(rs[k].reference.changed == rs[0].reference.changed);
      EXPECT_EQ(rs[k].table.to_csv(), rs[0].table.to_csv());
    }
  }
}

TEST(WeightedQuantile, Definition) {
  EXPECT_EQ(weighted_quantile({}, 0.5), 0.0);
  EXPECT_EQ(weighted_quantile({{1, 1}, {2, 1}, {3, 1}, {4, 1}}, 0.5), 2.0);
  EXPECT_EQ(weighted_quantile({{1, 1}, {2, 1}, {3, 1}, {4, 1}}, 0.51), 3.0);
  EXPECT_EQ(weighted_quantile({{4, 3}, {1, 1}}, 0.5), 4.0);
  EXPECT_EQ(weighted_quantile({{1, 0}, {2, 0}, {5, 2}}, 0.1), 5.0);
  EXPECT_EQ(weighted_quantile({{1, 1}, {9, 1}}, 1.0), 9.0);
}

TEST(ResamplePolyline, EqualStepsAndWeights) {
  std::vector<Vec3> s;
  std::vector<double> w;
  resample_polyline({{0, 0, 0}, {3, 0, 0}, {3, 4, 0}}, 1.0, s, w);
  ASSERT_EQ(s.size(), 8u);  // length 7, 7 steps
  EXPECT_EQ(s.front(), (Vec3{0, 0, 0}));
  EXPECT_EQ(s.back(), (Vec3{3, 4, 0}));
  EXPECT_NEAR(s[4][0], 3.0, 1e-12);
  EXPECT_NEAR(s[4][1], 1.0, 1e-12);
  double total = 0;
  for (double x : w) total += x;
  EXPECT_NEAR(total, 7.0, 1e-12);
  resample_polyline({{0, 0, 0}, {2.5, 0, 0}}, 1.0, s, w);
  ASSERT_EQ(s.size(), 4u);  // 3 steps of 5/6
  for (size_t i = 1; i < s.size(); ++i) EXPECT_NEAR(dist(s[i], s[i - 1]), 2.5 / 3, 1e-12);
}

// ---------------------------------------------------------------------------------------------

namespace {
struct BestMatching {
  int64_t pairs = 0;
  double cost = 0;
};
// Exhaustive: maximum number of pairs, then least cost.
BestMatching brute_force(int64_t nl, int64_t nr, const std::vector<AssignmentCandidate>& c) {
  BestMatching best;
  std::vector<char> used(static_cast<size_t>(nr), 0);
  std::function<void(int64_t, int64_t, double)> rec = [&](int64_t l, int64_t pairs, double cost) {
    if (l == nl) {
      if (pairs > best.pairs || (pairs == best.pairs && cost < best.cost)) best = {pairs, cost};
      return;
    }
    rec(l + 1, pairs, cost);
    for (const auto& x : c)
      if (x.left == l && !used[static_cast<size_t>(x.right)]) {
        used[static_cast<size_t>(x.right)] = 1;
        rec(l + 1, pairs + 1, cost + x.cost);
        used[static_cast<size_t>(x.right)] = 0;
      }
  };
  rec(0, 0, 0.0);
  return best;
}
}  // namespace

TEST(MinCostMatching, EqualsBruteForceOnSmallRandomCases) {
  std::mt19937 rng(5);
  for (int trial = 0; trial < 400; ++trial) {
    const int64_t nl = 1 + rng() % 7, nr = 1 + rng() % 7;
    std::vector<AssignmentCandidate> c;
    const double p = 0.2 + 0.6 * (rng() % 100) / 100.0;
    for (int64_t l = 0; l < nl; ++l)
      for (int64_t r = 0; r < nr; ++r)
        if ((rng() % 1000) / 1000.0 < p) {
          // Integer costs create many ties; real costs test the potentials.
          const double cost = trial % 2 ? static_cast<double>(rng() % 4) : (rng() % 100000) / 1000.0;
          c.push_back({l, r, cost});
        }
    std::shuffle(c.begin(), c.end(), rng);
    const auto m = min_cost_matching(nl, nr, c);
    ASSERT_EQ(static_cast<int64_t>(m.size()), nl);
    int64_t pairs = 0;
    double cost = 0;
    std::set<int64_t> rights;
    for (int64_t l = 0; l < nl; ++l) {
      if (m[static_cast<size_t>(l)] < 0) continue;
      ++pairs;
      ASSERT_TRUE(rights.insert(m[static_cast<size_t>(l)]).second) << "right node used twice";
      double best = std::numeric_limits<double>::infinity();  // cheapest candidate for this pair
      for (const auto& x : c)
        if (x.left == l && x.right == m[static_cast<size_t>(l)]) best = std::min(best, x.cost);
      ASSERT_TRUE(std::isfinite(best)) << "pair is not a candidate";
      cost += best;
    }
    const BestMatching bf = brute_force(nl, nr, c);
    ASSERT_EQ(pairs, bf.pairs) << "trial " << trial;
    ASSERT_NEAR(cost, bf.cost, 1e-9) << "trial " << trial;
  }
}

TEST(MinCostMatching, PrefersMoreMatchesOverLowerCost) {
  // Greedy would take (0,0) at cost 0 and leave left 1 unmatched.
  const auto m = min_cost_matching(2, 2, {{0, 0, 0.0}, {0, 1, 5.0}, {1, 0, 1.0}});
  EXPECT_EQ(m[0], 1);
  EXPECT_EQ(m[1], 0);
  EXPECT_THROW((void)min_cost_matching(1, 1, {{0, 1, 1.0}}), Error);
  EXPECT_THROW((void)min_cost_matching(1, 1, {{0, 0, -1.0}}), Error);
}

// ---------------------------------------------------------------------------------------------

namespace {
// A lattice graph (spacing 10) with slightly bent edges (3 interior points).
SpatialGraph lattice(int nx, int ny, int nz, uint32_t seed) {
  std::mt19937 rng(seed);
  auto jitter = [&] { return ((rng() % 1000) / 1000.0 - 0.5) * 1.0; };
  SpatialGraph g;
  auto id = [&](int i, int j, int k) { return static_cast<int64_t>(i + nx * (j + ny * k)); };
  for (int k = 0; k < nz; ++k)
    for (int j = 0; j < ny; ++j)
      for (int i = 0; i < nx; ++i) g.add_node({10.0 * i, 10.0 * j, 10.0 * k});
  for (int k = 0; k < nz; ++k)
    for (int j = 0; j < ny; ++j)
      for (int i = 0; i < nx; ++i)
        for (int a = 0; a < 3; ++a) {
          const int i2 = i + (a == 0), j2 = j + (a == 1), k2 = k + (a == 2);
          if (i2 >= nx || j2 >= ny || k2 >= nz) continue;
          const Vec3 p = g.positions[static_cast<size_t>(id(i, j, k))], q = g.positions[static_cast<size_t>(id(i2, j2, k2))];
          std::vector<Vec3> pts{p};
          for (int s = 1; s <= 3; ++s) {
            const double t = s / 4.0;
            pts.push_back({p[0] + t * (q[0] - p[0]) + jitter(), p[1] + t * (q[1] - p[1]) + jitter(), p[2] + t * (q[2] - p[2]) + jitter()});
          }
          pts.push_back(q);
          g.add_edge(id(i, j, k), id(i2, j2, k2), pts);
        }
  g.ensure_point_attribute("radius", 1.0f);
  return g;
}

GraphMatchOptions match_options(int threads = 0) {
  GraphMatchOptions o;
  o.node_tolerance = 2.0;
  o.edge_tolerance = 1.5;
  o.sample_spacing = 0.5;
  o.overlap = 0.8;
  o.threads = threads;
  return o;
}
}  // namespace

TEST(GraphMatch, GraphAgainstItselfIsPerfect) {
  const SpatialGraph g = lattice(5, 4, 3, 1);
  // And against a copy whose nodes and points moved by less than the tolerances.
  SpatialGraph moved = g;
  std::mt19937 rng(2);
  auto j = [&] { return ((rng() % 1000) / 1000.0 - 0.5) * 0.6; };
  for (size_t n = 0; n < moved.positions.size(); ++n) moved.positions[n] = {moved.positions[n][0] + j(), moved.positions[n][1] + j(), moved.positions[n][2] + j()};
  for (auto& e : moved.edges) {
    e.points.front() = moved.positions[static_cast<size_t>(e.node0)];
    e.points.back() = moved.positions[static_cast<size_t>(e.node1)];
    for (size_t i = 1; i + 1 < e.points.size(); ++i) e.points[i] = {e.points[i][0] + j(), e.points[i][1] + j(), e.points[i][2] + j()};
  }
  for (const SpatialGraph* other : {&g, static_cast<const SpatialGraph*>(&moved)}) {
    const auto r = graph_match(g, *other, match_options());
    for (const MatchCounts* c : {&r.nodes, &r.edges}) {
      EXPECT_EQ(c->fp, 0);
      EXPECT_EQ(c->fn, 0);
      EXPECT_EQ(c->precision, 1.0);
      EXPECT_EQ(c->recall, 1.0);
      EXPECT_EQ(c->f1, 1.0);
    }
    EXPECT_EQ(r.nodes.tp, static_cast<double>(g.node_count()));
    EXPECT_EQ(r.edges.tp, static_cast<double>(g.edge_count()));
    EXPECT_EQ(r.length.fn, 0.0);
    EXPECT_EQ(r.length.fp, 0.0);
    EXPECT_EQ(r.geometric_fnr, 0.0);
    EXPECT_EQ(r.geometric_fpr, 0.0);
    EXPECT_EQ(r.connectivity_fnr, 0.0);
    EXPECT_EQ(r.connectivity_fpr, 0.0);
    for (auto v : r.reference.node_labels.at("matched")) EXPECT_EQ(v, 1);
    for (auto v : r.other.edge_labels.at("matched")) EXPECT_EQ(v, 1);
    const auto& m = r.reference.node_labels.at("match");
    for (size_t n = 0; n < m.size(); ++n) EXPECT_EQ(m[n], static_cast<int32_t>(n));
    EXPECT_TRUE(r.reference.check_invariants().empty());
  }
}

TEST(GraphMatch, DeletedAndAddedEdgesAreExactlyTheMisses) {
  const SpatialGraph g = lattice(6, 5, 3, 3);
  std::mt19937 rng(4);
  for (int trial = 0; trial < 6; ++trial) {
    const int k = 1 + static_cast<int>(rng() % 8), jn = static_cast<int>(rng() % 6);
    SpatialGraph h = g;
    std::vector<int64_t> del;
    while (static_cast<int>(del.size()) < k) {
      const int64_t e = static_cast<int64_t>(rng() % static_cast<uint32_t>(g.edge_count()));
      if (std::find(del.begin(), del.end(), e) == del.end()) del.push_back(e);
    }
    h.remove_edges(del);
    // Added edges: face diagonals between lattice nodes (never an existing node pair), bent out of
    // the lattice planes; half of them end at a new node.
    int64_t new_nodes = 0;
    for (int a = 0; a < jn; ++a) {
      const int i = static_cast<int>(rng() % 5), jj = static_cast<int>(rng() % 4), kk = static_cast<int>(rng() % 3);
      const int64_t n0 = i + 6 * (jj + 5 * kk), n1 = (i + 1) + 6 * ((jj + 1) + 5 * kk);
      int64_t end = n1;
      if (a % 2) {
        end = h.add_node({10.0 * i + 5, 10.0 * jj + 5, 10.0 * kk + 4.5 + 0.01 * a});
        ++new_nodes;
      }
      const Vec3 p = h.positions[static_cast<size_t>(n0)], q = h.positions[static_cast<size_t>(end)];
      h.add_edge(n0, end, {p, {0.5 * (p[0] + q[0]), 0.5 * (p[1] + q[1]), 0.5 * (p[2] + q[2]) + 3.0 + 0.1 * a}, q});
    }
    const auto r = graph_match(g, h, match_options());
    SCOPED_TRACE("k " + std::to_string(k) + " j " + std::to_string(jn));
    EXPECT_EQ(r.edges.fn, static_cast<double>(k));
    EXPECT_EQ(r.edges.fp, static_cast<double>(jn));
    EXPECT_EQ(r.edges.tp, static_cast<double>(g.edge_count() - k));
    EXPECT_EQ(r.nodes.fn, 0.0);
    EXPECT_EQ(r.nodes.fp, static_cast<double>(new_nodes));
    int64_t unmatched = 0;
    for (auto v : r.reference.edge_labels.at("matched")) unmatched += v == 0;
    EXPECT_EQ(unmatched, k);
    const auto& ml = r.reference.edge_labels.at("matched");
    for (int64_t e : del) EXPECT_EQ(ml[static_cast<size_t>(e)], 0) << "deleted edge " << e;
    unmatched = 0;
    for (auto v : r.other.edge_labels.at("matched")) unmatched += v == 0;
    EXPECT_EQ(unmatched, jn);
    // The deleted edges' length is (mostly) not covered: geometric FNR > 0; nothing deleted -> 0.
    if (k > 0) {
      EXPECT_GT(r.geometric_fnr, 0.0);
    }
    EXPECT_EQ(r.connectivity_fnr, 0.0);  // no reference edge is found without its edge match
  }
}

TEST(GraphMatch, ConnectivityErrorWhenGeometryIsFoundButNodesDiffer) {
  // Reference: one straight edge 0-20 with a node in the middle (two edges). Other: one edge 0-20.
  SpatialGraph a, b;
  a.add_node({0, 0, 0});
  a.add_node({10, 0, 0});
  a.add_node({20, 0, 0});
  a.add_edge(0, 1);
  a.add_edge(1, 2);
  b.add_node({0, 0, 0});
  b.add_node({20, 0, 0});
  b.add_edge(0, 1);
  const auto r = graph_match(a, b, match_options());
  EXPECT_EQ(r.geometric_fnr, 0.0);
  EXPECT_EQ(r.geometric_fpr, 0.0);
  EXPECT_EQ(r.edges.tp, 0.0);
  EXPECT_EQ(r.edges.fn, 2.0);
  EXPECT_EQ(r.edges.fp, 1.0);
  EXPECT_EQ(r.connectivity_fnr, 1.0);
  EXPECT_EQ(r.connectivity_fpr, 1.0);
  EXPECT_EQ(r.nodes.fn, 1.0);
  EXPECT_NEAR(r.length.recall, 1.0, 1e-12);
}

TEST(GraphMatch, ResultsDoNotDependOnThreads) {
  const SpatialGraph g = lattice(8, 6, 4, 7);
  SpatialGraph h = lattice(8, 6, 4, 8);
  h.remove_edges({3, 10, 50});
  std::vector<std::string> csv;
  std::vector<std::vector<int32_t>> labels;
  for (int t : {1, 2, 4}) {
    const auto r = graph_match(g, h, match_options(t));
    csv.push_back(r.table.to_csv() + r.errors.to_csv());
    labels.push_back(r.other.edge_labels.at("match"));
  }
  EXPECT_EQ(csv[1], csv[0]);
  EXPECT_EQ(csv[2], csv[0]);
  EXPECT_EQ(labels[1], labels[0]);
  EXPECT_EQ(labels[2], labels[0]);
}

TEST(GraphMatch, InvalidParametersAreInputErrors) {
  const SpatialGraph g = lattice(2, 2, 1, 1);
  GraphMatchOptions o = match_options();
  o.overlap = 0;
  EXPECT_THROW((void)graph_match(g, g, o), InputError);
  o = match_options();
  o.sample_spacing = 0;
  EXPECT_THROW((void)graph_match(g, g, o), InputError);
  SpatialGraph broken = g;
  broken.edges[0].points.front()[0] += 1;  // end point no longer equals its node
  EXPECT_THROW((void)graph_match(g, broken, match_options()), InputError);
}

TEST(GraphMatch, CoverageAndEdgePairsEqualBruteForce) {
  // Reference vs a jittered copy with some edges removed: every edge `coverage`, every point
  // `covered` flag and every matched edge pair checked against brute-force sample distances.
  const SpatialGraph g = lattice(5, 4, 3, 11);
  SpatialGraph h = lattice(5, 4, 3, 11);
  std::mt19937 rng(5);
  auto j = [&] { return ((rng() % 1000) / 1000.0 - 0.5) * 2.4; };  // up to 1.2 per axis: some samples miss
  for (auto& e : h.edges)
    for (size_t i = 1; i + 1 < e.points.size(); ++i) e.points[i] = {e.points[i][0] + j(), e.points[i][1] + j(), e.points[i][2] + j()};
  h.remove_edges({1, 7, 20});
  const GraphMatchOptions o = match_options(2);
  const auto r = graph_match(g, h, o);
  auto samples = [&](const SpatialGraph& s) {
    std::vector<std::vector<Vec3>> out;
    std::vector<double> w;
    for (const auto& e : s.edges) {
      out.emplace_back();
      resample_polyline(e.points, o.sample_spacing, out.back(), w);
    }
    return out;
  };
  const auto sg = samples(g), sh = samples(h);
  auto near_any = [&](const Vec3& p, const std::vector<std::vector<Vec3>>& t, int64_t only) {
    for (size_t f = 0; f < t.size(); ++f)
      if (only < 0 || static_cast<int64_t>(f) == only)
        for (const Vec3& q : t[f])
          if (dist(p, q) <= o.edge_tolerance) return true;
    return false;
  };
  auto fraction = [&](const std::vector<Vec3>& s, const std::vector<std::vector<Vec3>>& t, int64_t only) {
    int64_t hit = 0;
    for (const Vec3& p : s) hit += near_any(p, t, only);
    return static_cast<double>(hit) / static_cast<double>(s.size());
  };
  int partial = 0, rejected = 0;
  for (size_t e = 0; e < g.edges.size(); ++e) {
    const double c = fraction(sg[e], sh, -1);
    partial += c < 1.0;
    EXPECT_FLOAT_EQ(r.reference.edge_attributes.at("coverage")[e], static_cast<float>(c)) << "edge " << e;
    for (size_t i = 0; i < g.edges[e].points.size(); ++i)
      EXPECT_EQ(r.reference.point_attributes.at("covered")[e][i], near_any(g.edges[e].points[i], sh, -1) ? 1.0f : 0.0f);
    const int32_t f = r.reference.edge_labels.at("match")[e];
    if (f >= 0) {
      EXPECT_GE(fraction(sg[e], sh, f), o.overlap) << "edge " << e;
      EXPECT_GE(fraction(sh[static_cast<size_t>(f)], sg, static_cast<int64_t>(e)), o.overlap) << "edge " << e;
    } else {
      // Unmatched: no other edge between the matched end nodes overlaps enough both ways.
      const auto& nm = r.reference.node_labels.at("match");
      const int32_t m0 = nm[static_cast<size_t>(g.edges[e].node0)], m1 = nm[static_cast<size_t>(g.edges[e].node1)];
      for (size_t k = 0; k < h.edges.size(); ++k) {
        const auto& hk = h.edges[k];
        if (std::minmax(hk.node0, hk.node1) != std::minmax<int64_t>(m0, m1)) continue;
        EXPECT_TRUE(fraction(sg[e], sh, static_cast<int64_t>(k)) < o.overlap ||
                    fraction(sh[k], sg, static_cast<int64_t>(e)) < o.overlap)
            << "edge " << e << " and " << k;
        ++rejected;
      }
    }
  }
  EXPECT_GT(partial, 0);   // the jitter makes some coverage fractions non-trivial
  EXPECT_GT(rejected, 0);  // and rejects some geometric candidates
  EXPECT_GE(r.edges.fn, 3.0);
}
