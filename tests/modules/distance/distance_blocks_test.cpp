// Block-wise (out-of-core) distance transforms against the in-memory ones: chamfer by Algorithm 4
// (eight block-wise scans with a one-voxel overlap) must be bit-identical for any block shape,
// odd ones and one-voxel blocks included, on random masks, on objects crossing block corners, with
// anisotropic weights and with the border as object.
#include <gtest/gtest.h>
#include <unistd.h>

#include <filesystem>
#include <cstring>
#include <random>

#include "distance/distance.hpp"
#include "io/hdf5_volume.hpp"
#include "skel/out_of_core.hpp"

namespace skel::distance {
namespace {

namespace fs = std::filesystem;

std::shared_ptr<ChunkedVolume> scratch(const std::string& name, const std::string& type, const Grid& g, const Dims& chunk) {
  // One file per process and volume: ctest runs the tests of this file in parallel processes.
  static int counter = 0;
  const fs::path f = fs::path(SKEL_BINARY_DIR) / "tests" /
                     ("distance_blocks_" + name + "_" + std::to_string(::getpid()) + "_" + std::to_string(++counter) + ".h5");
  return std::make_shared<ChunkedVolume>(g, type, io::create_scratch_store(f, type, g, chunk));
}

VolumeU8 random_mask(std::mt19937& rng, Dims dims, double p_object, Vec3 spacing = {1, 1, 1}) {
  VolumeU8 m(dims, 0, spacing);
  std::bernoulli_distribution obj(p_object);
  for (auto& v : m) v = obj(rng) ? 1 : 0;
  return m;
}

// Solid ball of `radius` voxels around `c`.
VolumeU8 ball(Dims dims, Vec3 c, double radius) {
  VolumeU8 m(dims, 0);
  for (int64_t z = 0; z < dims[2]; ++z)
    for (int64_t y = 0; y < dims[1]; ++y)
      for (int64_t x = 0; x < dims[0]; ++x) {
        const double dx = static_cast<double>(x) - c[0], dy = static_cast<double>(y) - c[1], dz = static_cast<double>(z) - c[2];
        m(x, y, z) = dx * dx + dy * dy + dz * dz <= radius * radius ? 1 : 0;
      }
  return m;
}

// The block-wise chamfer of `mask` read back whole, compared with chamfer().
void expect_same_chamfer(const VolumeU8& mask, const ChamferOptions& o, const Dims& block, const std::string& what) {
  DataPtr in_core = chamfer(mask, o);
  auto out = scratch("chamfer", chamfer_output_type(mask.grid(), o), mask.grid(), block);
  chamfer_blocks(mask, *out, o, block);
  DataPtr blocked = materialize(out);
  ASSERT_EQ(blocked->type_id(), in_core->type_id()) << what;
  if (auto* a = dynamic_cast<const VolumeU16*>(in_core.get())) {
    const auto& b = dynamic_cast<const VolumeU16&>(*blocked);
    ASSERT_EQ(a->grid(), b.grid()) << what;
    int64_t diff = 0;
    for (int64_t i = 0; i < a->size(); ++i) diff += (*a)[i] != b[i];
    EXPECT_EQ(diff, 0) << what << ": " << diff << " voxels differ";
  } else {
    EXPECT_TRUE(dynamic_cast<const VolumeU32&>(*in_core) == dynamic_cast<const VolumeU32&>(*blocked)) << what;
  }
}

TEST(ChamferBlocks, RandomMasksAnyBlockShapeBitIdentical) {
  std::mt19937 rng(16);
  const std::vector<Dims> blocks = {{1, 1, 1}, {2, 3, 2}, {4, 5, 3}, {7, 7, 7}, {13, 17, 11}, {64, 64, 64}};
  for (double p : {0.6, 0.9, 0.99}) {
    const VolumeU8 m = random_mask(rng, {23, 19, 17}, p);
    for (const auto& b : blocks)
      expect_same_chamfer(m, {}, b, "p " + std::to_string(p) + " block " + std::to_string(b[0]) + "x" +
                                        std::to_string(b[1]) + "x" + std::to_string(b[2]));
  }
}

TEST(ChamferBlocks, BallsAcrossBlockCornersBitIdentical) {
  // Blocks of 8: the ball's centre sits on a corner shared by eight blocks; the object spans 27.
  const VolumeU8 m = ball({33, 30, 28}, {16, 16, 16}, 12.5);
  expect_same_chamfer(m, {}, {8, 8, 8}, "ball, blocks 8");
  expect_same_chamfer(m, {}, {5, 9, 6}, "ball, blocks 5x9x6");
}

TEST(ChamferBlocks, AnisotropicWeightsAndBorderAsObject) {
  std::mt19937 rng(7);
  VolumeU8 m = random_mask(rng, {21, 18, 15}, 0.95, {1.0, 1.3, 2.1});
  ChamferOptions o;
  o.derive_from_spacing = true;
  expect_same_chamfer(m, o, {6, 5, 4}, "anisotropic");
  ChamferOptions b;
  b.border_is_object = true;
  expect_same_chamfer(m, b, {6, 5, 4}, "border is object");
  // No background at all with the border as object: the type's maximum everywhere, as in memory.
  VolumeU8 full({9, 8, 7}, 1);
  expect_same_chamfer(full, b, {4, 3, 5}, "no background");
}

TEST(ChamferBlocks, FloatMaskIsAnInputErrorNamingThePort) {
  VolumeF32 f({4, 4, 4}, 1.0f);
  auto out = scratch("float", type_ids::volume_u16, f.grid(), {4, 4, 4});
  try {
    chamfer_blocks(f, *out, {}, {2, 2, 2});
    FAIL() << "no error";
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("input 'mask'"), std::string::npos) << e.what();
  }
}

TEST(ChamferBlocks, ProgressCountsBlockVisitsOfAlgorithm4) {
  const VolumeU8 m = ball({20, 20, 20}, {10, 10, 10}, 7);
  ChamferOptions o;
  std::vector<std::string> notes;
  o.interrupter = Interrupter([](double) {}, nullptr, [&](const std::string& t) { notes.push_back(t); });
  auto out = scratch("progress", chamfer_output_type(m.grid(), o), m.grid(), {8, 8, 8});
  chamfer_blocks(m, *out, o, {8, 8, 8});
  // 27 blocks to start, then 2 * nz * (2nx - 1) * (2ny - 1) = 2 * 3 * 5 * 5 visits.
  ASSERT_FALSE(notes.empty());
  EXPECT_EQ(notes.back(), "chamfer 177/177 blocks");
}

TEST(ChamferBlocks, CancelledBetweenBlocks) {
  const VolumeU8 m = ball({20, 20, 20}, {10, 10, 10}, 7);
  std::atomic<bool> cancel{true};
  ChamferOptions o;
  o.interrupter = Interrupter([](double) {}, &cancel);
  auto out = scratch("cancel", chamfer_output_type(m.grid(), o), m.grid(), {8, 8, 8});
  EXPECT_THROW(chamfer_blocks(m, *out, o, {8, 8, 8}), Cancelled);
}

}  // namespace
}  // namespace skel::distance

