// Segmentation, completing issue 3's must-show list: Otsu against an exhaustive search (and against the
// "> threshold" rule the module applies), every segmentation function and module identical for 1, 2
// and 4 threads on volumes large enough to be split, and defined outputs for empty, constant and
// all-object inputs.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <limits>
#include <map>
#include <random>

#include "segmentation/segmentation.hpp"
#include "skel/run_module.hpp"

using namespace skel;
using namespace skel::segmentation;

namespace {

template <class T>
Volume<T> random_volume(Dims d, uint64_t seed, double lo, double hi) {
  std::mt19937_64 rng(seed);
  std::uniform_real_distribution<double> u(lo, hi);
  Volume<T> v(d, T{});
  for (auto& x : v) x = static_cast<T>(u(rng));
  return v;
}

// Smooth-ish random mask: a blob field thresholded, so that components span many rows and slabs.
VolumeU8 blob_mask(Dims d, uint64_t seed, double p) {
  std::mt19937_64 rng(seed);
  std::uniform_real_distribution<double> u(0, 1);
  VolumeU8 m(d, 0);
  for (int64_t z = 0; z < d[2]; ++z)
    for (int64_t y = 0; y < d[1]; ++y)
      for (int64_t x = 0; x < d[0]; ++x) {
        const double f = 0.5 + 0.25 * std::sin(0.4 * static_cast<double>(x) + static_cast<double>(seed)) *
                                   std::cos(0.3 * static_cast<double>(y)) +
                         0.25 * std::sin(0.35 * static_cast<double>(z)) + 0.3 * (u(rng) - 0.5);
        m(x, y, z) = f > 1.0 - p ? 1 : 0;
      }
  return m;
}

// Otsu by exhaustive search over the 256 exact uint8 bins: background = values <= t, maximising the
// between-class variance w0·w1·(m0 − m1)²; returns the first maximising t.
int brute_otsu_u8(const VolumeU8& v) {
  std::vector<double> h(256, 0);
  for (uint8_t x : v) h[x] += 1;
  int lo = 255, hi = 0;
  for (int b = 0; b < 256; ++b)
    if (h[b] > 0) {
      lo = std::min(lo, b);
      hi = std::max(hi, b);
    }
  double best = -1;
  int best_t = lo;
  for (int t = lo; t < hi; ++t) {
    double w0 = 0, s0 = 0, w1 = 0, s1 = 0;
    for (int b = 0; b < 256; ++b) (b <= t ? w0 : w1) += h[b], (b <= t ? s0 : s1) += b * h[b];
    if (w0 == 0 || w1 == 0) continue;
    const double d = s0 / w0 - s1 / w1;
    const double between = w0 * w1 * d * d;
    if (between > best * (1 + 1e-12)) {
      best = between;
      best_t = t;
    }
  }
  return best_t;
}

}  // namespace

TEST(Otsu, Uint8EqualsExhaustiveSearchAndModuleMaskIsAboveIt) {
  for (uint64_t seed = 1; seed <= 8; ++seed) {
    // Two overlapping modes that cover every grey value, so the optimum is a single bin (no plateau).
    std::mt19937_64 rng(seed);
    std::normal_distribution<double> a(60.0 + 5.0 * static_cast<double>(seed), 25), b(170, 30);
    VolumeU8 v(Dims{31, 29, 17}, 0);
    for (auto& x : v) x = static_cast<uint8_t>(std::clamp(std::lround(rng() % 3 ? a(rng) : b(rng)), 0L, 255L));
    const int t = brute_otsu_u8(v);
    const double ours = otsu_threshold(v, 1);
    // Same split: every value <= t is below the threshold, every value > t above it.
    EXPECT_GE(ours, static_cast<double>(t)) << seed;
    EXPECT_LT(ours, static_cast<double>(t + 1)) << seed;
    auto r = run_module("segmentation.threshold", {{"image", std::make_shared<VolumeU8>(v)}},
                        {{"method", std::string("otsu")}});
    const auto& m = *r.get<VolumeU8>("mask");
    for (int64_t i = 0; i < v.size(); ++i) ASSERT_EQ(m[i], v[i] > t ? 1 : 0) << "seed " << seed << " value " << int(v[i]) << " t " << t;
  }
}

TEST(Otsu, IdenticalFor1_2_4ThreadsOnEveryType) {
  const Dims d{97, 83, 41};  // 330k voxels: split into different chunks for every thread count
  auto f32 = random_volume<float>(d, 1, -3.0, 17.0);
  auto u16 = random_volume<uint16_t>(d, 2, 0, 4000);
  auto u8 = random_volume<uint8_t>(d, 3, 0, 256);
  auto i32 = random_volume<int32_t>(d, 4, -500, 500);
  for (const DataObject* v : std::initializer_list<const DataObject*>{&f32, &u16, &u8, &i32}) {
    const double t1 = otsu_threshold(*v, 1);
    const VolumeU8 m1 = threshold(*v, t1, 1e300, 1);
    for (int t : {2, 4}) {
      EXPECT_EQ(t1, otsu_threshold(*v, t)) << v->type_id();
      EXPECT_TRUE(m1 == threshold(*v, t1, 1e300, t)) << v->type_id();
    }
  }
}

