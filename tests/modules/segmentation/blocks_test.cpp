// Block-wise (out-of-core) segmentation against the in-memory functions: threshold (manual and
// Otsu), connected components (same labels, mask and table for 6/18/26-connectivity, min_size,
// keep_largest) and fill_cavities for odd block shapes, one-voxel blocks and objects that touch only across block
// edges and corners; Gaussian, median and illumination_z give the same values.
#include <gtest/gtest.h>
#include <unistd.h>

#include <cmath>
#include <cstring>
#include <filesystem>
#include <random>

#include "io/hdf5_volume.hpp"
#include "segmentation/segmentation.hpp"
#include "skel/out_of_core.hpp"

namespace skel::segmentation {
namespace {

namespace fs = std::filesystem;

std::shared_ptr<ChunkedVolume> scratch(const std::string& name, const std::string& type, const Grid& g) {
  // One file per process and volume: ctest runs the tests of this file in parallel processes.
  static int counter = 0;
  const fs::path f = fs::path(SKEL_BINARY_DIR) / "tests" /
                     ("segmentation_blocks_" + name + "_" + std::to_string(::getpid()) + "_" + std::to_string(++counter) + ".h5");
  return std::make_shared<ChunkedVolume>(g, type, io::create_scratch_store(f, type, g, {8, 8, 8}));
}

template <class T>
Volume<T> whole(const ChunkedVolume& c) {
  return c.read<T>({0, 0, 0}, c.dims());
}

TEST(ThresholdBlocks, ManualAndOtsuSameMaskAndThresholds) {
  std::mt19937 rng(3);
  VolumeF32 img({23, 19, 17}, 0.0f, {0.5, 1, 2});
  std::normal_distribution<float> noise(0.0f, 0.3f);
  for (int64_t i = 0; i < img.size(); ++i) img[i] = (i % 7 < 3 ? 1.0f : 0.0f) + noise(rng);
  for (ThresholdMethod method : {ThresholdMethod::manual, ThresholdMethod::otsu}) {
    ThresholdOptions o;
    o.method = method;
    o.low = 0.4;
    o.high = 1.2;
    const ThresholdResult in_core = threshold(img, o);
    for (const Dims& b : std::vector<Dims>{{1, 1, 1}, {5, 7, 3}, {13, 17, 11}}) {
      auto mask = scratch("threshold", type_ids::volume_u8, img.grid());
      const BlockThresholdResult r = threshold_blocks(img, *mask, o, b);
      EXPECT_EQ(r.low, in_core.low);
      EXPECT_EQ(r.high, in_core.high);
      EXPECT_EQ(r.object_voxels, in_core.object_voxels);
      EXPECT_TRUE(whole<uint8_t>(*mask) == in_core.mask);
    }
  }
  // uint8 images (exact Otsu bins) read from disk.
  VolumeU8 bytes({16, 16, 16});
  for (int64_t i = 0; i < bytes.size(); ++i) bytes[i] = static_cast<uint8_t>((i * 37) % 251);
  auto on_disk = scratch("threshold_in", type_ids::volume_u8, bytes.grid());
  on_disk->write(bytes, {0, 0, 0});
  ThresholdOptions otsu;
  otsu.method = ThresholdMethod::otsu;
  auto mask = scratch("threshold_u8", type_ids::volume_u8, bytes.grid());
  const BlockThresholdResult r = threshold_blocks(*on_disk, *mask, otsu, {6, 5, 7});
  const ThresholdResult in_core = threshold(bytes, otsu);
  EXPECT_EQ(r.low, in_core.low);
  EXPECT_TRUE(whole<uint8_t>(*mask) == in_core.mask);
}

void expect_same_components(const VolumeU8& m, const ComponentOptions& o, const Dims& block, const std::string& what) {
  const ComponentsResult in_core = connected_components(m, o);
  auto labels = scratch("labels", type_ids::volume_u32, m.grid());
  auto kept = scratch("kept", type_ids::volume_u8, m.grid());
  const BlockComponentsResult r = connected_components_blocks(m, *labels, *kept, o, block);
  EXPECT_EQ(r.count, in_core.count) << what;
  EXPECT_TRUE(whole<uint32_t>(*labels) == in_core.labels) << what;
  EXPECT_TRUE(whole<uint8_t>(*kept) == in_core.mask) << what;
  EXPECT_EQ(r.table.to_csv(), in_core.table.to_csv()) << what;
  EXPECT_EQ(r.warning, in_core.warning) << what;
}

TEST(ComponentsBlocks, RandomMasksSameLabelsAndTable) {
  std::mt19937 rng(11);
  for (double p : {0.2, 0.35, 0.6}) {
    VolumeU8 m({25, 21, 18}, 0, {1, 2, 3}, {5, 6, 7});
    std::bernoulli_distribution obj(p);
    for (auto& v : m) v = obj(rng) ? 1 : 0;
    for (Connectivity c : {Connectivity::c6, Connectivity::c18, Connectivity::c26})
      for (const Dims& b : std::vector<Dims>{{2, 1, 3}, {4, 7, 5}, {13, 17, 11}, {64, 64, 64}}) {
        ComponentOptions o;
        o.connectivity = c;
        expect_same_components(m, o, b, "p " + std::to_string(p) + " c" + std::to_string(static_cast<int>(c)) +
                                            " block " + std::to_string(b[0]) + "x" + std::to_string(b[1]) + "x" +
                                            std::to_string(b[2]));
      }
  }
}

TEST(ComponentsBlocks, DiagonalChainsThroughBlockCornersAndFilters) {
  // A chain of voxels touching only at corners, crossing the corners of 4x4x4 blocks: one component
  // for 26-connectivity, single voxels for 6 and 18.
  VolumeU8 m({16, 16, 16});
  for (int64_t i = 0; i < 16; ++i) m(i, i, i) = 1;
  for (int64_t i = 0; i < 10; ++i) m(15 - i, i, 3) = 1;  // an edge-diagonal chain in a plane
  for (Connectivity c : {Connectivity::c6, Connectivity::c18, Connectivity::c26}) {
    ComponentOptions o;
    o.connectivity = c;
    expect_same_components(m, o, {4, 4, 4}, "chains c" + std::to_string(static_cast<int>(c)));
    expect_same_components(m, o, {1, 1, 1}, "chains, one-voxel blocks, c" + std::to_string(static_cast<int>(c)));
  }
  ComponentOptions o;
  o.min_size = 2;
  expect_same_components(m, o, {3, 5, 4}, "min_size");
  o.keep_largest = true;
  expect_same_components(m, o, {3, 5, 4}, "keep_largest");
  ComponentOptions f;
  f.min_fraction = 0.5;  // the 10-voxel chain is more than half of the 16-voxel one
  expect_same_components(m, f, {3, 5, 4}, "min_fraction");
  expect_same_components(VolumeU8({9, 8, 7}), {}, {4, 4, 4}, "empty");
  expect_same_components(VolumeU8({9, 8, 7}, 1), {}, {4, 4, 4}, "full");
}

void expect_same_fill(const VolumeU8& m, const Dims& block, const std::string& what) {
  int64_t filled_in_core = 0;
  const VolumeU8 in_core = fill_cavities(m, &filled_in_core);
  auto out = scratch("filled", type_ids::volume_u8, m.grid());
  const int64_t filled = fill_cavities_blocks(m, *out, block);
  EXPECT_EQ(filled, filled_in_core) << what;
  EXPECT_TRUE(whole<uint8_t>(*out) == in_core) << what;
}

TEST(FillCavitiesBlocks, SameMaskAsInMemory) {
  std::mt19937 rng(21);
  for (double p : {0.55, 0.7, 0.85}) {
    VolumeU8 m({22, 19, 17});
    std::bernoulli_distribution obj(p);
    for (auto& v : m) v = obj(rng) ? 1 : 0;
    for (const Dims& b : std::vector<Dims>{{1, 1, 1}, {4, 7, 5}, {13, 17, 11}})
      expect_same_fill(m, b, "p " + std::to_string(p) + " block " + std::to_string(b[0]));
  }
  // A hollow ball whose cavity spans the corner of eight 8³ blocks, and a tunnel to the border that
  // leaves through a block face: the first is filled, the second not.
  VolumeU8 shell({24, 24, 24});
  for (int64_t z = 0; z < 24; ++z)
    for (int64_t y = 0; y < 24; ++y)
      for (int64_t x = 0; x < 24; ++x) {
        const double r = std::sqrt(double((x - 8) * (x - 8) + (y - 8) * (y - 8) + (z - 8) * (z - 8)));
        shell(x, y, z) = r >= 4 && r <= 6.5 ? 1 : 0;
      }
  expect_same_fill(shell, {8, 8, 8}, "hollow ball");
  int64_t filled = 0;
  (void)fill_cavities(shell, &filled);
  EXPECT_GT(filled, 100);
  for (int64_t x = 8; x < 24; ++x) shell(x, 8, 8) = 0;  // tunnel to the x face
  expect_same_fill(shell, {8, 8, 8}, "opened ball");
}

TEST(GaussianBlocks, SameValuesAsInMemory) {
  std::mt19937 rng(4);
  VolumeU16 img({27, 22, 19}, 0, {0.8, 1.0, 1.7});
  std::uniform_int_distribution<int> val(0, 4000);
  for (auto& v : img) v = static_cast<uint16_t>(val(rng));
  for (const Vec3& sigma : std::vector<Vec3>{{1, 1, 1}, {2.5, 0, 1.2}}) {
    GaussianOptions o;
    o.sigma = sigma;
    const VolumeF32 in_core = gaussian(img, o);
    for (const Dims& b : std::vector<Dims>{{3, 4, 2}, {5, 7, 3}, {13, 17, 11}}) {
      auto out = scratch("gaussian", type_ids::volume_f32, img.grid());
      gaussian_blocks(img, *out, o, b);
      const VolumeF32 blocked = whole<float>(*out);
      int64_t diff = 0;
      for (int64_t i = 0; i < img.size(); ++i) diff += std::memcmp(&blocked[i], &in_core[i], sizeof(float)) != 0;
      EXPECT_EQ(diff, 0) << "sigma " << sigma[0] << " block " << b[0] << "x" << b[1] << "x" << b[2];
    }
  }
  GaussianOptions o;
  o.sigma = {2.5, 0, 1.2};
  EXPECT_EQ(gaussian_halo(img.grid(), o), (Dims{11, 0, 3}));  // ceil(3.5 * 2.5 / 0.8), -, ceil(3.5 * 1.2 / 1.7)
}

TEST(MedianBlocks, SameValuesAsInMemory) {
  std::mt19937 rng(8);
  VolumeU16 img({21, 17, 13});
  std::uniform_int_distribution<int> val(0, 1000);
  for (auto& v : img) v = static_cast<uint16_t>(val(rng));
  for (int64_t radius : {0, 1, 2}) {
    MedianOptions o;
    o.radius = static_cast<int>(radius);
    const VolumeU16 in_core = median_as(img, o);
    for (const Dims& b : std::vector<Dims>{{3, 4, 2}, {13, 17, 11}}) {
      auto out = scratch("median", type_ids::volume_u16, img.grid());
      median_blocks(img, *out, o, b);
      EXPECT_TRUE(whole<uint16_t>(*out) == in_core) << "radius " << radius << " block " << b[0];
    }
  }
}

TEST(IlluminationBlocks, SameStatisticsFactorsAndValuesAsInMemory) {
  // Brightness falling with depth, noise, an image on disk and one in memory; odd blocks and slabs.
  std::mt19937 rng(11);
  VolumeU16 img({23, 19, 29}, 0, {0.5, 0.5, 2.0});
  std::uniform_int_distribution<int> val(0, 1000);
  for (int64_t z = 0; z < img.nz(); ++z)
    for (int64_t y = 0; y < img.ny(); ++y)
      for (int64_t x = 0; x < img.nx(); ++x) img(x, y, z) = static_cast<uint16_t>(val(rng) * (60 - z) / 60);
  auto on_disk = scratch("illumination_in", type_ids::volume_u16, img.grid());
  on_disk->write(img, {0, 0, 0});
  for (IlluminationMode mode : {IlluminationMode::fit, IlluminationMode::given}) {
    IlluminationOptions o;
    o.mode = mode;
    o.percentile = 0.05;
    o.slope = -0.01;
    o.intercept = 1.2;
    const IlluminationResult in_core = illumination_z(img, o);
    for (const auto& [b, slab] : std::vector<std::pair<Dims, int64_t>>{{{3, 4, 2}, 1}, {{13, 17, 11}, 4}, {{23, 19, 29}, 29}}) {
      for (const DataObject* input : {static_cast<const DataObject*>(&img), static_cast<const DataObject*>(on_disk.get())}) {
        auto out = scratch("illumination", type_ids::volume_f32, img.grid());
        const IlluminationResult r = illumination_z_blocks(*input, *out, o, b, slab);
        const std::string what = "block " + std::to_string(b[0]) + " slab " + std::to_string(slab);
        EXPECT_EQ(r.slice_statistic, in_core.slice_statistic) << what;
        EXPECT_EQ(r.factor, in_core.factor) << what;
        EXPECT_EQ(r.fit_slope, in_core.fit_slope) << what;
        const VolumeF32 blocked = whole<float>(*out);
        EXPECT_EQ(std::memcmp(blocked.data(), in_core.image.data(), static_cast<size_t>(img.size()) * sizeof(float)), 0) << what;
      }
    }
  }
  // The fitted line must stay positive: the same error as in memory.
  VolumeU16 dark({4, 4, 3});
  for (int64_t x = 0; x < 4; ++x) dark(x, 0, 0) = 1000;  // bright first slice, then black
  auto out = scratch("illumination_dark", type_ids::volume_f32, dark.grid());
  EXPECT_THROW(illumination_z(dark), InputError);
  EXPECT_THROW(illumination_z_blocks(dark, *out, {}, {2, 2, 2}, 1), InputError);
}

}  // namespace
}  // namespace skel::segmentation
