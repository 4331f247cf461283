// Segmentation filters and morphology against brute force: median (radius 1 and 2, several types),
// morphology with an exact ball (erode/dilate/open/close), illumination correction (given and fitted),
// Gaussian and connected components for 1, 2 and 4 threads, empty and full volumes, mask rule.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <random>

#include "segmentation/segmentation.hpp"
#include "skel/executor.hpp"
#include "skel/pipeline.hpp"
#include "skel/run_module.hpp"

using namespace skel;
using namespace skel::segmentation;

namespace {
template <class T>
Volume<T> random_volume(Dims d, uint64_t seed, int maxv) {
  std::mt19937_64 rng(seed);
  Volume<T> v(d, T{});
  for (auto& x : v) x = static_cast<T>(rng() % static_cast<uint64_t>(maxv));
  return v;
}
VolumeU8 random_mask(Dims d, uint64_t seed, double p) {
  std::mt19937_64 rng(seed);
  std::uniform_real_distribution<double> u(0, 1);
  VolumeU8 m(d, 0);
  for (auto& x : m) x = u(rng) < p;
  return m;
}
int64_t cl(int64_t i, int64_t n) { return std::clamp<int64_t>(i, 0, n - 1); }

template <class T>
Volume<T> brute_median(const Volume<T>& v, int r) {
  Volume<T> out(v.grid());
  for (int64_t z = 0; z < v.nz(); ++z)
    for (int64_t y = 0; y < v.ny(); ++y)
      for (int64_t x = 0; x < v.nx(); ++x) {
        std::vector<T> vals;
        for (int dz = -r; dz <= r; ++dz)
          for (int dy = -r; dy <= r; ++dy)
            for (int dx = -r; dx <= r; ++dx) vals.push_back(v(cl(x + dx, v.nx()), cl(y + dy, v.ny()), cl(z + dz, v.nz())));
        std::sort(vals.begin(), vals.end());
        out(x, y, z) = vals[vals.size() / 2];
      }
  return out;
}

// Brute-force morphology: outside the volume is background.
VolumeU8 brute_morph(const VolumeU8& m, double r, bool dilate) {
  const int R = static_cast<int>(std::floor(r));
  VolumeU8 out(m.grid(), 0);
  for (int64_t z = 0; z < m.nz(); ++z)
    for (int64_t y = 0; y < m.ny(); ++y)
      for (int64_t x = 0; x < m.nx(); ++x) {
        bool any = false, all = true;
        for (int dz = -R; dz <= R; ++dz)
          for (int dy = -R; dy <= R; ++dy)
            for (int dx = -R; dx <= R; ++dx) {
              if (dx * dx + dy * dy + dz * dz > r * r) continue;
              const uint8_t v = m.at_or(x + dx, y + dy, z + dz, 0);
              any = any || v;
              all = all && v;
            }
        out(x, y, z) = dilate ? any : all;
      }
  return out;
}
}  // namespace

TEST(Median, EqualsBruteForceForRadius1And2AndAnyThreadCount) {
  for (uint64_t seed = 1; seed <= 4; ++seed) {
    const Dims d{static_cast<int64_t>(70 + seed * 13), 7, static_cast<int64_t>(3 + seed)};  // rows longer than one 64-lane block
    auto u8 = random_volume<uint8_t>(d, seed, 256);
    auto f32 = random_volume<float>(d, seed + 10, 1000);
    auto i32 = random_volume<int32_t>(d, seed + 20, 50);
    for (int threads : {1, 2, 4}) {
      MedianOptions o;
      o.threads = threads;
      EXPECT_TRUE(median_as(u8, o) == brute_median(u8, 1)) << seed << " " << threads;
      EXPECT_TRUE(median_as(f32, o) == brute_median(f32, 1)) << seed << " " << threads;
      EXPECT_TRUE(median_as(i32, o) == brute_median(i32, 1)) << seed << " " << threads;
    }
  }
  auto v = random_volume<uint16_t>(Dims{9, 8, 7}, 5, 4000);
  MedianOptions o2;
  o2.radius = 2;
  EXPECT_TRUE(median_as(v, o2) == brute_median(v, 2));
  o2.radius = 0;
  EXPECT_TRUE(median_as(v, o2) == v);
  // Single-voxel and thin volumes (every neighbour replicated).
  auto thin = random_volume<uint8_t>(Dims{1, 1, 5}, 6, 256);
  EXPECT_TRUE(median_as(thin, MedianOptions{}) == brute_median(thin, 1));
  // Module keeps the type.
  auto r = run_module("segmentation.median", {{"image", std::make_shared<VolumeU16>(v)}}, {{"radius", int64_t{2}}});
  o2.radius = 2;
  EXPECT_TRUE(*r.get<VolumeU16>("image") == median_as(v, o2));
}