TEST(Otsu, ConstantNaNAndEmptyImagesAreDefined) {
  // Constant image: the threshold is the value; the module's mask (value > threshold) is empty.
  VolumeF32 c(Dims{5, 4, 3}, 2.5f);
  EXPECT_EQ(otsu_threshold(c), 2.5);
  auto r = run_module("segmentation.threshold", {{"image", std::make_shared<VolumeF32>(c)}},
                      {{"method", std::string("otsu")}});
  EXPECT_TRUE(*r.get<VolumeU8>("mask") == VolumeU8(c.grid(), 0));
  // NaN voxels are ignored by Otsu and are background in the mask.
  VolumeF32 n(Dims{6, 1, 1}, 0.0f);
  const float vals[6] = {1, 1, 1, 9, 9, std::numeric_limits<float>::quiet_NaN()};
  for (int i = 0; i < 6; ++i) n[i] = vals[i];
  const double t = otsu_threshold(n);
  EXPECT_GT(t, 1.0);
  EXPECT_LT(t, 9.0);
  r = run_module("segmentation.threshold", {{"image", std::make_shared<VolumeF32>(n)}}, {{"method", std::string("otsu")}});
  const auto& m = *r.get<VolumeU8>("mask");
  for (int i = 0; i < 6; ++i) EXPECT_EQ(m[i], i == 3 || i == 4 ? 1 : 0);
  // A volume without voxels has no threshold.
  EXPECT_THROW(otsu_threshold(VolumeF32(Dims{0, 4, 4}, 0.0f)), InputError);
}

TEST(Threads, EverySegmentationFunctionIdenticalFor1_2_4) {
  const Dims d{67, 53, 45};
  const VolumeU8 mask = blob_mask(d, 7, 0.45);
  auto img16 = random_volume<uint16_t>(d, 8, 0, 3000);
  auto imgf = random_volume<float>(d, 9, 0, 1);
  imgf.set_spacing({0.7, 1.0, 1.6});
  for (int t : {1, 2, 4}) {
    SCOPED_TRACE(t);
    // connected components with min_size and keep_largest: labels, kept mask and table
    for (int conn : {6, 26}) {
      ComponentOptions o;
      o.connectivity = static_cast<Connectivity>(conn);
      o.min_size = 20;
      o.threads = 1;
      const auto a = connected_components(mask, o);
      o.threads = t;
      const auto b = connected_components(mask, o);
      EXPECT_TRUE(a.labels == b.labels);
      EXPECT_TRUE(a.mask == b.mask);
      EXPECT_EQ(a.table.to_csv(), b.table.to_csv());
      o.keep_largest = true;
      o.threads = 1;
      const auto c = connected_components(mask, o);
      o.threads = t;
      EXPECT_TRUE(c.mask == connected_components(mask, o).mask);
    }
    // median radius 1 (float, anisotropic grid) and radius 2 (nth_element path)
    MedianOptions mo;
    mo.threads = 1;
    const VolumeF32 med1 = median_as(imgf, mo);
    mo.radius = 2;
    const VolumeU16 med2 = median_as(img16, mo);
    mo.threads = t;
    EXPECT_TRUE(median_as(img16, mo) == med2);
    mo.radius = 1;
    EXPECT_TRUE(median_as(imgf, mo) == med1);
    // Gaussian of a float image on an anisotropic grid, one axis skipped
    GaussianOptions go;
    go.sigma = {1.4, 0.0, 2.2};
    go.threads = 1;
    const VolumeF32 g1 = gaussian(imgf, go);
    go.threads = t;
    EXPECT_TRUE(gaussian(imgf, go) == g1);
    // illumination_z, fitted and given
    IlluminationOptions io;
    io.percentile = 0.05;
    io.threads = 1;
    const auto i1 = illumination_z(img16, io);
    io.threads = t;
    const auto it = illumination_z(img16, io);
    EXPECT_TRUE(it.image == i1.image);
    EXPECT_EQ(it.factor, i1.factor);
    EXPECT_EQ(it.slice_statistic, i1.slice_statistic);
    io.mode = segmentation::IlluminationMode::given;
    io.slope = 0.03;
    io.intercept = 0.8;
    io.threads = 1;
    const auto j1 = illumination_z(imgf, io);
    io.threads = t;
    EXPECT_TRUE(illumination_z(imgf, io).image == j1.image);
    // morphology, every operation with a non-integer radius
    for (auto op : {MorphologyOp::erode, MorphologyOp::dilate, MorphologyOp::open, MorphologyOp::close}) {
      MorphologyOptions m;
      m.op = op;
      m.radius = 2.5;
      m.threads = 1;
      const VolumeU8 r1 = morphology(mask, m);
      m.threads = t;
      EXPECT_TRUE(morphology(mask, m) == r1) << static_cast<int>(op);
    }
  }
}

