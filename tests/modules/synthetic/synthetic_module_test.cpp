// synthetic.network and synthetic.vessel_tree through the module API (run_module): the outputs equal
// the library functions', parameters reach them, and bad parameters are rejected by name.
#include <gtest/gtest.h>

#include <string>
#include <vector>

#include "skel/run_module.hpp"
#include "skel/spatial_graph.hpp"
#include "skel/table.hpp"
#include "synthetic/network.hpp"
#include "synthetic/vessel_tree.hpp"

using namespace skel;

TEST(SyntheticModule, NetworkMatchesLibrary) {
  const ModuleRunResult r = run_module("synthetic.network", {},
                                       {{"shape", ParamValue(std::string("mixed"))},
                                        {"size", ParamValue(std::vector<int64_t>{40, 36, 52})},
                                        {"seed", ParamValue(int64_t{7})},
                                        {"noise", ParamValue(0.2)},
                                        {"spacing", ParamValue(std::vector<double>{0.5, 0.5, 2.0})},
                                        {"radius", ParamValue(2.5)}},
                                       {.threads = 2});
  synthetic::NetworkOptions o;
  o.shape = synthetic::Shape::mixed;
  o.size = {40, 36, 52};
  o.seed = 7;
  o.noise = 0.2;
  o.spacing = {0.5, 0.5, 2.0};
  o.radius = 2.5;
  o.threads = 1;
  const auto lib = synthetic::make_network(o);
  EXPECT_TRUE(*r.get<VolumeF32>("image") == lib.image);
  EXPECT_TRUE(*r.get<VolumeU8>("mask") == lib.mask);
  EXPECT_THROW(run_module("synthetic.network", {}, {{"shape", ParamValue(std::string("cubes"))}}), InputError);
  EXPECT_THROW(run_module("synthetic.network", {}, {{"size", ParamValue(std::vector<int64_t>{8, 8})}}), InputError);
}

TEST(SyntheticModule, VesselTreeOutputsGroundTruth) {
  const ModuleRunResult r = run_module("synthetic.vessel_tree", {},
                                       {{"size", ParamValue(std::vector<int64_t>{96, 80, 64})},
                                        {"seed", ParamValue(int64_t{3})},
                                        {"spacing", ParamValue(std::vector<double>{2.0, 2.0, 2.0})}},
                                       {.threads = 2});
  synthetic::VesselTreeOptions o;
  o.size = {96, 80, 64};
  o.seed = 3;
  o.spacing = {2.0, 2.0, 2.0};
  const auto lib = synthetic::make_vessel_tree(o);
  EXPECT_TRUE(*r.get<VolumeU8>("mask") == lib.mask);
  EXPECT_TRUE(*r.get<VolumeF32>("image") == lib.image);
  const auto g = r.get<SpatialGraph>("graph");
  EXPECT_EQ(r.data("graph"), r.data("truth"));
  EXPECT_EQ(g->node_count(), lib.truth.node_count());
  EXPECT_EQ(g->edge_count(), lib.truth.edge_count());
  EXPECT_DOUBLE_EQ(g->total_length(), lib.total_length);
  EXPECT_EQ(r.get<Table>("nodes")->to_csv(), lib.nodes.to_csv());
  EXPECT_EQ(r.get<Table>("edges")->to_csv(), lib.edges.to_csv());
  EXPECT_THROW(run_module("synthetic.vessel_tree", {}, {{"roots", ParamValue(int64_t{1})}}), InputError);
}