TEST(Morphology, EqualsBruteForceBallForAllOperations) {
  for (uint64_t seed = 1; seed <= 6; ++seed) {
    VolumeU8 m = random_mask(Dims{11, 9, 10}, seed, seed % 2 ? 0.2 : 0.7);
    for (double r : {0.0, 1.0, 1.5, 2.0, 2.3}) {
      const VolumeU8 dil = brute_morph(m, r, true), ero = brute_morph(m, r, false);
      for (int threads : {1, 2, 4}) {
        MorphologyOptions o;
        o.radius = r;
        o.threads = threads;
        o.op = MorphologyOp::dilate;
        EXPECT_TRUE(morphology(m, o) == dil) << seed << " r=" << r;
        o.op = MorphologyOp::erode;
        EXPECT_TRUE(morphology(m, o) == ero) << seed << " r=" << r;
        o.op = MorphologyOp::open;
        EXPECT_TRUE(morphology(m, o) == brute_morph(ero, r, true)) << seed << " r=" << r;
        o.op = MorphologyOp::close;
        EXPECT_TRUE(morphology(m, o) == brute_morph(dil, r, false)) << seed << " r=" << r;
      }
    }
  }
}

TEST(Morphology, EmptyAndFullVolumesAndMaskRule) {
  const Dims d{8, 7, 6};
  MorphologyOptions o;
  o.radius = 2;
  for (auto op : {MorphologyOp::erode, MorphologyOp::dilate, MorphologyOp::open, MorphologyOp::close}) {
    o.op = op;
    EXPECT_TRUE(morphology(VolumeU8(d, 0), o) == VolumeU8(d, 0));
  }
  o.op = MorphologyOp::dilate;
  EXPECT_TRUE(morphology(VolumeU8(d, 1), o) == VolumeU8(d, 1));
  o.op = MorphologyOp::erode;
  VolumeU8 e = morphology(VolumeU8(d, 1), o);  // voxels farther than 2 from the outside ring survive
  for (int64_t z = 0; z < 6; ++z)
    for (int64_t y = 0; y < 7; ++y)
      for (int64_t x = 0; x < 8; ++x)
        EXPECT_EQ(e(x, y, z), x >= 2 && x <= 5 && y >= 2 && y <= 4 && z >= 2 && z <= 3 ? 1 : 0);
  // Any integer volume: voxel > 0 is object; a float volume is an error naming the port.
  VolumeU16 lab(d, 0);
  lab(3, 3, 3) = 500;
  auto r = run_module("segmentation.morphology", {{"mask", std::make_shared<VolumeU16>(lab)}},
                      {{"operation", std::string("dilate")}, {"radius", 1.0}});
  const auto& out = *r.get<VolumeU8>("mask");
  EXPECT_EQ(out(3, 3, 3), 1);
  EXPECT_EQ(out(4, 3, 3), 1);
  EXPECT_EQ(out(4, 4, 3), 0);
  try {
    run_module("segmentation.morphology", {{"mask", std::make_shared<VolumeF32>(d, 1.0f)}});
    FAIL();
  } catch (const InputError& e2) {
    EXPECT_NE(std::string(e2.what()).find("mask"), std::string::npos) << e2.what();
  }
}

