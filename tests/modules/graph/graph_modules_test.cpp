// The graph family's modules through run_module: ports, parameters, errors, and a small chain
// skeleton → graph → prune → statistics → file → graph.
#include <gtest/gtest.h>

#include <algorithm>
#include <filesystem>

#include "graph_test_util.hpp"
#include "skel/run_module.hpp"
#include "skel/spatial_graph.hpp"
#include "skel/table.hpp"

using namespace skel;

namespace {
std::shared_ptr<const VolumeU8> comb() {
  auto v = std::make_shared<VolumeU8>(Dims{40, 10, 5}, 0, Vec3{0.5, 0.5, 0.5});
  skel::test::draw_line(*v, {0, 2, 2}, {39, 2, 2});
  for (int x = 8; x <= 32; x += 8) skel::test::draw_line(*v, {x, 3, 2}, {x, 4 + x / 8, 2});
  return v;
}
}  // namespace

TEST(GraphModules, SkeletonToGraphPruneStatisticsAndFiles) {
  auto sk = comb();
  auto dist = std::make_shared<VolumeF32>(sk->grid(), 2.0f);
  auto r = run_module("geometry.skeleton_to_graph", {{"skeleton", sk}, {"distance", dist}},
                      {{"with_manifold", ParamValue(true)}}, {.threads = 2});
  auto g = r.get<SpatialGraph>("graph");
  EXPECT_TRUE(g->check_invariants().empty());
  EXPECT_EQ(g->edge_count(), 9);
  EXPECT_EQ(r.get<VolumeU8>("manifold")->dims(), sk->dims());
  EXPECT_FLOAT_EQ(g->point_attributes.at("radius")[0][0], 2.0f);

  // Teeth are 1.5, 2.0, 2.5, 3.0 µm long: pruning below 2.2 µm removes two of them and merges the
  // trunk through their junctions.
  auto p = run_module("graph.prune", {{"graph", g}}, {{"min_length", ParamValue(2.2)}});
  auto pg = p.get<SpatialGraph>("graph");
  EXPECT_EQ(p.get<Table>("report")->ints("removed_edges")[0], 2);
  EXPECT_EQ(pg->edge_count(), 5);

  auto s = run_module("analysis.network_statistics", {{"graph", pg}}, {{"axis", ParamValue(std::string("x"))}});
  const auto sum = s.get<Table>("summary");
  EXPECT_EQ(sum->ints("branch_points")[0], 2);
  EXPECT_EQ(sum->ints("end_points")[0], 4);
  EXPECT_DOUBLE_EQ(sum->reals("total_length")[0], 19.5 + 2.5 + 3.0);
  EXPECT_DOUBLE_EQ(sum->reals("reference_volume")[0], 20.0 * 5.0 * 2.5);
  EXPECT_EQ(s.get<Table>("segments")->rows(), 5);

  const auto dir = std::filesystem::path(SKEL_BINARY_DIR) / "graph_modules_test";
  std::filesystem::create_directories(dir);
  for (const char* name : {"g.am", "g.vtp", "g.swc", "g.graphml"}) {
    const auto path = (dir / name).string();
    run_module("io.write_graph", {{"graph", pg}}, {{"path", ParamValue(path)}});
    auto back = run_module("io.read_graph", {}, {{"path", ParamValue(path)}}).get<SpatialGraph>("graph");
    EXPECT_EQ(back->edge_count(), pg->edge_count()) << name;
    EXPECT_NEAR(back->total_length(), pg->total_length(), 1e-5) << name;
    const auto& ins = Registry::instance().inspectors();
    auto it = std::find_if(ins.begin(), ins.end(), [](const FileInspector& i) { return i.name == "spatial graph"; });
    ASSERT_NE(it, ins.end());
    EXPECT_NE(it->describe(path).find("graph " + std::to_string(pg->node_count()) + " nodes"), std::string::npos);
  }
  const auto csv = (dir / "g.csv").string(), nodes = (dir / "g_nodes.csv").string();
  EXPECT_THROW(run_module("io.write_graph", {{"graph", pg}}, {{"path", ParamValue(csv)}}), InputError);
  run_module("io.write_graph", {{"graph", pg}}, {{"path", ParamValue(csv)}, {"nodes_path", ParamValue(nodes)}});
  auto back = run_module("io.read_graph", {}, {{"path", ParamValue(csv)}}).get<SpatialGraph>("graph");
  EXPECT_EQ(back->edge_count(), 5);
  EXPECT_THROW(run_module("io.write_graph", {{"graph", pg}}, {{"path", ParamValue((dir / "g.xyz").string())}}),
               InputError);
}

TEST(GraphModules, FilterTreesAndLabelPropagation) {
  auto sk = comb();
  auto g = run_module("geometry.skeleton_to_graph", {{"skeleton", sk}}, {}).get<SpatialGraph>("graph");
  auto f = run_module("graph.filter", {{"graph", g}}, {{"min", ParamValue(3.1)}, {"merge", ParamValue(true)}});
  auto fg = f.get<SpatialGraph>("graph");
  ASSERT_EQ(fg->edge_count(), 1);  // only trunk pieces are >= 3.1 µm long; merged into one
  EXPECT_DOUBLE_EQ(fg->edge_length(0), 19.5);
  EXPECT_THROW(run_module("graph.filter", {{"graph", g}}, {{"attribute", ParamValue(std::string("radius"))}}),
               InputError);

  auto t = run_module("analysis.trees", {{"graph", g}}, {{"root_points", ParamValue(std::vector<double>{0, 1, 1})}});
  auto tg = t.get<SpatialGraph>("graph");
  const auto& tree = tg->edge_labels.at("tree");
  EXPECT_EQ(std::count(tree.begin(), tree.end(), 1), 9);
  EXPECT_EQ(t.get<Table>("trees")->ints("edges")[0], 9);
  EXPECT_THROW(run_module("analysis.trees", {{"graph", g}}, {}), InputError);

  auto mask = std::make_shared<VolumeU8>(*sk);
  auto l = run_module("analysis.label_propagation", {{"mask", mask}, {"graph", g}}, {});
  auto lab = l.get<VolumeU32>("labels");
  for (int64_t i = 0; i < mask->size(); ++i) EXPECT_EQ((*lab)[i] != 0, (*mask)[i] != 0);
  EXPECT_THROW(run_module("analysis.label_propagation", {{"mask", mask}}, {}), InputError);
}
