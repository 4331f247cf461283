#include <gtest/gtest.h>

#include <cmath>
#include <numbers>
#include <random>
#include <string>

#include "graph/graph_ops.hpp"
#include "analysis/network_analysis.hpp"
#include "geometry/skeleton_to_graph.hpp"
#include "graph_test_util.hpp"

using namespace skel::analysis;
using namespace skel::geometry;
using namespace skel::graph;

using namespace skel;

namespace {

// A long straight trunk 0-1-2 (node 1 a junction) with a short spur at 1 and a long branch at 1.
SpatialGraph y_with_spur() {
  SpatialGraph g;
  g.add_node({0, 0, 0});    // 0
  g.add_node({10, 0, 0});   // 1 junction
  g.add_node({20, 0, 0});   // 2
  g.add_node({10, 2, 0});   // 3 spur end (length 2)
  g.add_node({10, -9, 0});  // 4 branch end (length 9)
  g.add_edge(0, 1, {{0, 0, 0}, {5, 0, 0}, {10, 0, 0}});
  g.add_edge(1, 2, {{10, 0, 0}, {15, 0, 0}, {20, 0, 0}});
  g.add_edge(1, 3);
  g.add_edge(1, 4);
  auto& r = g.ensure_point_attribute("radius");
  r[0] = {1, 2, 3};
  r[1] = {3, 4, 5};
  return g;
}

}  // namespace

TEST(GraphOps, MergeDegreeTwoConcatenatesPolylinesAndAttributes) {
  SpatialGraph g;
  for (int i = 0; i < 4; ++i) g.add_node({double(i), 0, 0});
  g.add_edge(1, 0);
  g.add_edge(1, 2);
  g.add_edge(3, 2);
  auto& w = g.ensure_edge_attribute("w");
  w = {1.0f, 2.0f, 6.0f};
  auto& r = g.ensure_point_attribute("r");
  r[0] = {11, 10};
  r[1] = {11, 12};
  r[2] = {13, 12};
  EXPECT_EQ(merge_degree_two(g), 2);
  EXPECT_TRUE(g.check_invariants().empty());
  ASSERT_EQ(g.edge_count(), 1);
  ASSERT_EQ(g.node_count(), 2);
  EXPECT_DOUBLE_EQ(g.edge_length(0), 3.0);
  const auto& e = g.edges[0];
  const auto& pr = g.point_attributes.at("r")[0];
  ASSERT_EQ(e.points.size(), 4u);
  for (size_t i = 0; i < 4; ++i) EXPECT_FLOAT_EQ(pr[i], 10.0f + float(e.points[i][0]));
  EXPECT_FLOAT_EQ(g.edge_attributes.at("w")[0], 3.0f);
  // A closed chain becomes one loop edge on a single node.
  SpatialGraph ring;
  for (int i = 0; i < 4; ++i) ring.add_node({double(i % 2), double(i / 2), 0});
  ring.add_edge(0, 1);
  ring.add_edge(1, 3);
  ring.add_edge(3, 2);
  ring.add_edge(2, 0);
  merge_degree_two(ring);
  EXPECT_TRUE(ring.check_invariants().empty());
  EXPECT_EQ(ring.node_count(), 1);
  ASSERT_EQ(ring.edge_count(), 1);
  EXPECT_EQ(ring.edges[0].node0, ring.edges[0].node1);
  EXPECT_DOUBLE_EQ(ring.edge_length(0), 4.0);
}