TEST(IlluminationZ, GivenAndFittedFactors) {
  VolumeU16 v(Dims{10, 10, 6}, 0);
  // Slice z: 100 voxels, the brightest 10 at 200 - 20·z, the rest at 5.
  for (int64_t z = 0; z < 6; ++z)
    for (int64_t i = 0; i < 100; ++i) v[z * 100 + i] = static_cast<uint16_t>(i < 10 ? 200 - 20 * z : 5);
  IlluminationOptions o;
  o.mode = segmentation::IlluminationMode::given;
  o.intercept = 1.0;
  o.slope = 0.5;
  auto g = illumination_z(v, o);
  for (int64_t z = 0; z < 6; ++z) {
    EXPECT_DOUBLE_EQ(g.factor[static_cast<size_t>(z)], 1.0 + 0.5 * static_cast<double>(z));
    EXPECT_FLOAT_EQ(g.image(3, 0, z), static_cast<float>(v(3, 0, z) * (1.0 + 0.5 * static_cast<double>(z))));
  }
  IlluminationOptions f;
  f.percentile = 0.1;
  for (int threads : {1, 3}) {
    f.threads = threads;
    auto r = illumination_z(v, f);
    EXPECT_NEAR(r.fit_intercept, 200, 1e-9);
    EXPECT_NEAR(r.fit_slope, -20, 1e-9);
    for (int64_t z = 0; z < 6; ++z) {
      EXPECT_DOUBLE_EQ(r.slice_statistic[static_cast<size_t>(z)], 200.0 - 20.0 * static_cast<double>(z));
      EXPECT_NEAR(r.image(0, 0, z), 200.0, 1e-3);  // the bright voxels become equally bright
    }
  }
  // A line that reaches zero inside the stack cannot be inverted.
  VolumeU16 w(Dims{2, 2, 12}, 0);
  for (int64_t z = 0; z < 12; ++z)
    for (int64_t i = 0; i < 4; ++i) w[z * 4 + i] = static_cast<uint16_t>(std::max<int64_t>(0, 100 - 20 * z));
  EXPECT_THROW(illumination_z(w, IlluminationOptions{}), InputError);
}

TEST(Gaussian, IdenticalFor1_2_4Threads) {
  auto v = random_volume<uint8_t>(Dims{37, 29, 23}, 9, 256);
  GaussianOptions o;
  o.sigma = {2.0, 1.0, 1.5};
  o.threads = 1;
  const VolumeF32 a = gaussian(v, o);
  for (int t : {2, 4}) {
    o.threads = t;
    EXPECT_TRUE(gaussian(v, o) == a);
  }
  // A constant image stays constant (normalised kernels, replicated borders).
  o.threads = 2;
  VolumeF32 c = gaussian(VolumeF32(Dims{9, 8, 7}, 3.0f), o);
  for (float x : c) EXPECT_NEAR(x, 3.0f, 1e-5);
}

TEST(Gaussian, InPlaceInAPipelineGivesTheSameBytesAsOutOfPlace) {
  // The phantom's float image has one reader, the Gaussian: a headless run hands it over and the
  // image is smoothed in its own buffer; the GUI (keep_outputs) smooths out of place. Same bytes, and
  // the same as gaussian() on the phantom's image.
  Pipeline p = Pipeline::parse(R"(skelflow: 1
nodes:
  phantom: {module: synthetic.vessel_tree, params: {size: [40, 36, 28], seed: 3, roots: 2, noise: 0.1}}
  smooth: {module: segmentation.gaussian, inputs: {image: phantom.image}, params: {sigma: [1.2, 0.7, 0.9]}}
)");
  for (int threads : {1, 2}) {
    const float* phantom_voxels = nullptr;
    std::shared_ptr<const VolumeF32> headless;
    ExecOptions o;
    o.threads = threads;
    o.on_outputs = [&](const std::string& node, const std::map<std::string, DataPtr>& out) {
      auto v = std::dynamic_pointer_cast<const VolumeF32>(out.at("image"));
      if (node == "phantom") phantom_voxels = v->data();  // its address only: a reference keeps it
      else headless = v;
    };
    Executor ex;
    ASSERT_TRUE(ex.run(p, o).ok);
    ASSERT_NE(headless, nullptr);
    EXPECT_EQ(headless->data(), phantom_voxels);  // written in place
    Executor gui;
    ExecOptions keep;
    keep.threads = threads;
    keep.keep_outputs = true;
    ASSERT_TRUE(gui.run(p, keep).ok);
    auto image = std::dynamic_pointer_cast<const VolumeF32>(gui.output(p, "phantom", "image"));
    auto smooth = std::dynamic_pointer_cast<const VolumeF32>(gui.output(p, "smooth", "image"));
    ASSERT_NE(image, nullptr);
    ASSERT_NE(smooth, nullptr);
    EXPECT_NE(smooth->data(), image->data());
    EXPECT_TRUE(*smooth == *headless);
    GaussianOptions g;
    g.sigma = {1.2, 0.7, 0.9};
    g.threads = threads;
    EXPECT_TRUE(gaussian(*image, g) == *headless);
    EXPECT_FALSE(*image == *headless);  // it did smooth
  }
}

