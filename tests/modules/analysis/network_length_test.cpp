// Length estimators of analysis.network_statistics (issue 21): digital straight lines and circles at
// random orientations, tubes of known length through the whole skeleton pipeline (EDT, thinning,
// dual-cube graph), and the end-cap convention of terminal branches.
#include <gtest/gtest.h>

#include <array>
#include <cmath>
#include <cstdio>
#include <numbers>
#include <random>

#include "analysis/network_analysis.hpp"
#include "distance/distance.hpp"
#include "geometry/skeleton_to_graph.hpp"
#include "skel/error.hpp"
#include "thinning/thinning.hpp"

using namespace skel;
using namespace skel::analysis;

namespace {

using Pt = std::array<int64_t, 3>;

Vec3 random_direction(std::mt19937_64& rng) {
  std::normal_distribution<double> n(0.0, 1.0);
  for (;;) {
    const Vec3 d{n(rng), n(rng), n(rng)};
    const double l = std::sqrt(d[0] * d[0] + d[1] * d[1] + d[2] * d[2]);
    if (l > 1e-6) return {d[0] / l, d[1] / l, d[2] / l};
  }
}
Vec3 cross(const Vec3& a, const Vec3& b) {
  return {a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]};
}
Vec3 unit(const Vec3& a) {
  const double l = std::sqrt(a[0] * a[0] + a[1] * a[1] + a[2] * a[2]);
  return {a[0] / l, a[1] / l, a[2] / l};
}

// A thin 26-connected voxel path digitising curve(t), t in [0, 1], sampled at `samples` points: each
// sample rounded to its voxel, repeats dropped, then every voxel whose neighbours along the path are
// 26-adjacent dropped (as thinning would: it is simple), so that the path is a skeleton-like curve.
template <class Curve>
std::vector<Pt> digitise(Curve curve, int64_t samples) {
  std::vector<Pt> v;
  for (int64_t i = 0; i <= samples; ++i) {
    const Vec3 p = curve(static_cast<double>(i) / static_cast<double>(samples));
    const Pt q{std::llround(p[0]), std::llround(p[1]), std::llround(p[2])};
    if (v.empty() || q != v.back()) v.push_back(q);
  }
  const auto adjacent = [](const Pt& a, const Pt& b) {
    return std::abs(a[0] - b[0]) <= 1 && std::abs(a[1] - b[1]) <= 1 && std::abs(a[2] - b[2]) <= 1;
  };
  std::vector<Pt> out{v.front()};
  for (size_t i = 1; i + 1 < v.size(); ++i)
    if (!adjacent(out.back(), v[i + 1])) out.push_back(v[i]);
  out.push_back(v.back());
  for (size_t i = 1; i < out.size(); ++i) EXPECT_TRUE(adjacent(out[i - 1], out[i]));
  return out;
}

// A graph of one edge along the voxel path (nodes at its first and last voxel; closed: one node, a
// loop edge back to it) on a unit grid of `size`³.
SpatialGraph path_graph(const std::vector<Pt>& path, int64_t size, bool closed) {
  SpatialGraph g;
  g.source_grid = Grid(Dims{size, size, size});
  std::vector<Vec3> pts;
  for (const auto& q : path) pts.push_back(Vec3{static_cast<double>(q[0]), static_cast<double>(q[1]), static_cast<double>(q[2])});
  if (closed) pts.push_back(pts.front());
  const int64_t a = g.add_node(pts.front());
  const int64_t b = closed ? a : g.add_node(pts.back());
  g.add_edge(a, b, pts);
  return g;
}

double total_length(const SpatialGraph& g, LengthEstimator estimator) {
  NetworkStatisticsOptions o;
  o.length_estimator = estimator;
  return network_statistics(g, o).summary.reals("total_length")[0];
}

struct Bias {
  double polyline = 0, tangent = 0, chain_code = 0, truth = 0;
  void add(const SpatialGraph& g, double true_length) {
    polyline += total_length(g, LengthEstimator::polyline);
    tangent += total_length(g, LengthEstimator::tangent);
    chain_code += total_length(g, LengthEstimator::chain_code);
    truth += true_length;
  }
  void print(const char* what) const {
    std::printf("%s: polyline %+.2f %%, tangent %+.2f %%, chain_code %+.2f %%\n", what, 100 * (polyline / truth - 1),
                100 * (tangent / truth - 1), 100 * (chain_code / truth - 1));
  }
};

}  // namespace