TEST(GraphOps, PruneRemovesShortSpursAndMerges) {
  SpatialGraph g = y_with_spur();
  auto s = prune(g, {.min_length = 3.0, .max_iterations = 0, .interrupter = {}});
  EXPECT_TRUE(g.check_invariants().empty());
  EXPECT_EQ(s.removed_edges, 1);
  EXPECT_EQ(g.edge_count(), 3);
  EXPECT_EQ(g.node_count(), 4);
  // Longer threshold: the 9 µm branch goes too, the trunk merges into one edge of length 20.
  SpatialGraph h = y_with_spur();
  s = prune(h, {.min_length = 9.5, .max_iterations = 0, .interrupter = {}});
  EXPECT_TRUE(h.check_invariants().empty());
  EXPECT_EQ(s.removed_edges, 2);
  EXPECT_EQ(s.merged_nodes, 1);
  ASSERT_EQ(h.edge_count(), 1);
  EXPECT_DOUBLE_EQ(h.edge_length(0), 20.0);
  const auto& r = h.point_attributes.at("radius")[0];
  EXPECT_EQ(r.size(), 5u);
  EXPECT_EQ(h.degrees(), (std::vector<int64_t>{1, 1}));
  EXPECT_THROW(prune(h, {.min_length = -1.0, .max_iterations = 0, .interrupter = {}}), InputError);
}

TEST(GraphOps, PruneIteratesOnSkeletonGraphs) {
  // A comb: trunk with short teeth; teeth at the ends make the last junctions terminal in turn.
  VolumeU8 v({30, 8, 3}, 0);
  skel::test::draw_line(v, {0, 1, 1}, {29, 1, 1});
  for (int x = 5; x <= 25; x += 5) skel::test::draw_line(v, {x, 2, 1}, {x, 3, 1});
  auto g = skeleton_to_graph(v, nullptr, {}).graph;
  EXPECT_EQ(g.edge_count(), 11);
  prune(g, {.min_length = 3.0, .max_iterations = 0, .interrupter = {}});
  EXPECT_TRUE(g.check_invariants().empty());
  ASSERT_EQ(g.edge_count(), 1);
  EXPECT_DOUBLE_EQ(g.edge_length(0), 29.0);
}

TEST(GraphOps, PruneRelativeToTheRadiusAtTheJunction) {
  // y_with_spur: spur of length 2 (edge 2, stored junction -> end) and branch of length 9 (edge 3).
  SpatialGraph g = y_with_spur();
  auto& r = g.point_attributes.at("radius");
  r[2] = {2.0f, 0.5f};  // limit 2 x 2 = 4 > 2: removed
  r[3] = {4.0f, 1.0f};  // limit 8 < 9: kept
  auto s = prune(g, {.min_length = 0.0, .max_iterations = 0, .interrupter = {}, .radius_factor = 2.0});
  EXPECT_TRUE(g.check_invariants().empty());
  EXPECT_EQ(s.removed_edges, 1);
  EXPECT_EQ(g.edge_count(), 3);
  // A thicker junction under the branch: limit 10 > 9, both terminal branches go, the trunk merges.
  SpatialGraph h = y_with_spur();
  auto& rh = h.point_attributes.at("radius");
  rh[2] = {2.0f, 0.5f};
  rh[3] = {5.0f, 1.0f};
  s = prune(h, {.min_length = 0.0, .max_iterations = 0, .interrupter = {}, .radius_factor = 2.0});
  EXPECT_EQ(s.removed_edges, 2);
  ASSERT_EQ(h.edge_count(), 1);
  EXPECT_DOUBLE_EQ(h.edge_length(0), 20.0);
  // min_length still applies on its own: radius 0 at the junction, spur shorter than min_length.
  SpatialGraph m = y_with_spur();
  m.point_attributes.at("radius")[2] = {0.0f, 0.0f};
  m.point_attributes.at("radius")[3] = {0.0f, 0.0f};
  s = prune(m, {.min_length = 3.0, .max_iterations = 0, .interrupter = {}, .radius_factor = 2.0});
  EXPECT_EQ(s.removed_edges, 1);

  // The junction end is the last point when the branch is stored from its free end to the junction.
  const auto reversed = [](float at_free_end, float at_junction) {
    SpatialGraph k;
    k.add_node({0, 0, 0});
    k.add_node({10, 0, 0});  // junction
    k.add_node({20, 0, 0});
    k.add_node({10, 6, 0});  // free end, 6 away
    k.add_edge(0, 1);
    k.add_edge(1, 2);
    k.add_edge(3, 1, {{10, 6, 0}, {10, 0, 0}});
    auto& rk = k.ensure_point_attribute("radius");
    rk[0] = {1.0f, 1.0f};
    rk[1] = {1.0f, 1.0f};
    rk[2] = {at_free_end, at_junction};
    return prune(k, {.min_length = 0.0, .max_iterations = 0, .interrupter = {}, .radius_factor = 2.0}).removed_edges;
  };
  EXPECT_EQ(reversed(0.5f, 4.0f), 1);  // limit 8 > 6
  EXPECT_EQ(reversed(4.0f, 0.5f), 0);  // limit 1 < 6: a thick free end does not count

  SpatialGraph bare;
  bare.add_node({0, 0, 0});
  bare.add_node({1, 0, 0});
  bare.add_edge(0, 1);
  try {
    prune(bare, {.min_length = 0.0, .max_iterations = 0, .interrupter = {}, .radius_factor = 1.0});
    ADD_FAILURE() << "expected InputError";
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("'radius'"), std::string::npos) << e.what();
  }
  EXPECT_THROW(prune(bare, {.min_length = 0.0, .max_iterations = 0, .interrupter = {}, .radius_factor = -1.0}),
               InputError);
}

