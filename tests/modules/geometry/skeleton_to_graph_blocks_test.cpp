// Block-wise (out-of-core) skeleton_to_graph against the in-memory function: the same nodes, edges,
// polylines, labels, radii and manifold types for skeletons whose loops, junctions, junction
// clusters with tunnels and plates cross block faces, edges and corners, for odd block shapes,
// one-voxel blocks and a skeleton read from disk.
#include <gtest/gtest.h>
#include <unistd.h>

#include <filesystem>
#include <random>

#include "../graph/graph_test_util.hpp"
#include "geometry/skeleton_to_graph.hpp"
#include "io/hdf5_volume.hpp"
#include "skel/out_of_core.hpp"

namespace skel::geometry {
namespace {

namespace fs = std::filesystem;
using skel::test::draw_line;
using skel::test::draw_square_ring;

std::shared_ptr<ChunkedVolume> scratch(const std::string& name, const std::string& type, const Grid& g) {
  static int counter = 0;
  const fs::path f = fs::path(SKEL_BINARY_DIR) / "tests" /
                     ("skeleton_to_graph_blocks_" + name + "_" + std::to_string(::getpid()) + "_" +
                      std::to_string(++counter) + ".h5");
  return std::make_shared<ChunkedVolume>(g, type, io::create_scratch_store(f, type, g, {8, 8, 8}));
}

// Everything the graph holds, compared exactly (positions are sums of the same voxel positions in
// the same order, so even the doubles are equal).
void expect_same_graph(const SpatialGraph& a, const SpatialGraph& b, const std::string& what) {
  ASSERT_EQ(a.node_count(), b.node_count()) << what;
  ASSERT_EQ(a.edge_count(), b.edge_count()) << what;
  EXPECT_EQ(a.positions, b.positions) << what;
  for (int64_t e = 0; e < a.edge_count(); ++e) {
    EXPECT_EQ(a.edges[e].node0, b.edges[e].node0) << what << " edge " << e;
    EXPECT_EQ(a.edges[e].node1, b.edges[e].node1) << what << " edge " << e;
    EXPECT_EQ(a.edges[e].points, b.edges[e].points) << what << " edge " << e;
    EXPECT_EQ(a.edge_length(e), b.edge_length(e)) << what << " edge " << e;
  }
  EXPECT_EQ(a.node_labels, b.node_labels) << what;
  EXPECT_EQ(a.node_attributes, b.node_attributes) << what;
  EXPECT_EQ(a.point_attributes, b.point_attributes) << what;
  EXPECT_EQ(a.edge_attributes, b.edge_attributes) << what;
  EXPECT_EQ(a.unit, b.unit) << what;
  EXPECT_EQ(a.source_grid.dims, b.source_grid.dims) << what;
  EXPECT_EQ(a.source_grid.origin, b.source_grid.origin) << what;
  EXPECT_EQ(a.connected_components(), b.connected_components()) << what;
  EXPECT_EQ(a.cyclomatic_number(), b.cyclomatic_number()) << what;
  EXPECT_TRUE(b.check_invariants().empty()) << what;
}

const std::vector<Dims>& block_shapes() {
  static const std::vector<Dims> shapes{{1, 1, 1}, {2, 3, 5}, {4, 4, 4}, {5, 7, 3}, {7, 6, 11}, {64, 64, 64}};
  return shapes;
}

// Compares block-wise to in-memory for every block shape, the skeleton in memory and on disk, with
// a float distance on disk (radii) and the manifold volume.
void check_equal(const VolumeU8& v, const std::string& what) {
  VolumeF32 dist(v.grid(), 0.0f);
  for (int64_t i = 0; i < dist.size(); ++i) dist[i] = static_cast<float>((i * 7919) % 101) * 0.25f;
  SkeletonToGraphOptions o;
  o.radius_scale = 0.5;
  o.smooth_passes = 2;
  o.want_manifold = true;
  const SkeletonGraphResult in_core = skeleton_to_graph(v, &dist, o);
  SkeletonToGraphOptions plain;
  const SpatialGraph in_core_plain = skeleton_to_graph(v, nullptr, plain).graph;
  auto on_disk = scratch("skeleton", type_ids::volume_u8, v.grid());
  on_disk->write(v, {0, 0, 0});
  auto dist_disk = scratch("distance", type_ids::volume_f32, v.grid());
  dist_disk->write(dist, {0, 0, 0});
  for (const Dims& b : block_shapes()) {
    const std::string tag = what + " block " + std::to_string(b[0]) + "x" + std::to_string(b[1]) + "x" + std::to_string(b[2]);
    auto manifold = scratch("manifold", type_ids::volume_u8, v.grid());
    const SpatialGraph g = skeleton_to_graph_blocks(*on_disk, dist_disk.get(), b, o, manifold.get());
    expect_same_graph(in_core.graph, g, tag + " (on disk, radius)");
    EXPECT_TRUE(manifold->read<uint8_t>({0, 0, 0}, v.dims()) == in_core.manifold) << tag;
    expect_same_graph(in_core_plain, skeleton_to_graph_blocks(v, nullptr, b, plain), tag + " (in memory)");
  }
}

TEST(SkeletonToGraphBlocks, LoopsThroughBlockEdgesAndCorners) {
  // Blocks of 4: a ring around the block edge x = 4, y = 4 (every voxel in another block than its
  // neighbour across the edge), a ring through the corner (4, 4, 4), a diagonal line through corners.
  VolumeU8 v({13, 11, 9}, 0, {0.5, 1.0, 2.0});
  draw_square_ring(v, {2, 2, 2}, 0, 1, 5);   // in the plane z = 2, around the edge x = 4, y = 4
  draw_square_ring(v, {3, 3, 4}, 0, 2, 3);   // through the corner (4, 4, 4)
  draw_line(v, {0, 0, 8}, {8, 8, 0});        // 26-steps through block corners
  draw_line(v, {12, 0, 0}, {12, 10, 8});
  draw_line(v, {8, 10, 0}, {12, 10, 4});     // a junction on the volume's border
  check_equal(v, "rings");
}

TEST(SkeletonToGraphBlocks, JunctionClustersPlatesAndIsolatedVoxelsOnBlockBorders) {
  VolumeU8 v({17, 15, 13}, 0);
  // A plate (surface voxels) crossing the faces x = 4 and x = 8, with a rod through it.
  for (int64_t x = 3; x <= 9; ++x)
    for (int64_t y = 2; y <= 6; ++y) v(x, y, 5) = 1;
  draw_line(v, {6, 4, 0}, {6, 4, 12});
  // A junction cluster with a tunnel (ring of junction voxels) at the corner (8, 8, 8).
  draw_square_ring(v, {7, 7, 8}, 0, 1, 3);
  draw_line(v, {7, 7, 8}, {7, 7, 12});
  draw_line(v, {9, 9, 8}, {16, 14, 8});
  draw_line(v, {9, 7, 8}, {9, 7, 0});
  // Isolated voxels and a 26-adjacent pair on block corners.
  v(0, 0, 0) = 1;
  v(4, 12, 4) = 1;
  v(15, 3, 11) = 1;
  v(16, 4, 12) = 1;
  check_equal(v, "plates");
}

TEST(SkeletonToGraphBlocks, RandomDigitalLinesEqualInCore) {
  for (int seed = 0; seed < 12; ++seed) {
    std::mt19937 rng(static_cast<unsigned>(seed));
    VolumeU8 v({19, 17, 15}, 0);
    const int segments = 4 + seed % 8;
    for (int s = 0; s < segments; ++s) {
      std::array<int64_t, 3> a{}, b{};
      for (int k = 0; k < 3; ++k) {
        a[k] = static_cast<int64_t>(rng() % static_cast<unsigned>(v.dims()[k]));
        b[k] = static_cast<int64_t>(rng() % static_cast<unsigned>(v.dims()[k]));
      }
      draw_line(v, a, b);
    }
    check_equal(v, "seed " + std::to_string(seed));
  }
}

TEST(SkeletonToGraphBlocks, EmptySkeletonAndErrors) {
  VolumeU8 empty({5, 6, 7}, 0);
  const SpatialGraph g = skeleton_to_graph_blocks(empty, nullptr, {2, 2, 2}, {});
  EXPECT_EQ(g.node_count(), 0);
  EXPECT_EQ(g.edge_count(), 0);
  EXPECT_EQ(g.source_grid.dims, empty.dims());
  VolumeF32 wrong({5, 6, 8}, 0.0f);
  try {
    (void)skeleton_to_graph_blocks(empty, &wrong, {2, 2, 2}, {});
    ADD_FAILURE() << "a distance on another grid was accepted";
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("input 'distance'"), std::string::npos) << e.what();
  }
  VolumeF32 not_u8({5, 6, 7}, 0.0f);
  try {
    (void)skeleton_to_graph_blocks(not_u8, nullptr, {2, 2, 2}, {});
    ADD_FAILURE() << "a float skeleton was accepted";
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("input 'skeleton'"), std::string::npos) << e.what();
  }
}

}  // namespace
}  // namespace skel::geometry