TEST(NetworkLength, TangentEstimatorIsUnbiasedOnDigitalStraightLinesAtRandomOrientations) {
  std::mt19937_64 rng(21);
  std::uniform_real_distribution<double> u(0.0, 1.0);
  Bias bias;
  for (int trial = 0; trial < 300; ++trial) {
    const Vec3 d = random_direction(rng);
    const Vec3 p0{40 + u(rng), 40 + u(rng), 40 + u(rng)};
    const double len = 60.0;
    const auto path = digitise([&](double t) { return Vec3{p0[0] + t * len * d[0], p0[1] + t * len * d[1], p0[2] + t * len * d[2]}; },
                               static_cast<int64_t>(len * 20));
    // The true length of the digitised segment: between the centres of its end voxels (the ends are
    // rounded like every other point).
    const Pt& a = path.front();
    const Pt& b = path.back();
    const double truth = std::sqrt(static_cast<double>((b[0] - a[0]) * (b[0] - a[0]) + (b[1] - a[1]) * (b[1] - a[1]) + (b[2] - a[2]) * (b[2] - a[2])));
    bias.add(path_graph(path, 128, false), truth);
  }
  bias.print("digital straight lines, length 60");
  EXPECT_NEAR(bias.tangent / bias.truth, 1.0, 0.01);
  EXPECT_NEAR(bias.chain_code / bias.truth, 1.0, 0.02);  // unbiased on average over directions (held at the chord)
  EXPECT_GT(bias.polyline / bias.truth, 1.06);           // the staircase the estimators correct
}

TEST(NetworkLength, TangentEstimatorIsExactAlongAxesWhereTheChainCodeIsNot) {
  std::vector<Pt> path;
  for (int64_t x = 2; x <= 42; ++x) path.push_back({x, 5, 5});
  const auto g = path_graph(path, 64, false);
  EXPECT_DOUBLE_EQ(total_length(g, LengthEstimator::polyline), 40.0);
  EXPECT_NEAR(total_length(g, LengthEstimator::tangent), 40.0, 1e-9);
  // 38 lattice steps weighted 0.9016 and the two steps to the nodes: below the chord, so the chord.
  EXPECT_DOUBLE_EQ(total_length(g, LengthEstimator::chain_code), 40.0);
  std::vector<Pt> bent;  // 20 steps along x, then 20 along y: 38 weighted steps + 2 exceed the chord
  for (int64_t x = 2; x <= 22; ++x) bent.push_back({x, 5, 5});
  for (int64_t y = 6; y <= 25; ++y) bent.push_back({22, y, 5});
  EXPECT_NEAR(total_length(path_graph(bent, 64, false), LengthEstimator::chain_code), 38 * 0.9016 + 2.0, 1e-9);
  std::vector<Pt> diagonal;
  for (int64_t i = 0; i <= 30; ++i) diagonal.push_back({2 + i, 3 + i, 4 + i});
  EXPECT_NEAR(total_length(path_graph(diagonal, 64, false), LengthEstimator::tangent), 30.0 * std::sqrt(3.0), 1e-9);
}

TEST(NetworkLength, TangentEstimatorIsUnbiasedOnDigitalCirclesAtRandomOrientations) {
  std::mt19937_64 rng(7);
  std::uniform_real_distribution<double> u(0.0, 1.0);
  for (const double radius : {15.0, 30.0}) {
    Bias bias;
    for (int trial = 0; trial < 60; ++trial) {
      const Vec3 a = random_direction(rng);
      const Vec3 b = unit(cross(a, random_direction(rng)));
      const Vec3 c = cross(a, b);
      const Vec3 o{50 + u(rng), 50 + u(rng), 50 + u(rng)};
      auto path = digitise(
          [&](double t) {
            const double phi = 2.0 * std::numbers::pi * t;
            const double cs = std::cos(phi) * radius, sn = std::sin(phi) * radius;
            return Vec3{o[0] + cs * b[0] + sn * c[0], o[1] + cs * b[1] + sn * c[1], o[2] + cs * b[2] + sn * c[2]};
          },
          static_cast<int64_t>(2 * std::numbers::pi * radius * 20));
      path.pop_back();  // t = 1 repeats t = 0
      bias.add(path_graph(path, 128, true), 2.0 * std::numbers::pi * radius);
    }
    bias.print(radius < 20 ? "digital circles, radius 15" : "digital circles, radius 30");
    EXPECT_NEAR(bias.tangent / bias.truth, 1.0, 0.01) << radius;
    EXPECT_GT(bias.polyline / bias.truth, 1.05) << radius;
  }
}

