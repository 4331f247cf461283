#include "skel/spatial_graph.hpp"

#include <gtest/gtest.h>

#include <cmath>

using namespace skel;

namespace {
SpatialGraph square_with_tail() {
  SpatialGraph g;
  for (int i = 0; i < 5; ++i) g.add_node({double(i % 2), double(i / 2), 0.0});
  g.add_edge(0, 1);
  g.add_edge(1, 3);
  g.add_edge(3, 2);
  g.add_edge(2, 0);
  g.add_edge(2, 4, {g.positions[2], {0.5, 1.5, 0.0}, g.positions[4]});
  return g;
}
}  // namespace

TEST(SpatialGraph, BuildQueriesAndInvariants) {
  SpatialGraph g = square_with_tail();
  EXPECT_TRUE(g.check_invariants().empty());
  EXPECT_EQ(g.node_count(), 5);
  EXPECT_EQ(g.edge_count(), 5);
  EXPECT_EQ(g.point_count(), 11);
  EXPECT_EQ(g.degrees(), (std::vector<int64_t>{2, 2, 3, 2, 1}));
  auto adj = g.adjacency();
  EXPECT_EQ(adj.degree(2), 3);
  EXPECT_EQ(std::vector<int64_t>(adj.edge_ids.begin() + adj.offsets[2],
                                 adj.edge_ids.begin() + adj.offsets[3]),
            (std::vector<int64_t>{2, 3, 4}));
  EXPECT_DOUBLE_EQ(g.edge_length(0), 1.0);
  EXPECT_NEAR(g.edge_length(4), 2.0 * std::sqrt(0.5), 1e-12);
  EXPECT_EQ(g.connected_components(), 1);
  EXPECT_EQ(g.cyclomatic_number(), 1);
  EXPECT_NE(g.describe().find("5 nodes"), std::string::npos);
  EXPECT_GT(g.bytes(), 0u);
}

TEST(SpatialGraph, AttributesStaySized) {
  SpatialGraph g = square_with_tail();
  g.ensure_node_attribute("w", 1.0f);
  g.ensure_edge_label("tree", 7);
  auto& r = g.ensure_point_attribute("radius", 2.0f);
  EXPECT_EQ(r[4].size(), 3u);
  const int64_t n = g.add_node({5, 5, 5});
  const int64_t e = g.add_edge(4, n);
  EXPECT_TRUE(g.check_invariants().empty());
  EXPECT_EQ(g.node_attributes.at("w")[n], 0.0f);
  EXPECT_EQ(g.edge_labels.at("tree")[e], 0);
  EXPECT_EQ(g.point_attributes.at("radius")[e].size(), 2u);
  g.edge_labels["tree"].push_back(1);
  g.edges[0].points.front()[0] = 9.0;
  g.point_attributes["radius"][1].pop_back();
  const auto problems = g.check_invariants();
  ASSERT_EQ(problems.size(), 3u);
  EXPECT_NE(problems[0].find("edge 0: first point"), std::string::npos);
}

TEST(SpatialGraph, SwapRemovalReportsMovedIds) {
  SpatialGraph g = square_with_tail();
  auto& lab = g.ensure_edge_label("id");
  for (int i = 0; i < 5; ++i) lab[i] = i;
  EXPECT_EQ(g.remove_edge(1), 4);  // last edge (2-4) moves to id 1
  EXPECT_EQ(g.edge_labels.at("id")[1], 4);
  EXPECT_EQ(g.edges[1].node1, 4);
  EXPECT_EQ(g.remove_edge(3), -1);
  EXPECT_TRUE(g.check_invariants().empty());

  SpatialGraph h = square_with_tail();
  EXPECT_EQ(h.remove_node(1), 4);  // node 4 moves to id 1; edges 0-1 and 1-3 go
  EXPECT_EQ(h.node_count(), 4);
  EXPECT_EQ(h.edge_count(), 3);
  EXPECT_TRUE(h.check_invariants().empty());
  EXPECT_EQ(h.degrees(), (std::vector<int64_t>{1, 1, 3, 1}));
}

TEST(SpatialGraph, BatchRemovalKeepsOrder) {
  SpatialGraph g = square_with_tail();
  auto map = g.remove_edges({0, 2});
  EXPECT_EQ(map, (std::vector<int64_t>{-1, 0, -1, 1, 2}));
  EXPECT_EQ(g.edge_count(), 3);
  EXPECT_EQ(g.edges[0].node0, 1);
  SpatialGraph h = square_with_tail();
  auto nmap = h.remove_nodes({0, 3});
  EXPECT_EQ(nmap, (std::vector<int64_t>{-1, 0, 1, -1, 2}));
  ASSERT_EQ(h.edge_count(), 1);
  EXPECT_EQ(h.edges[0].node0, 1);
  EXPECT_EQ(h.edges[0].node1, 2);
  EXPECT_TRUE(h.check_invariants().empty());
}

TEST(SpatialGraph, LoopEdgeCountsTwice) {
  SpatialGraph g;
  g.add_node({0, 0, 0});
  g.add_edge(0, 0, {{0, 0, 0}, {1, 0, 0}, {1, 1, 0}, {0, 0, 0}});
  EXPECT_EQ(g.degrees()[0], 2);
  EXPECT_EQ(g.cyclomatic_number(), 1);
  EXPECT_TRUE(g.check_invariants().empty());
  EXPECT_THROW(g.add_edge(0, 3), Error);
  EXPECT_THROW(g.add_edge(0, 0, {{0, 0, 0}}), Error);
}