TEST(GraphOps, FindSpursIsThePruneRule) {
  // y_with_spur: terminal branches 2 (1 -> 3, length 2) and 3 (1 -> 4, length 9) at junction 1.
  SpatialGraph g = y_with_spur();
  auto spurs = find_spurs(g, g.degrees(), {.min_length = 10.0, .max_iterations = 0, .interrupter = {}});
  ASSERT_EQ(spurs.size(), 2u);  // in edge order, whatever the junction would keep
  EXPECT_EQ(spurs[0].edge, 2);
  EXPECT_EQ(spurs[0].tip, 3);
  EXPECT_EQ(spurs[0].junction, 1);
  EXPECT_DOUBLE_EQ(spurs[0].length, 2.0);
  EXPECT_EQ(spurs[1].edge, 3);
  EXPECT_EQ(spurs[1].tip, 4);
  EXPECT_DOUBLE_EQ(spurs[1].length, 9.0);
  EXPECT_EQ(find_spurs(g, g.degrees(), {.min_length = 9.0, .max_iterations = 0, .interrupter = {}}).size(), 1u);  // strictly shorter
  auto& r = g.point_attributes.at("radius");
  r[2] = {0.5f, 0.5f};
  r[3] = {5.0f, 1.0f};  // 2 x 5 = 10 at the junction end
  spurs = find_spurs(g, g.degrees(), {.min_length = 1.0, .max_iterations = 0, .interrupter = {}, .radius_factor = 2.0});
  ASSERT_EQ(spurs.size(), 1u);
  EXPECT_EQ(spurs[0].edge, 3);
  // graph.prune applies it with the two-edges-per-junction cap: of a star of three spurs only the
  // shortest goes (the graph editor's prune op takes all three).
  SpatialGraph star;
  star.add_node({0, 0, 0});
  star.add_node({1, 0, 0});
  star.add_node({0, 2, 0});
  star.add_node({0, 0, 3});
  for (int64_t n = 1; n <= 3; ++n) star.add_edge(0, n);
  EXPECT_EQ(find_spurs(star, star.degrees(), {.min_length = 10.0, .max_iterations = 0, .interrupter = {}}).size(), 3u);
  EXPECT_EQ(prune(star, {.min_length = 10.0, .max_iterations = 0, .interrupter = {}}).removed_edges, 1);
  EXPECT_EQ(star.edge_count(), 1);
}