TEST(ConnectedComponents, InPlaceAndWithoutUnreadLabelsInAPipeline) {
  // `largest` is the last reader of the phantom's mask (four balls of 167-470 voxels) and nobody reads
  // its labels: a headless run writes the kept mask into the phantom's buffer and makes no label
  // volume; the GUI run (everything kept) and the function give the same mask and table.
  Pipeline p = Pipeline::parse(R"(skelflow: 1
nodes:
  seg: {module: synthetic.network, params: {size: [48, 40, 32], shape: spheres, seed: 5}}
  largest: {module: segmentation.connected_components, inputs: {mask: seg.mask}, params: {connectivity: 26, min_size: 200}}
  distance: {module: distance.euclidean, inputs: {mask: largest.mask}}
)");
  const uint8_t* seg_voxels = nullptr;
  std::map<std::string, DataPtr> headless;
  ExecOptions o;
  o.threads = 2;
  o.on_outputs = [&](const std::string& node, const std::map<std::string, DataPtr>& out) {
    if (node == "seg") seg_voxels = std::dynamic_pointer_cast<const VolumeU8>(out.at("mask"))->data();
    if (node == "largest") headless = out;
  };
  Executor ex;
  ASSERT_TRUE(ex.run(p, o).ok);
  EXPECT_FALSE(headless.contains("labels"));
  auto mask = std::dynamic_pointer_cast<const VolumeU8>(headless.at("mask"));
  ASSERT_NE(mask, nullptr);
  EXPECT_EQ(mask->data(), seg_voxels);  // written into the thresholded mask
  Executor gui;
  ExecOptions keep;
  keep.threads = 2;
  keep.keep_outputs = true;
  ASSERT_TRUE(gui.run(p, keep).ok);
  auto seg = std::dynamic_pointer_cast<const VolumeU8>(gui.output(p, "seg", "mask"));
  auto kept = std::dynamic_pointer_cast<const VolumeU8>(gui.output(p, "largest", "mask"));
  ASSERT_NE(seg, nullptr);
  ASSERT_NE(kept, nullptr);
  EXPECT_NE(gui.output(p, "largest", "labels"), nullptr);
  EXPECT_TRUE(*kept == *mask);
  ComponentOptions c;
  c.min_size = 200;
  const auto ref = connected_components(*seg, c);
  EXPECT_TRUE(ref.mask == *mask);
  EXPECT_EQ(ref.count, 2);
  EXPECT_FALSE(*seg == *mask);  // two balls removed: the test does test something
  auto table = std::dynamic_pointer_cast<const Table>(headless.at("table"));
  ASSERT_NE(table, nullptr);
  EXPECT_EQ(table->rows(), ref.table.rows());
  // The function forms: in place and without labels, the same mask, table and count.
  VolumeU8 copy = *seg;
  c.labels = false;
  const auto in_place = connected_components_in_place(copy, c);
  EXPECT_TRUE(copy == ref.mask);
  EXPECT_EQ(in_place.labels.size(), 0);
  EXPECT_EQ(in_place.mask.size(), 0);
  EXPECT_EQ(in_place.count, ref.count);
  EXPECT_EQ(in_place.table.rows(), ref.table.rows());
}

