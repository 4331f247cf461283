// The comparison.* modules through run_module: outputs per input kind, parameters, errors.
#include <gtest/gtest.h>

#include <cmath>
#include <memory>

#include "comparison/comparison.hpp"
#include "skel/run_module.hpp"
#include "skel/spatial_graph.hpp"
#include "skel/table.hpp"

namespace skel {
namespace {

std::shared_ptr<VolumeU8> line_volume(int64_t y, Vec3 spacing = {1, 1, 1}) {
  auto v = std::make_shared<VolumeU8>(Dims{16, 8, 6}, 0, spacing);
  for (int64_t x = 2; x < 14; ++x) (*v)(x, y, 3) = 1;
  return v;
}

TEST(ComparisonModules, SkeletonDistanceOnVolumes) {
  auto a = line_volume(2, {0.5, 2.0, 1.0});
  auto b = line_volume(3, {0.5, 2.0, 1.0});
  // A uint16 label volume is a skeleton too (voxel > 0).
  auto b16 = std::make_shared<VolumeU16>(b->grid(), 0);
  for (int64_t i = 0; i < b->size(); ++i) (*b16)[i] = (*b)[i] ? 7 : 0;
  auto r = run_module("comparison.skeleton_distance", {{"reference", a}, {"other", b16}},
                      {{"threshold", 1.5}, {"symmetric", true}, {"off_skeleton", std::string("nan")}}, {.threads = 2});
  auto d = r.get<VolumeF32>("distance");
  auto c = r.get<VolumeU8>("changed");
  auto t = r.get<Table>("table");
  EXPECT_TRUE(r.outputs.count("other_distance"));
  EXPECT_FALSE(r.outputs.count("graph"));
  for (int64_t i = 0; i < a->size(); ++i) {
    if ((*a)[i]) {
      EXPECT_FLOAT_EQ((*d)[i], 2.0f);  // one voxel along y = 2 µm
      EXPECT_EQ((*c)[i], 1);
    } else {
      EXPECT_TRUE(std::isnan((*d)[i]));
      EXPECT_EQ((*c)[i], 0);
    }
  }
  ASSERT_EQ(t->rows(), 3);
  EXPECT_EQ(t->strings("direction")[2], "symmetric");
  EXPECT_DOUBLE_EQ(t->reals("hausdorff")[2], 2.0);
  EXPECT_DOUBLE_EQ(t->reals("changed_fraction")[0], 1.0);
  EXPECT_EQ(t->ints("points")[0], 12);
}

TEST(ComparisonModules, SkeletonDistanceOnGraphs) {
  auto g = std::make_shared<SpatialGraph>();
  g->add_node({0, 0, 0});
  g->add_node({8, 0, 0});
  g->add_edge(0, 1);
  auto v = line_volume(0);
  auto r = run_module("comparison.skeleton_distance", {{"reference", g}, {"other", v}}, {{"threshold", 1.0}});
  EXPECT_FALSE(r.outputs.count("distance"));
  auto out = r.get<SpatialGraph>("graph");
  ASSERT_TRUE(out->point_attributes.count("distance"));
  // (0,0,0) is 3 voxels from the line at z = 3, (8,0,0) too.
  EXPECT_FLOAT_EQ(out->point_attributes.at("distance")[0][0], std::sqrt(4.0f + 9.0f));
  EXPECT_FLOAT_EQ(out->point_attributes.at("distance")[0][1], 3.0f);
  EXPECT_EQ(out->point_attributes.at("changed")[0][1], 1.0f);
}

TEST(ComparisonModules, SkeletonDistanceErrors) {
  auto f = std::make_shared<VolumeF32>(Dims{4, 4, 4}, 1.0f);
  auto u = std::make_shared<VolumeU8>(Dims{4, 4, 4}, 1);
  // Float volumes are rejected at the port.
  EXPECT_THROW(run_module("comparison.skeleton_distance", {{"reference", f}, {"other", u}}), InputError);
  auto u2 = std::make_shared<VolumeU8>(Dims{5, 4, 4}, 1);
  try {
    run_module("comparison.skeleton_distance", {{"reference", u}, {"other", u2}}, {{"method", std::string("transform")}});
    FAIL();
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("method"), std::string::npos) << e.what();
  }
  auto r = run_module("comparison.skeleton_distance", {{"reference", u}, {"other", u2}});
  EXPECT_EQ(r.get<Table>("table")->reals("hausdorff")[0], 0.0);
}

TEST(ComparisonModules, GraphMatch) {
  auto a = std::make_shared<SpatialGraph>();
  a->add_node({0, 0, 0});
  a->add_node({10, 0, 0});
  a->add_node({10, 10, 0});
  a->add_edge(0, 1);
  a->add_edge(1, 2);
  auto b = std::make_shared<SpatialGraph>(*a);
  b->remove_edges({1});
  b->add_node({20, 0, 0});
  b->add_edge(1, 3);
  auto r = run_module("comparison.graph_match", {{"reference", a}, {"other", b}},
                      {{"node_tolerance", 1.0}, {"edge_tolerance", 1.0}, {"sample_spacing", 0.5}}, {.threads = 2});
  auto t = r.get<Table>("table");
  ASSERT_EQ(t->rows(), 3);
  EXPECT_EQ(t->strings("level")[1], "edges");
  EXPECT_EQ(t->reals("tp")[1], 1.0);
  EXPECT_EQ(t->reals("fn")[1], 1.0);
  EXPECT_EQ(t->reals("fp")[1], 1.0);
  EXPECT_EQ(t->reals("fp")[0], 1.0);  // the new node
  // Length: edge 0-1 (10) is covered, and of the deleted edge 1-2 the part within edge_tolerance (1.0)
  // of node 1 — 11 of 20 units, up to half a sample spacing (0.5) of discretisation.
  EXPECT_NEAR(t->reals("recall")[2], 0.55, 0.25 / 20 + 1e-12);
  auto ra = r.get<SpatialGraph>("reference_graph");
  EXPECT_EQ(ra->edge_labels.at("matched"), (std::vector<int32_t>{1, 0}));
  auto rb = r.get<SpatialGraph>("other_graph");
  EXPECT_EQ(rb->node_labels.at("matched"), (std::vector<int32_t>{1, 1, 1, 0}));
  auto err = r.get<Table>("errors");
  EXPECT_NEAR(err->reals("geometric_fnr")[0], 0.45, 0.25 / 20 + 1e-12);
  EXPECT_THROW(run_module("comparison.graph_match", {{"reference", a}, {"other", b}}, {{"overlap", 0.0}}), InputError);
}

}  // namespace
}  // namespace skel