TEST(GraphOps, FilterByLengthAndPointAttribute) {
  SpatialGraph g = y_with_spur();
  FilterOptions o;
  o.attribute = "length";
  o.min = 5.0;
  EXPECT_EQ(filter_edges(g, o), 1);  // the spur (length 2)
  EXPECT_EQ(g.node_count(), 4);
  EXPECT_TRUE(g.check_invariants().empty());
  SpatialGraph h = y_with_spur();
  const auto mean_r = edge_values(h, "radius", "x");
  EXPECT_DOUBLE_EQ(mean_r[0], 2.0);
  EXPECT_DOUBLE_EQ(mean_r[1], 4.0);
  o.attribute = "radius";
  o.min = 3.0;
  o.max = 10.0;
  EXPECT_EQ(filter_edges(h, o), 3);
  EXPECT_EQ(h.edge_count(), 1);
  EXPECT_EQ(h.node_count(), 2);
  o.attribute = "nope";
  EXPECT_THROW(filter_edges(h, o), InputError);
}

TEST(NetworkStatistics, SegmentsNodesSummary) {
  SpatialGraph g = y_with_spur();
  g.source_grid = Grid({10, 10, 10}, {2, 2, 2});
  auto st = network_statistics(g);
  ASSERT_EQ(st.segments.rows(), 4);
  EXPECT_DOUBLE_EQ(st.segments.reals("length")[0], 10.0);
  EXPECT_DOUBLE_EQ(st.segments.reals("tortuosity")[0], 1.0);
  // Frustum volume of radii 1→2→3 over 5 µm each: π·5/3·(1+2+4) + π·5/3·(4+6+9).
  const double pi = std::numbers::pi;
  EXPECT_NEAR(st.segments.reals("volume")[0], pi * 5 / 3 * (7 + 19), 1e-9);
  EXPECT_NEAR(st.segments.reals("surface")[0], pi * 3 * std::sqrt(26.0) + pi * 5 * std::sqrt(26.0), 1e-9);
  EXPECT_DOUBLE_EQ(st.segments.reals("mean_radius")[0], 2.0);
  EXPECT_DOUBLE_EQ(st.segments.reals("min_radius")[1], 3.0);
  EXPECT_DOUBLE_EQ(st.segments.reals("max_radius")[1], 5.0);
  EXPECT_EQ(st.nodes.ints("degree"), (std::vector<int64_t>{1, 4, 1, 1, 1}));
  EXPECT_EQ(st.summary.rows(), 1);
  EXPECT_DOUBLE_EQ(st.summary.reals("total_length")[0], 31.0);
  EXPECT_DOUBLE_EQ(st.summary.reals("reference_volume")[0], 8000.0);
  EXPECT_DOUBLE_EQ(st.summary.reals("length_density")[0], 31.0 / 8000.0);
  EXPECT_EQ(st.summary.ints("branch_points")[0], 1);
  EXPECT_EQ(st.summary.ints("end_points")[0], 4);
  EXPECT_EQ(st.summary.ints("loops")[0], 0);
  // All edges lie in the xy-plane: 90° to the z axis, last bin.
  EXPECT_DOUBLE_EQ(st.summary.reals("orientation_8")[0], 31.0);
  EXPECT_DOUBLE_EQ(st.summary.reals("orientation_0")[0], 0.0);
  NetworkStatisticsOptions o;
  o.axis = Axis::x;
  o.orientation_bins = 2;
  auto sx = network_statistics(g, o);
  EXPECT_DOUBLE_EQ(sx.summary.reals("orientation_0")[0], 20.0);
  EXPECT_DOUBLE_EQ(sx.summary.reals("orientation_1")[0], 11.0);
}

TEST(NetworkStatistics, OrientationFollowsVoxelPathsNotTheGrid) {
  // A digital line at atan(15 / 60) = 14.0° to z: its voxel steps point at 0° or 45° only.
  VolumeU8 v({20, 3, 64}, 0);
  skel::test::draw_line(v, {1, 1, 1}, {16, 1, 61});
  auto g = skeleton_to_graph(v, nullptr, {}).graph;
  ASSERT_EQ(g.edge_count(), 1);
  auto st = network_statistics(g);
  const double total = st.summary.reals("total_length")[0];
  EXPECT_GT(st.summary.reals("orientation_window")[0], 9.9);  // 10 x the median step (1 voxel)
  EXPECT_GT(st.summary.reals("orientation_1")[0], 0.9 * total);  // 10..20°
  double sum = 0.0;
  for (int b = 0; b < 9; ++b) sum += st.summary.reals("orientation_" + std::to_string(b))[0];
  EXPECT_NEAR(sum, total, 1e-9);  // every piece is counted once
  // A window below one step measures single steps: the grid directions, nothing near 14°.
  NetworkStatisticsOptions o;
  o.orientation_window = 0.5;
  auto steps = network_statistics(g, o);
  EXPECT_EQ(steps.summary.reals("orientation_1")[0], 0.0);
  EXPECT_GT(steps.summary.reals("orientation_0")[0], 0.5 * total);
}

