// graph.apply_edits and analysis.dangling_ends as modules (through run_module).
#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>

#include "skel/run_module.hpp"
#include "skel/spatial_graph.hpp"
#include "skel/table.hpp"

using namespace skel;
namespace fs = std::filesystem;

TEST(ApplyEditsModule, ReportsWhatMatchedAndWhatNot) {
  const fs::path dir = fs::path(SKEL_BINARY_DIR) / "tests" / "scratch" / "apply_edits";
  fs::remove_all(dir);
  fs::create_directories(dir);
  std::ofstream(dir / "j.yaml") << "skelflow_edits: 1\ntolerance: 0.5\nops:\n"
                                   "- {op: delete_edge, at: [5, 0, 0]}\n"
                                   "- {op: delete_node, at: [99, 99, 99]}\n"
                                   "- {op: connect, from: [0, 0, 0], to: [20, 0, 0], route: straight}\n";
  auto g = std::make_shared<SpatialGraph>();
  g->add_node({0, 0, 0});
  g->add_node({10, 0, 0});
  g->add_node({20, 0, 0});
  g->add_edge(0, 1);
  g->add_edge(1, 2);
  auto r = run_module("graph.apply_edits", {{"graph", g}}, {{"journal", std::string("j.yaml")}},
                      {.threads = 1, .base_dir = dir});
  auto out = r.get<SpatialGraph>("graph");
  EXPECT_EQ(out->edge_count(), 2);  // one deleted, one added
  auto t = r.get<Table>("table");
  EXPECT_EQ(t->strings("status"), (std::vector<std::string>{"applied", "not matched", "applied"}));
  ASSERT_EQ(r.warnings.size(), 1u);
  EXPECT_THROW(run_module("graph.apply_edits", {{"graph", g}}, {{"journal", std::string("j.yaml")}, {"strict", true}},
                          {.threads = 1, .base_dir = dir}),
               InputError);
  EXPECT_THROW(run_module("graph.apply_edits", {{"graph", g}}, {{"journal", std::string("missing.yaml")}},
                          {.threads = 1, .base_dir = dir}),
               InputError);
}

TEST(DanglingEndsModule, TableAndAttributes) {
  auto g = std::make_shared<SpatialGraph>();
  g->add_node({0, 0, 0});
  g->add_node({10, 0, 0});
  g->add_node({12, 0, 0});
  g->add_node({30, 0, 0});
  g->add_edge(0, 1);
  g->add_edge(2, 3);
  auto r = run_module("analysis.dangling_ends", {{"graph", g}}, {{"max_distance", 5.0}});
  auto t = r.get<Table>("table");
  EXPECT_EQ(t->rows(), 4);
  EXPECT_EQ(t->strings("partner")[0], "node");
  EXPECT_DOUBLE_EQ(t->reals("distance")[0], 2.0);
  auto out = r.get<SpatialGraph>("graph");
  EXPECT_EQ(out->node_labels.at("dangling"), (std::vector<int32_t>{1, 1, 1, 1}));
}