namespace skel::distance {
namespace {

void expect_same_edt(const VolumeU8& mask, const EuclideanOptions& o, const Dims& cross, const std::string& what) {
  const VolumeF32 in_core = euclidean(mask, o);
  auto out = scratch("edt", type_ids::volume_f32, mask.grid(), {8, 8, 8});
  euclidean_blocks(mask, *out, o, cross);
  const auto blocked = std::dynamic_pointer_cast<const VolumeF32>(materialize(out));
  ASSERT_TRUE(blocked) << what;
  ASSERT_EQ(blocked->grid(), in_core.grid()) << what;
  int64_t diff = 0;
  for (int64_t i = 0; i < in_core.size(); ++i)
    diff += std::memcmp(&in_core[i], &(*blocked)[i], sizeof(float)) != 0;  // bit for bit (inf included)
  EXPECT_EQ(diff, 0) << what << ": " << diff << " voxels differ";
}

TEST(EuclideanBlocks, BitIdenticalForAnySlabShape) {
  std::mt19937 rng(5);
  for (double p : {0.7, 0.97}) {
    const VolumeU8 m = random_mask(rng, {29, 23, 19}, p);
    for (const Dims& c : std::vector<Dims>{{1, 1, 1}, {3, 5, 2}, {7, 4, 9}, {64, 64, 64}})
      expect_same_edt(m, {}, c, "p " + std::to_string(p) + " cross " + std::to_string(c[0]) + "x" + std::to_string(c[1]) +
                                    "x" + std::to_string(c[2]));
  }
  expect_same_edt(ball({33, 30, 28}, {16, 16, 16}, 12.5), {}, {5, 9, 6}, "ball");
}

TEST(EuclideanBlocks, AnisotropicSquaredAndBorderAsObject) {
  std::mt19937 rng(9);
  const VolumeU8 m = random_mask(rng, {21, 18, 15}, 0.95, {0.7, 1.3, 2.1});
  expect_same_edt(m, {}, {4, 3, 5}, "anisotropic");
  EuclideanOptions sq;
  sq.squared = true;
  expect_same_edt(m, sq, {4, 3, 5}, "squared");
  EuclideanOptions b;
  b.border_is_object = true;
  expect_same_edt(m, b, {6, 5, 4}, "border is object");
  expect_same_edt(VolumeU8({9, 8, 7}, 1), b, {4, 3, 5}, "no background: +inf everywhere");
  expect_same_edt(VolumeU8({9, 1, 7}, 1), {}, {4, 3, 5}, "one row thick");
}

TEST(EuclideanBlocks, CrossSectionFromBudget) {
  // 256 MiB: a quarter holds one slab of 512-voxel lines at 5 bytes per voxel: side sqrt(13421772 / 512) = 161.
  EXPECT_EQ(euclidean_cross_section(256ull << 20, {512, 512, 300}), (Dims{161, 161, 161}));
  EXPECT_EQ(euclidean_cross_section(1024, {512, 512, 512}), (Dims{1, 1, 1}));
}

}  // namespace
}  // namespace skel::distance