TEST(NetworkStatistics, TorusLoop) {
  VolumeU8 v({20, 20, 5}, 0);
  skel::test::draw_square_ring(v, {2, 2, 2}, 0, 1, 10);
  auto g = skeleton_to_graph(v, nullptr, {}).graph;
  auto st = network_statistics(g);
  EXPECT_EQ(st.summary.ints("loops")[0], 1);
  EXPECT_DOUBLE_EQ(st.summary.reals("total_length")[0], 36.0);
  EXPECT_TRUE(std::isnan(st.segments.reals("tortuosity")[0]));
  EXPECT_DOUBLE_EQ(st.summary.reals("reference_volume")[0], 2000.0);
}

TEST(Trees, RootsDiameterAndBranchOrder) {
  // Root 0 —(thick)— 1 —(thick)— 2 (branching, deg 3) —(thick)— 3, —(thin)— 4; 4 —(thin)— 5.
  SpatialGraph g;
  for (int i = 0; i < 6; ++i) g.add_node({double(i) * 10, 0, 0});
  g.add_edge(0, 1);
  g.add_edge(1, 2);
  g.add_edge(2, 3);
  g.add_edge(2, 4);
  g.add_edge(4, 5);
  g.add_edge(3, 2, {{30, 0, 0}, {25, 5, 0}, {20, 0, 0}});  // second thick branch 3-2 (a loop)
  auto& r = g.ensure_point_attribute("radius");
  for (int e = 0; e < 6; ++e)
    for (auto& x : r[e]) x = (e == 3 || e == 4) ? 1.0f : 5.0f;
  TreeOptions o;
  o.root_points = {{1, 1, 0}};
  o.min_diameter = 4.0;
  auto s = extract_trees(g, o);
  EXPECT_EQ(s.root_nodes, (std::vector<int64_t>{0}));
  EXPECT_EQ(s.tree_edges, 4);
  EXPECT_EQ(s.capillary_edges, 2);
  EXPECT_EQ(g.edge_labels.at("tree"), (std::vector<int32_t>{1, 1, 1, 0, 0, 1}));
  EXPECT_EQ(g.edge_labels.at("branch_order"), (std::vector<int32_t>{1, 1, 2, 0, 0, 2}));
  TreeOptions two;
  two.roots = {0, 5};
  extract_trees(g, two);  // no diameter limit: nearest root along the graph
  EXPECT_EQ(g.edge_labels.at("tree"), (std::vector<int32_t>{1, 1, 1, 2, 2, 1}));
  two.roots = {9};
  EXPECT_THROW(extract_trees(g, two), InputError);
}