TEST(NetworkLength, EdgesThatAreNoVoxelPathsAreMeasuredAsPolylinesByEveryEstimator) {
  SpatialGraph g;
  g.source_grid = Grid(Dims{32, 32, 32});
  const int64_t a = g.add_node({1, 1, 1}), b = g.add_node({11, 1, 1}), c = g.add_node({11, 9, 4});
  g.add_edge(a, b, {{1, 1, 1}, {4, 1, 1}, {11, 1, 1}});                   // steps longer than a voxel
  g.add_edge(b, c, {{11, 1, 1}, {11.5, 2.2, 1.1}, {11.2, 3.1, 2.0}, {11, 9, 4}});  // off-grid (smoothed) points
  const double poly = g.total_length();
  EXPECT_DOUBLE_EQ(total_length(g, LengthEstimator::tangent), poly);
  EXPECT_DOUBLE_EQ(total_length(g, LengthEstimator::chain_code), poly);
  // A voxel path without a source grid is no voxel path either.
  std::vector<Pt> path;
  for (int64_t i = 0; i < 20; ++i) path.push_back({i, i / 2, 0});
  auto h = path_graph(path, 32, false);
  const double staircase = h.total_length();
  EXPECT_LT(total_length(h, LengthEstimator::tangent), staircase - 0.5);
  h.source_grid = Grid();
  EXPECT_DOUBLE_EQ(total_length(h, LengthEstimator::tangent), staircase);
}

namespace {

// `mask` -> exact EDT -> smooth DOHT (end_point_length 2) -> dual-cube graph with radii: the vessel
// pipeline's skeleton stages.
SpatialGraph skeleton_graph(const VolumeU8& mask, bool border_is_object = false) {
  distance::EuclideanOptions eo;
  eo.border_is_object = border_is_object;
  const VolumeF32 dist = distance::euclidean(mask, eo);
  thinning::ThinningOptions to;
  to.end_point_length = 2;
  const auto skel = thinning::thin_doht(mask, dist, nullptr, to);
  return geometry::skeleton_to_graph(skel.skeleton, &dist).graph;
}

// A capsule (all points within `radius` of the segment a-b) rasterised on an n³ grid.
VolumeU8 capsule(int64_t n, const Vec3& a, const Vec3& b, double radius) {
  VolumeU8 m(Grid(Dims{n, n, n}));
  const Vec3 ab{b[0] - a[0], b[1] - a[1], b[2] - a[2]};
  const double ll = ab[0] * ab[0] + ab[1] * ab[1] + ab[2] * ab[2];
  for (int64_t z = 0; z < n; ++z)
    for (int64_t y = 0; y < n; ++y)
      for (int64_t x = 0; x < n; ++x) {
        const Vec3 ap{static_cast<double>(x) - a[0], static_cast<double>(y) - a[1], static_cast<double>(z) - a[2]};
        const double t = std::clamp((ap[0] * ab[0] + ap[1] * ab[1] + ap[2] * ab[2]) / ll, 0.0, 1.0);
        const double dx = ap[0] - t * ab[0], dy = ap[1] - t * ab[1], dz = ap[2] - t * ab[2];
        m(x, y, z) = dx * dx + dy * dy + dz * dz <= radius * radius ? 1 : 0;
      }
  return m;
}

}  // namespace

