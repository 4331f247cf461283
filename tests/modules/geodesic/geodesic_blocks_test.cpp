// Block-wise (out-of-core) geodesic boundary distance against the in-memory function: importance and
// surface skeleton identical on plates, mixed phantoms and random blobs for odd block shapes and tiny
// budgets (blocks halved until their margin fits); refused with the parameter named when no block
// can hold its margin, and in full mode.
#include <gtest/gtest.h>
#include <unistd.h>

#include <algorithm>
#include <filesystem>
#include <random>

#include "geodesic/geodesic_blocks.hpp"
#include "io/hdf5_volume.hpp"
#include "synthetic/network.hpp"

namespace skel::geodesic {
namespace {

namespace fs = std::filesystem;

std::shared_ptr<ChunkedVolume> scratch(const std::string& name, const std::string& type, const Grid& g) {
  static int counter = 0;
  const fs::path f = fs::path(SKEL_BINARY_DIR) / "tests" /
                     ("geodesic_blocks_" + name + "_" + std::to_string(::getpid()) + "_" + std::to_string(++counter) + ".h5");
  return std::make_shared<ChunkedVolume>(g, type, io::create_scratch_store(f, type, g, {8, 8, 8}));
}

VolumeU8 phantom(synthetic::Shape shape, const Dims& size, uint64_t seed) {
  synthetic::NetworkOptions o;
  o.shape = shape;
  o.size = size;
  o.seed = seed;
  o.period = 14;
  o.radius = 2.5;
  o.plate_thickness = 4.0;
  o.noise = 0.3;
  return synthetic::make_network(o).mask;
}

VolumeU8 random_blobs(const Dims& d, uint64_t seed) {
  std::mt19937_64 rng(seed);
  VolumeU8 v(d, 0);
  std::uniform_real_distribution<double> u(0, 1);
  for (auto& x : v) x = u(rng) < 0.5 ? 1 : 0;
  VolumeU8 s(d, 0);
  for (int64_t z = 0; z < d[2]; ++z)
    for (int64_t y = 0; y < d[1]; ++y)
      for (int64_t x = 0; x < d[0]; ++x) {
        int c = v(x, y, z);
        c += v.at_or(x - 1, y, z, 0) + v.at_or(x + 1, y, z, 0) + v.at_or(x, y - 1, z, 0) + v.at_or(x, y + 1, z, 0) +
             v.at_or(x, y, z - 1, 0) + v.at_or(x, y, z + 1, 0);
        s(x, y, z) = c >= 4 ? 1 : 0;
      }
  return s;
}

// Block-wise equals in-core for the block shapes and budgets given; returns the largest margin used.
int64_t check_equal(const VolumeU8& mask, int64_t t, const std::vector<Dims>& blocks, uint64_t budget,
                    const std::string& what) {
  Options o;
  o.threshold = t;
  o.threads = 1;  // many small blocks: thread start-up would dominate
  const Result in_core = boundary_distance(mask, o);
  auto on_disk = scratch("mask", type_ids::volume_u8, mask.grid());
  on_disk->write(mask, {0, 0, 0});
  int64_t margin = 0;
  for (const Dims& b : blocks) {
    const std::string tag = what + " t " + std::to_string(t) + " block " + std::to_string(b[0]) + "x" +
                            std::to_string(b[1]) + "x" + std::to_string(b[2]);
    auto imp = scratch("importance", type_ids::volume_f32, mask.grid());
    auto surf = scratch("surface", type_ids::volume_u8, mask.grid());
    const BlockStatistics s = boundary_distance_blocks(*on_disk, *imp, *surf, o, b, budget);
    EXPECT_TRUE(imp->read<float>({0, 0, 0}, mask.dims()) == in_core.importance) << tag;
    EXPECT_TRUE(surf->read<uint8_t>({0, 0, 0}, mask.dims()) == in_core.surface_skeleton) << tag;
    EXPECT_EQ(s.object_voxels, in_core.stats.object_voxels) << tag;
    EXPECT_GE(s.largest_margin, exact_margin(s.max_ring, t)) << tag;
    if (budget > 0) {
      EXPECT_LE(s.largest_block_bytes, budget) << tag;
    }
    margin = std::max(margin, s.largest_margin);
  }
  return margin;
}

TEST(GeodesicBlocks, PlatesEqualInCore) {
  const VolumeU8 m = phantom(synthetic::Shape::plates, {37, 33, 29}, 3);
  ASSERT_GT(std::count(m.begin(), m.end(), uint8_t{1}), 1000);
  for (int64_t t : {3, 8}) check_equal(m, t, {{5, 7, 3}, {8, 8, 8}, {13, 11, 17}, {64, 64, 64}}, 0, "plates");
  check_equal(m, 20, {{13, 11, 17}, {64, 64, 64}}, 0, "plates");
}

TEST(GeodesicBlocks, MixedAndBlobsEqualInCore) {
  const VolumeU8 mixed = phantom(synthetic::Shape::mixed, {31, 29, 35}, 5);
  for (int64_t t : {4, 12}) check_equal(mixed, t, {{6, 5, 7}, {16, 16, 16}}, 0, "mixed");
  for (uint64_t seed = 1; seed <= 4; ++seed) {
    const VolumeU8 blobs = random_blobs({19, 17, 21}, seed);
    check_equal(blobs, 5, {{3, 4, 5}, {7, 5, 6}}, 0, "blobs " + std::to_string(seed));
  }
}

TEST(GeodesicBlocks, ThickSlabNeedsTheRingsMarginAndTinyBudgetsHalveBlocks) {
  // A slab 11 voxels thick: d_max = 6, so blocks of 4 with the least margin (t/2 + 3) are read again
  // with the larger one; a budget that holds only small boxes halves the 32-voxel blocks.
  VolumeU8 slab({40, 36, 30}, 0);
  for (int64_t z = 10; z < 21; ++z)
    for (int64_t y = 3; y < 33; ++y)
      for (int64_t x = 2; x < 38; ++x) slab(x, y, z) = 1;
  const int64_t m = check_equal(slab, 6, {{4, 4, 4}, {7, 9, 5}}, 0, "slab");
  EXPECT_EQ(m, exact_margin(6, 6));
  const uint64_t budget = static_cast<uint64_t>(34 * 34 * 34) * kBlockBytesPerVoxel;
  check_equal(slab, 6, {{32, 32, 32}}, budget, "slab, tiny budget");
}

TEST(GeodesicBlocks, RefusedWhenNoBlockHoldsItsMarginAndInFullMode) {
  VolumeU8 cube({30, 30, 30}, 0);
  for (int64_t z = 2; z < 28; ++z)
    for (int64_t y = 2; y < 28; ++y)
      for (int64_t x = 2; x < 28; ++x) cube(x, y, z) = 1;
  auto imp = scratch("importance", type_ids::volume_f32, cube.grid());
  auto surf = scratch("surface", type_ids::volume_u8, cube.grid());
  Options o;
  o.threshold = 10;
  // d_max 13: a margin of 21 around 8 voxels does not fit 20³ voxels' worth of budget.
  const uint64_t budget = static_cast<uint64_t>(20 * 20 * 20) * kBlockBytesPerVoxel;
  try {
    (void)boundary_distance_blocks(cube, *imp, *surf, o, {16, 16, 16}, budget);
    ADD_FAILURE() << "a block without room for its margin was accepted";
  } catch (const InputError& e) {
    const std::string msg = e.what();
    EXPECT_NE(msg.find("parameter 'threshold'"), std::string::npos) << msg;
    EXPECT_NE(msg.find("memory budget"), std::string::npos) << msg;
  }
  o.mode = Mode::Full;
  try {
    (void)boundary_distance_blocks(cube, *imp, *surf, o, {16, 16, 16}, 0);
    ADD_FAILURE() << "full mode was accepted block-wise";
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("parameter 'mode'"), std::string::npos) << e.what();
  }
}

}  // namespace
}  // namespace skel::geodesic