TEST(LabelPropagation, NearestEdgeColoursTheObject) {
  // An L-shaped thick object (two rods) with its skeleton: each rod gets its edge's colour.
  VolumeU8 mask({20, 20, 5}, 0);
  for (int z = 1; z <= 3; ++z)
    for (int y = 1; y <= 3; ++y)
      for (int x = 1; x <= 18; ++x) mask(x, y, z) = 1;
  for (int z = 1; z <= 3; ++z)
    for (int y = 1; y <= 18; ++y)
      for (int x = 15; x <= 17; ++x) mask(x, y, z) = 1;
  SpatialGraph g;
  g.add_node({1, 2, 2});
  g.add_node({16, 2, 2});
  g.add_node({16, 18, 2});
  g.add_edge(0, 1);
  g.add_edge(1, 2);
  auto lab = propagate_edge_labels(mask, g);
  for (int64_t i = 0; i < mask.size(); ++i) EXPECT_EQ(lab[i] != 0, mask[i] != 0);
  EXPECT_EQ(lab(1, 1, 1), 1u);
  EXPECT_EQ(lab(10, 3, 3), 1u);
  EXPECT_EQ(lab(16, 10, 1), 2u);
  EXPECT_EQ(lab(17, 18, 3), 2u);
  auto& t = g.ensure_edge_label("kind");
  t = {4, 6};
  LabelPropagationOptions o;
  o.label = "kind";
  auto lk = propagate_edge_labels(mask, g, o);
  EXPECT_EQ(lk(1, 1, 1), 5u);
  EXPECT_EQ(lk(16, 10, 1), 7u);
  VolumeU32 seeds(mask.grid(), 0);
  seeds(2, 2, 2) = 9;
  auto ls = propagate_labels(mask, seeds);
  for (int64_t i = 0; i < mask.size(); ++i) EXPECT_EQ(ls[i], mask[i] ? 9u : 0u);
}

TEST(LabelPropagation, EuclideanMatchesBruteForceAndGeodesicStaysInside) {
  std::mt19937 rng(11);
  VolumeU8 mask({9, 8, 7}, 0, {1.0, 1.5, 0.7});
  for (auto& m : mask) m = (rng() % 4) != 0;
  VolumeU32 seeds(mask.grid(), 0);
  std::vector<int64_t> seed_ids;
  for (int k = 0; k < 6; ++k) {
    const int64_t i = static_cast<int64_t>(rng() % static_cast<unsigned>(mask.size()));
    if (!mask[i] || seeds[i]) continue;
    seeds[i] = static_cast<uint32_t>(k + 1);
    seed_ids.push_back(i);
  }
  std::sort(seed_ids.begin(), seed_ids.end());
  ASSERT_GE(seed_ids.size(), 2u);
  for (int threads : {1, 2, 4}) {
    LabelPropagationOptions o;
    o.threads = threads;
    auto lab = propagate_labels(mask, seeds, o);
    const auto& s = mask.spacing();
    for (int64_t z = 0; z < mask.nz(); ++z)
      for (int64_t y = 0; y < mask.ny(); ++y)
        for (int64_t x = 0; x < mask.nx(); ++x) {
          const int64_t i = mask.index(x, y, z);
          if (!mask[i]) {
            EXPECT_EQ(lab[i], 0u);
            continue;
          }
          double best = 1e300;
          uint32_t want = 0;
          for (int64_t j : seed_ids) {  // ascending index: the first of equals wins
            const double dx = (x - j % 9) * s[0], dy = (y - j / 9 % 8) * s[1], dz = (z - j / 72) * s[2];
            const double d = dx * dx + dy * dy + dz * dz;
            if (d < best) {
              best = d;
              want = seeds[j];
            }
          }
          EXPECT_EQ(lab[i], want) << x << " " << y << " " << z;
        }
  }
  // Geodesic: two rods joined only far away; the seed on one rod does not leak across the gap.
  VolumeU8 u({12, 5, 3}, 0);
  for (int x = 0; x < 12; ++x) u(x, 0, 1) = u(x, 4, 1) = 1;
  for (int y = 0; y < 5; ++y) u(11, y, 1) = 1;
  VolumeU32 s2(u.grid(), 0);
  s2(0, 0, 1) = 1;
  s2(0, 4, 1) = 2;
  LabelPropagationOptions g;
  g.metric = PropagationMetric::geodesic;
  auto lg = propagate_labels(u, s2, g);
  EXPECT_EQ(lg(10, 0, 1), 1u);
  EXPECT_EQ(lg(10, 4, 1), 2u);
  EXPECT_EQ(lg(11, 0, 1), 1u);
  EXPECT_EQ(lg(11, 4, 1), 2u);
  EXPECT_EQ(lg(11, 2, 1), 1u);  // equal arrival: the earlier seed's wave reaches it first
}
