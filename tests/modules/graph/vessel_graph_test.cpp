// Ground truth check on the synthetic vessel network: mask → Euclidean distance → smooth DOHT with end
// points → skeleton_to_graph → prune: the graph's loops equal the tunnels of skeleton and mask exactly
// (also after pruning), and the total length is close to the phantom's ground-truth graph.
#include <gtest/gtest.h>

#include <cstdlib>

#include "distance/distance.hpp"
#include "graph/graph_ops.hpp"
#include "analysis/network_analysis.hpp"
#include "geometry/skeleton_to_graph.hpp"
#include "graph_test_util.hpp"
#include "synthetic/vessel_tree.hpp"
#include "thinning/thinning.hpp"

using namespace skel::thinning;
using namespace skel::analysis;
using namespace skel::geometry;
using namespace skel::graph;

using namespace skel;

TEST(VesselGraph, RecoversTheSyntheticNetwork) {
  for (uint64_t seed : {1, 2, 3, 4, 5, 6}) {
    SCOPED_TRACE("seed " + std::to_string(seed));
    synthetic::VesselTreeOptions vo;
    vo.size = {96, 96, 64};
    vo.seed = seed;
    vo.threads = 2;
    const auto phantom = synthetic::make_vessel_tree(vo);
    distance::EuclideanOptions eo;
    eo.threads = 2;
    const VolumeF32 dist = distance::euclidean(phantom.mask, eo);
    ThinningOptions to;
    to.threads = 2;
    to.end_point_length = 3;
    const auto thin = thin_doht(phantom.mask, dist, nullptr, to);
    SkeletonToGraphOptions go;
    go.threads = 2;
    auto g = skeleton_to_graph(thin.skeleton, &dist, go).graph;
    ASSERT_TRUE(g.check_invariants().empty());
    // The graph has exactly the tunnels of the skeleton (= those of the mask, thinning keeps topology).
    const auto mask_topo = skel::test::topology_26_6(phantom.mask);
    EXPECT_EQ(g.cyclomatic_number(), skel::test::topology_26_6(thin.skeleton).tunnels);
    EXPECT_EQ(g.cyclomatic_number(), mask_topo.tunnels);
    prune(g, {.min_length = 4.0, .max_iterations = 0, .interrupter = {}});
    const auto ours = network_statistics(g).summary;
    const auto truth = network_statistics(phantom.truth).summary;
    EXPECT_EQ(ours.ints("loops")[0], mask_topo.tunnels);
    // Thinning shortens every free end by about the vessel radius, and the phantom's mask may merge or
    // miss thin capillaries, so lengths agree only approximately.
    EXPECT_NEAR(ours.reals("total_length")[0], truth.reals("total_length")[0], 0.10 * truth.reals("total_length")[0]);
  }
}