TEST(NetworkLength, CapsuleSkeletonsHaveTheCentrelineLength) {
  // Capsules of radius 3.5-6 and centreline length 36 at random orientations. The distance-ordered
  // thinning ends the skeleton near the centres of the rounded ends, where the medial axis ends (it does
  // not run into the caps), so the tangent length of the one edge is the centreline's.
  std::mt19937_64 rng(3);
  std::uniform_real_distribution<double> u(0.0, 1.0);
  double truth = 0, tangent = 0, polyline = 0;
  for (int trial = 0; trial < 8; ++trial) {
    const double radius = 3.5 + 2.5 * u(rng), len = 36.0;
    const Vec3 d = random_direction(rng);
    const Vec3 c{32 + u(rng), 32 + u(rng), 32 + u(rng)};
    const Vec3 a{c[0] - 0.5 * len * d[0], c[1] - 0.5 * len * d[1], c[2] - 0.5 * len * d[2]};
    const Vec3 b{c[0] + 0.5 * len * d[0], c[1] + 0.5 * len * d[1], c[2] + 0.5 * len * d[2]};
    const auto g = skeleton_graph(capsule(64, a, b, radius));
    ASSERT_EQ(g.edge_count(), 1) << trial;
    ASSERT_EQ(g.degrees()[0], 1);
    const double t = total_length(g, LengthEstimator::tangent), p = total_length(g, LengthEstimator::polyline);
    std::printf("capsule r %.2f: tangent %.2f, polyline %.2f (centreline %.1f)\n", radius, t, p, len);
    EXPECT_NEAR(t, len, 2.0) << trial;  // each end within a voxel of its cap's centre
    truth += len;
    tangent += t;
    polyline += p;
  }
  std::printf("capsules: tangent %+.2f %%, polyline %+.2f %%\n", 100 * (tangent / truth - 1), 100 * (polyline / truth - 1));
  EXPECT_NEAR(tangent / truth, 1.0, 0.02);
  EXPECT_GT(polyline / truth, 1.05);
}

TEST(NetworkLength, TubeLeavingTheImageReachesTheBorderWhenTheBorderIsObject) {
  // A tube along x from the border (x = 0: the vessel leaves the image) to a rounded end centred at
  // x = 40. With the default border convention (outside = background) the border caps the tube and
  // the skeleton stops about a radius inside; with border_is_object it runs to the border, and the
  // length is the centreline's (the vessel pipeline's setting).
  VolumeU8 m(Grid(Dims{56, 24, 24}));
  for (int64_t z = 0; z < 24; ++z)
    for (int64_t y = 0; y < 24; ++y)
      for (int64_t x = 0; x < 56; ++x) {
        const double dx = std::max(0.0, static_cast<double>(x) - 40.0), dy = static_cast<double>(y) - 12.0,
                     dz = static_cast<double>(z) - 12.0;
        m(x, y, z) = dx * dx + dy * dy + dz * dz <= 25.0 ? 1 : 0;
      }
  const auto low_end = [](const SpatialGraph& g) { return std::min(g.edges[0].points.front()[0], g.edges[0].points.back()[0]); };
  const auto capped = skeleton_graph(m, false);
  ASSERT_EQ(capped.edge_count(), 1);
  EXPECT_GE(low_end(capped), 3.0);
  const auto open = skeleton_graph(m, true);
  ASSERT_EQ(open.edge_count(), 1);
  EXPECT_EQ(low_end(open), 0.0);
  EXPECT_NEAR(total_length(open, LengthEstimator::tangent), 40.0, 1.0);
}

TEST(NetworkLength, TorusSkeletonLengthWithinOnePercent) {
  // A torus (tube radius 3) of centreline radius 20 at a random orientation: a closed curved tube.
  std::mt19937_64 rng(5);
  const Vec3 a = random_direction(rng);
  const Vec3 b = unit(cross(a, random_direction(rng)));
  const Vec3 c = cross(a, b);
  const int64_t n = 56;
  const double big = 20.0, small = 3.0, o = 27.5;
  VolumeU8 m(Grid(Dims{n, n, n}));
  for (int64_t z = 0; z < n; ++z)
    for (int64_t y = 0; y < n; ++y)
      for (int64_t x = 0; x < n; ++x) {
        const Vec3 q{static_cast<double>(x) - o, static_cast<double>(y) - o, static_cast<double>(z) - o};
        const double h = q[0] * a[0] + q[1] * a[1] + q[2] * a[2];
        const double pb = q[0] * b[0] + q[1] * b[1] + q[2] * b[2], pc = q[0] * c[0] + q[1] * c[1] + q[2] * c[2];
        const double rho = std::sqrt(pb * pb + pc * pc) - big;
        m(x, y, z) = rho * rho + h * h <= small * small ? 1 : 0;
      }
  const auto g = skeleton_graph(m);
  ASSERT_EQ(g.edge_count(), 1);
  ASSERT_EQ(g.edges[0].node0, g.edges[0].node1);
  const double truth = 2.0 * std::numbers::pi * big;
  const double tangent = total_length(g, LengthEstimator::tangent);
  const double poly = total_length(g, LengthEstimator::polyline);
  std::printf("torus R 20: tangent %+.2f %%, polyline %+.2f %%\n", 100 * (tangent / truth - 1), 100 * (poly / truth - 1));
  EXPECT_NEAR(tangent / truth, 1.0, 0.01);
  EXPECT_GT(poly / truth, 1.04);
}