TEST(ConnectedComponents, IdenticalFor1_2_4ThreadsAndEmptyFullVolumes) {
  for (int conn : {6, 18, 26}) {
    VolumeU8 m = random_mask(Dims{41, 37, 53}, static_cast<uint64_t>(conn), 0.3);
    ComponentOptions o;
    o.connectivity = static_cast<Connectivity>(conn);
    o.threads = 1;
    const auto a = connected_components(m, o);
    for (int t : {2, 4}) {
      o.threads = t;
      const auto b = connected_components(m, o);
      EXPECT_TRUE(a.labels == b.labels);
      EXPECT_EQ(a.count, b.count);
      EXPECT_EQ(a.table.rows(), b.table.rows());
    }
    // Ties in size keep the raster order of the first voxel.
    std::vector<int64_t> first(static_cast<size_t>(a.count) + 1, -1), size(static_cast<size_t>(a.count) + 1, 0);
    for (int64_t i = 0; i < m.size(); ++i) {
      const uint32_t l = a.labels[i];
      if (!l) continue;
      if (first[l] < 0) first[l] = i;
      ++size[l];
    }
    for (size_t l = 2; l < first.size(); ++l) {
      EXPECT_GE(size[l - 1], size[l]);
      if (size[l - 1] == size[l]) {
        EXPECT_LT(first[l - 1], first[l]);
      }
    }
  }
  const Dims d{6, 5, 4};
  auto e = connected_components(VolumeU8(d, 0));
  EXPECT_EQ(e.count, 0);
  EXPECT_EQ(e.table.rows(), 0);
  EXPECT_TRUE(e.labels == VolumeU32(d, 0));
  auto f = connected_components(VolumeU8(d, 1));
  EXPECT_EQ(f.count, 1);
  EXPECT_TRUE(f.labels == VolumeU32(d, 1));
  // Module: a uint16 volume counts "> 0" as object; a float volume is an error naming the port.
  VolumeU16 lab(d, 0);
  lab(1, 1, 1) = 300;
  lab(4, 3, 2) = 2;
  auto r = run_module("segmentation.connected_components", {{"mask", std::make_shared<VolumeU16>(lab)}},
                      {{"connectivity", int64_t{6}}});
  EXPECT_EQ(r.get<Table>("table")->rows(), 2);
  try {
    run_module("segmentation.connected_components", {{"mask", std::make_shared<VolumeF32>(d, 1.0f)}});
    FAIL();
  } catch (const InputError& err) {
    EXPECT_NE(std::string(err.what()).find("mask"), std::string::npos) << err.what();
  }
}

TEST(FillCavities, NoEnclosedBackgroundOnRandomMasksAndNothingElseChanges) {
  for (uint64_t seed = 1; seed <= 10; ++seed) {
    VolumeU8 m = random_mask(Dims{12, 10, 11}, seed, 0.55);
    VolumeU8 f = fill_cavities(m);
    // Every background component (6-connected) of the result touches the border.
    VolumeU8 bg(m.grid(), 0);
    for (int64_t i = 0; i < m.size(); ++i) bg[i] = f[i] ? 0 : 1;
    ComponentOptions o;
    o.connectivity = Connectivity::c6;
    auto c = connected_components(bg, o);
    const auto* x0 = &c.table.ints("bbox_min_x");
    const auto* y0 = &c.table.ints("bbox_min_y");
    const auto* z0 = &c.table.ints("bbox_min_z");
    const auto* x1 = &c.table.ints("bbox_max_x");
    const auto* y1 = &c.table.ints("bbox_max_y");
    const auto* z1 = &c.table.ints("bbox_max_z");
    for (int64_t k = 0; k < c.count; ++k) {
      const auto s = static_cast<size_t>(k);
      EXPECT_TRUE((*x0)[s] == 0 || (*y0)[s] == 0 || (*z0)[s] == 0 || (*x1)[s] == 11 || (*y1)[s] == 9 || (*z1)[s] == 10);
    }
    // Object stays object; a background voxel of the input stays background iff it is in a border-
    // touching background component of the input.
    VolumeU8 bgin(m.grid(), 0);
    for (int64_t i = 0; i < m.size(); ++i) bgin[i] = m[i] ? 0 : 1;
    auto ci = connected_components(bgin, o);
    std::vector<char> touches(static_cast<size_t>(ci.count) + 1, 0);
    for (int64_t z = 0; z < 11; ++z)
      for (int64_t y = 0; y < 10; ++y)
        for (int64_t x = 0; x < 12; ++x)
          if (x == 0 || y == 0 || z == 0 || x == 11 || y == 9 || z == 10) touches[ci.labels(x, y, z)] = 1;
    for (int64_t i = 0; i < m.size(); ++i) {
      if (m[i]) EXPECT_EQ(f[i], 1);
      else EXPECT_EQ(f[i], touches[ci.labels[i]] ? 0 : 1);
    }
  }
  EXPECT_TRUE(fill_cavities(VolumeU8(Dims{4, 4, 4}, 0)) == VolumeU8(Dims{4, 4, 4}, 0));
  EXPECT_TRUE(fill_cavities(VolumeU8(Dims{4, 4, 4}, 1)) == VolumeU8(Dims{4, 4, 4}, 1));
}
