// Statistics travel with the graph: analysis' per-edge values become graph attributes that the graph
// files carry, and GraphML is typed so that networkx (what Python users read it with) gets numbers.
#include <gtest/gtest.h>

#include <cmath>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <sstream>

#include "analysis/network_analysis.hpp"
#include "geometry/skeleton_to_graph.hpp"
#include "io/graph_io.hpp"
#include "../graph/graph_test_util.hpp"

using namespace skel;

namespace {

// A small network with junctions, ends, a ring and radii, in mm.
SpatialGraph network() {
  VolumeU8 v({24, 20, 6}, 0, {0.07, 0.13, 0.21}, {-3.25, 10.0, 0.125});
  v.set_unit("mm");
  skel::test::draw_line(v, {1, 1, 2}, {20, 12, 2});
  skel::test::draw_line(v, {10, 1, 3}, {10, 18, 3});
  skel::test::draw_line(v, {10, 10, 3}, {3, 17, 4});
  skel::test::draw_square_ring(v, {15, 14, 1}, 0, 1, 5);
  VolumeF32 d(v.grid(), 0.0f);
  for (int64_t i = 0; i < d.size(); ++i) d[i] = 0.01f * static_cast<float>(i % 17) + 0.033f;
  return geometry::skeleton_to_graph(v, &d, {}).graph;
}

std::filesystem::path tmp_dir(const char* name) {
  auto d = std::filesystem::path(SKEL_BINARY_DIR) / "graph_statistics_export_test" / name;
  std::filesystem::remove_all(d);
  std::filesystem::create_directories(d);
  return d;
}

}  // namespace

TEST(GraphStatisticsExport, StatisticsBecomeGraphAttributes) {
  const SpatialGraph g = network();
  ASSERT_EQ(g.unit, "mm");
  const auto st = analysis::network_statistics(g);
  const SpatialGraph& a = st.graph;
  EXPECT_TRUE(a.check_invariants().empty());
  const auto& len = a.edge_attributes.at("length");
  const auto& seg = st.segments.reals("length");
  for (int64_t e = 0; e < a.edge_count(); ++e) EXPECT_FLOAT_EQ(len[e], static_cast<float>(seg[e]));
  for (const char* n : {"chord", "tortuosity", "orientation", "direction_x", "mean_radius", "volume"})
    EXPECT_TRUE(a.edge_attributes.count(n)) << n;
  const auto& bt = a.edge_labels.at("branch_type");
  const auto deg = g.degrees();
  for (int64_t e = 0; e < a.edge_count(); ++e) {
    const auto& ed = g.edges[e];
    if (ed.node0 == ed.node1) EXPECT_EQ(bt[e], static_cast<int32_t>(analysis::BranchType::loop));
    else if (deg[ed.node0] == 1 && deg[ed.node1] == 1) EXPECT_EQ(bt[e], static_cast<int32_t>(analysis::BranchType::isolated));
    else if (deg[ed.node0] == 1 || deg[ed.node1] == 1) EXPECT_EQ(bt[e], static_cast<int32_t>(analysis::BranchType::terminal));
    else EXPECT_EQ(bt[e], static_cast<int32_t>(analysis::BranchType::internal));
  }
  EXPECT_TRUE(std::count(bt.begin(), bt.end(), static_cast<int32_t>(analysis::BranchType::loop)) >= 1);
  // Two components (the lines and the ring), numbered per edge and node.
  const auto& comp = a.edge_labels.at("component");
  EXPECT_EQ(*std::max_element(comp.begin(), comp.end()), 1);
  EXPECT_EQ(a.node_labels.at("degree")[0], deg[0]);
  // Every format carries them back.
  const auto dir = tmp_dir("formats");
  for (const char* f : {"s.am", "s.vtp", "s.graphml"}) {
    SCOPED_TRACE(f);
    const auto p = dir / f;
    io::write_graph(a, p, io::graph_format_from_path(p));
    const SpatialGraph r = io::read_graph(p, io::graph_format_from_path(p));
    EXPECT_EQ(r.edge_labels.at("branch_type"), bt);
    EXPECT_EQ(r.edge_attributes.at("length"), len);
    EXPECT_EQ(r.node_labels.at("degree"), a.node_labels.at("degree"));
    EXPECT_EQ(r.unit, "mm");
  }
}

TEST(GraphStatisticsExport, NetworkxReadsNumbersAndTheSameTotalLength) {
  if (std::system("/usr/bin/python3 -c 'import networkx' >/dev/null 2>&1") != 0)
    GTEST_SKIP() << "python3-networkx is not installed";
  const auto st = analysis::network_statistics(network());
  const auto dir = tmp_dir("networkx");
  io::write_graph(st.graph, dir / "net.graphml", io::GraphFormat::graphml);
  {
    std::ofstream py(dir / "check.py");
    py << R"PY(import sys, math, networkx as nx
G = nx.read_graphml(sys.argv[1])
assert G.graph["unit"] == "mm", G.graph
attr_total = 0.0
geom_total = 0.0
for u, v, d in G.edges(data=True):
    for k in ("length", "tortuosity", "mean_radius", "p0_x", "p1_z", "p0_radius"):
        assert isinstance(d[k], float), (k, type(d[k]))
    for k in ("branch_type", "component", "num_points"):
        assert isinstance(d[k], int), (k, type(d[k]))
    attr_total += d["length"]
    pts = [(d["p%d_x" % i], d["p%d_y" % i], d["p%d_z" % i]) for i in range(d["num_points"])]
    geom_total += sum(math.dist(pts[i], pts[i + 1]) for i in range(len(pts) - 1))
for n, d in G.nodes(data=True):
    assert isinstance(d["x"], float) and isinstance(d["degree"], int), d
print("%d %.17g %.17g" % (G.number_of_edges(), attr_total, geom_total))
)PY";
  }
  const auto out = dir / "out.txt";
  ASSERT_EQ(std::system(("/usr/bin/python3 " + (dir / "check.py").string() + " " + (dir / "net.graphml").string() + " > " +
                         out.string()).c_str()),
            0);
  std::ifstream in(out);
  int64_t edges = 0;
  double attr_total = 0, geom_total = 0;
  in >> edges >> attr_total >> geom_total;
  EXPECT_EQ(edges, st.graph.edge_count());
  const double total = st.graph.total_length();
  EXPECT_NEAR(geom_total, total, 1e-12 * total);  // the coordinates are exact doubles
  EXPECT_NEAR(attr_total, total, 1e-6 * total);   // lengths are float attributes
}