TEST(NetworkLength, TangentPointsBelowOneIsRejected) {
  SpatialGraph g;
  g.add_edge(g.add_node({0, 0, 0}), g.add_node({1, 0, 0}));
  NetworkStatisticsOptions o;
  o.tangent_points = 0;
  try {
    (void)network_statistics(g, o);
    FAIL() << "no error";
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("parameter 'tangent_points'"), std::string::npos) << e.what();
  }
}


TEST(NetworkLength, OrientationHistogramSumsToTheEstimatedTotalLength) {
  std::vector<Pt> path;
  for (int64_t i = 0; i <= 40; ++i) path.push_back({2 + i, 2 + i / 3, 2 + i / 5});
  const auto g = path_graph(path, 64, false);
  NetworkStatisticsOptions o;
  o.length_estimator = LengthEstimator::tangent;
  const auto st = network_statistics(g, o);
  const double total = st.summary.reals("total_length")[0];
  EXPECT_LT(total, g.total_length() - 1.0);  // the staircase is not counted
  double sum = 0.0;
  for (int b = 0; b < o.orientation_bins; ++b) sum += st.summary.reals("orientation_" + std::to_string(b))[0];
  EXPECT_NEAR(sum, total, 1e-9 * total);
  EXPECT_NEAR(st.segments.reals("length")[0], total, 1e-12);
  EXPECT_NEAR(st.graph.edge_attributes.at("length")[0], total, 1e-4);
}

TEST(NetworkLength, JunctionsOfTubesAndTheShortfallAtShallowForks) {
  // Capsules joined at a node O: a T (a thin branch off a thick tube) and forks of 2 × 33.7° (the
  // vessel phantom's children leave at 25-45°). The T is measured to within a voxel. At a shallow fork
  // the tubes overlap for ~r / sin(33.7°) beyond O, and the medial axis (so the skeleton) branches only
  // there: its branches are shorter than the centrelines by 1-3 voxels per fork. This is the remaining
  // shortfall of the vessel pipeline against the phantom's ground truth (bench/RESULTS.md).
  const int64_t n = 96;
  struct Seg {
    Vec3 a, b;
    double r;
  };
  const auto measure = [&](const std::vector<Seg>& segs) {
    VolumeU8 m(Grid(Dims{n, n, n}));
    double truth = 0;
    for (const auto& s : segs) {
      const auto c = capsule(n, s.a, s.b, s.r);
      for (int64_t i = 0; i < m.size(); ++i) m.begin()[i] |= c.begin()[i];
      truth += std::sqrt((s.b[0] - s.a[0]) * (s.b[0] - s.a[0]) + (s.b[1] - s.a[1]) * (s.b[1] - s.a[1]) + (s.b[2] - s.a[2]) * (s.b[2] - s.a[2]));
    }
    const auto g = skeleton_graph(m);
    EXPECT_EQ(g.edge_count(), 3);
    return total_length(g, LengthEstimator::tangent) - truth;
  };
  const Vec3 o{48.3, 48.2, 48.1};
  const double t = measure({{{18.3, 48.2, 48.1}, {78.3, 48.2, 48.1}, 8}, {o, {48.3, 78.2, 48.1}, 3}});
  const double y3 = measure({{{18.3, 48.2, 48.1}, o, 3}, {o, {78.3, 68.2, 48.1}, 3}, {o, {78.3, 28.2, 48.1}, 3}});
  const double y5 = measure({{{18.3, 48.2, 48.1}, o, 5}, {o, {78.3, 68.2, 48.1}, 4}, {o, {78.3, 28.2, 48.1}, 4}});
  std::printf("length - centrelines: T %+.2f, fork r 3 %+.2f, fork r 5/4 %+.2f voxels\n", t, y3, y5);
  EXPECT_NEAR(t, 0.0, 1.0);
  EXPECT_LT(y3, -0.5);
  EXPECT_GT(y3, -4.0);
  EXPECT_LT(y5, -0.5);
  EXPECT_GT(y5, -4.0);
}