TEST(Threads, EverySegmentationModuleIdenticalFor1And4) {
  const Dims d{48, 40, 36};
  auto mask = std::make_shared<VolumeU8>(blob_mask(d, 3, 0.5));
  auto img = std::make_shared<VolumeU16>(random_volume<uint16_t>(d, 5, 0, 1000));
  struct Case {
    std::string module;
    DataPtr input;
    std::string in_port;
    ParamMap params;
    std::vector<std::string> volume_outputs;
  };
  const std::vector<Case> cases = {
      {"segmentation.threshold", img, "image", {{"method", std::string("otsu")}}, {"mask"}},
      {"segmentation.gaussian", img, "image", {{"sigma", std::vector<double>{1.5, 1.0, 2.0}}}, {"image"}},
      {"segmentation.median", img, "image", {{"radius", int64_t{1}}}, {"image"}},
      {"segmentation.illumination_z", img, "image", {}, {"image"}},
      {"segmentation.connected_components", mask, "mask", {{"connectivity", int64_t{18}}}, {"labels", "mask"}},
      {"segmentation.fill_cavities", mask, "mask", {}, {"mask"}},
      {"segmentation.morphology", mask, "mask", {{"operation", std::string("close")}, {"radius", 2.0}}, {"mask"}},
  };
  for (const auto& c : cases) {
    auto a = run_module(c.module, {{c.in_port, c.input}}, c.params, {.threads = 1});
    auto b = run_module(c.module, {{c.in_port, c.input}}, c.params, {.threads = 4});
    for (const auto& port : c.volume_outputs) {
      auto x = a.data(port);
      auto y = b.data(port);
      ASSERT_TRUE(x && y) << c.module << " " << port;
      EXPECT_EQ(x->type_id(), y->type_id());
      visit_volume(*x, port, [&](const auto& vx) {
        using V = std::decay_t<decltype(vx)>;
        const auto* vy = dynamic_cast<const V*>(y.get());
        ASSERT_NE(vy, nullptr);
        EXPECT_TRUE(vx == *vy) << c.module << " " << port;
      });
    }
  }
}

TEST(EdgeCases, EmptyConstantAndAllObjectInputs) {
  const Dims d{9, 8, 7};
  // Filters keep a constant image constant (replicated borders, normalised kernels).
  VolumeU8 full(d, 1), empty(d, 0);
  EXPECT_TRUE(median_as(full, MedianOptions{}) == full);
  EXPECT_TRUE(median_as(empty, MedianOptions{}) == empty);
  MedianOptions m2;
  m2.radius = 3;
  EXPECT_TRUE(median_as(VolumeU16(d, 77), m2) == VolumeU16(d, 77));
  EXPECT_TRUE(gaussian(empty, GaussianOptions{}) == VolumeF32(d, 0.0f));
  for (float x : gaussian(full, GaussianOptions{})) EXPECT_NEAR(x, 1.0f, 1e-6f);
  // Connected components: min_size above every component leaves nothing; the full volume is one
  // component whose table row covers the whole box.
  ComponentOptions co;
  co.min_size = 10000;
  auto none = connected_components(full, co);
  EXPECT_EQ(none.count, 0);
  EXPECT_TRUE(none.mask == empty);
  EXPECT_TRUE(none.labels == VolumeU32(d, 0));
  auto one = connected_components(full);
  ASSERT_EQ(one.count, 1);
  EXPECT_EQ(one.table.ints("bbox_max_x")[0], 8);
  EXPECT_EQ(one.table.ints("bbox_max_y")[0], 7);
  EXPECT_EQ(one.table.ints("bbox_max_z")[0], 6);
  // Module outputs on an empty mask: defined and documented (warnings, no error).
  auto e = std::make_shared<VolumeU8>(empty);
  auto r = run_module("segmentation.connected_components", {{"mask", e}});
  EXPECT_EQ(r.get<Table>("table")->rows(), 0);
  EXPECT_TRUE(*r.get<VolumeU32>("labels") == VolumeU32(d, 0));
  EXPECT_TRUE(*run_module("segmentation.fill_cavities", {{"mask", e}}).get<VolumeU8>("mask") == empty);
  auto f = std::make_shared<VolumeU8>(full);
  EXPECT_TRUE(*run_module("segmentation.fill_cavities", {{"mask", f}}).get<VolumeU8>("mask") == full);
  EXPECT_TRUE(*run_module("segmentation.morphology", {{"mask", e}}, {{"operation", std::string("close")}, {"radius", 2.0}})
                   .get<VolumeU8>("mask") == empty);
  // Illumination: a stack without signal cannot be fitted (the fitted brightness is 0): an error; the
  // given mode just scales.
  EXPECT_THROW(illumination_z(VolumeU16(d, 0), IlluminationOptions{}), InputError);
  IlluminationOptions given;
  given.mode = segmentation::IlluminationMode::given;
  given.intercept = 2.0;
  EXPECT_TRUE(illumination_z(VolumeU16(d, 0), given).image == VolumeF32(d, 0.0f));
}
