// Segmentation: connected components equal a BFS flood fill (6/18/26), cavities filled and nothing
// else changed, Gaussian equals a brute-force convolution, Otsu splits a bimodal image, thread
// independence, and the mask rule (voxel > 0; float masks are an error naming the port).
#include <gtest/gtest.h>

#include <cmath>
#include <map>
#include <random>
#include <set>

#include "segmentation/segmentation.hpp"
#include "skel/mask.hpp"
#include "skel/run_module.hpp"

using namespace skel;
using namespace skel::segmentation;

namespace {
VolumeU8 random_mask(Dims d, uint64_t seed, double p) {
  std::mt19937_64 rng(seed);
  std::uniform_real_distribution<double> u(0, 1);
  VolumeU8 m(d, 0);
  for (auto& x : m) x = u(rng) < p;
  return m;
}
// BFS labelling for reference.
std::vector<int64_t> bfs_labels(const VolumeU8& m, int conn) {
  std::vector<int64_t> lab(static_cast<size_t>(m.size()), -1);
  int64_t next = 0;
  for (int64_t s = 0; s < m.size(); ++s) {
    if (!m[s] || lab[s] >= 0) continue;
    std::vector<int64_t> st{s};
    lab[s] = next;
    while (!st.empty()) {
      const int64_t i = st.back();
      st.pop_back();
      const int64_t x = i % m.nx(), y = (i / m.nx()) % m.ny(), z = i / (m.nx() * m.ny());
      for (int dz = -1; dz <= 1; ++dz)
        for (int dy = -1; dy <= 1; ++dy)
          for (int dx = -1; dx <= 1; ++dx) {
            const int k = std::abs(dx) + std::abs(dy) + std::abs(dz);
            if (k == 0 || (conn == 6 && k > 1) || (conn == 18 && k > 2)) continue;
            if (!m.grid().contains(x + dx, y + dy, z + dz)) continue;
            const int64_t j = m.index(x + dx, y + dy, z + dz);
            if (m[j] && lab[j] < 0) {
              lab[j] = next;
              st.push_back(j);
            }
          }
    }
    ++next;
  }
  return lab;
}
}  // namespace

TEST(ConnectedComponents, EqualBfsPartitionsFor6_18_26) {
  for (uint64_t seed = 1; seed <= 20; ++seed)
    for (int conn : {6, 18, 26}) {
      VolumeU8 m = random_mask(Dims{13, 11, 9}, seed, 0.3);
      ComponentOptions o;
      o.connectivity = static_cast<Connectivity>(conn);
      auto r = connected_components(m, o);
      auto ref = bfs_labels(m, conn);
      std::map<int64_t, uint32_t> a2b;
      std::map<uint32_t, int64_t> b2a;
      std::map<uint32_t, int64_t> sizes;
      for (int64_t i = 0; i < m.size(); ++i) {
        if (!m[i]) {
          EXPECT_EQ(r.labels[i], 0u);
          continue;
        }
        ASSERT_GT(r.labels[i], 0u);
        auto [it, ins] = a2b.emplace(ref[i], r.labels[i]);
        EXPECT_EQ(it->second, r.labels[i]);
        auto [it2, ins2] = b2a.emplace(r.labels[i], ref[i]);
        EXPECT_EQ(it2->second, ref[i]);
        ++sizes[r.labels[i]];
      }
      EXPECT_EQ(static_cast<int64_t>(a2b.size()), r.count);
      // Labels ordered by size, largest first.
      for (uint32_t l = 2; l <= static_cast<uint32_t>(r.count); ++l) EXPECT_GE(sizes[l - 1], sizes[l]);
      EXPECT_EQ(r.table.rows(), r.count);
    }
}

TEST(CountComponents, EqualsBfsForObjectAndBackgroundWithBorderContacts) {
  for (uint64_t seed = 1; seed <= 20; ++seed)
    for (int conn : {6, 18, 26})
      for (double p : {0.3, 0.6}) {
        const VolumeU8 m = random_mask(Dims{13, 11, 9}, seed, p);
        for (bool background : {false, true}) {
          VolumeU8 sel = m;
          if (background)
            for (auto& v : sel) v = v ? 0 : 1;
          const auto ref = bfs_labels(sel, conn);
          std::set<int64_t> all, border;
          for (int64_t z = 0; z < m.nz(); ++z)
            for (int64_t y = 0; y < m.ny(); ++y)
              for (int64_t x = 0; x < m.nx(); ++x) {
                const int64_t l = ref[static_cast<size_t>(m.index(x, y, z))];
                if (l < 0) continue;
                all.insert(l);
                if (x == 0 || y == 0 || z == 0 || x == m.nx() - 1 || y == m.ny() - 1 || z == m.nz() - 1)
                  border.insert(l);
              }
          for (int threads : {1, 3}) {
            const auto c = count_components(m, conn, background, threads);
            EXPECT_EQ(c.components, static_cast<int64_t>(all.size())) << seed << " " << conn << " " << background;
            EXPECT_EQ(c.touching_border, static_cast<int64_t>(border.size())) << seed << " " << conn << " " << background;
          }
        }
      }
  EXPECT_EQ(count_components(VolumeU8(Dims{4, 4, 4}, 0), 26, false).components, 0);
  EXPECT_EQ(count_components(VolumeU8(Dims{4, 4, 4}, 0), 6, true).touching_border, 1);
  EXPECT_THROW(count_components(VolumeU8(Dims{4, 4, 4}, 0), 8, false), InputError);
}

TEST(ConnectedComponents, KeepLargestAndMinSize) {
  VolumeU8 m(Dims{10, 10, 10}, 0);
  for (int x = 0; x < 5; ++x) m(x, 0, 0) = 1;  // 5 voxels
  for (int x = 0; x < 3; ++x) m(x, 5, 5) = 1;  // 3 voxels
  m(9, 9, 9) = 1;                               // 1 voxel
  ComponentOptions o;
  o.keep_largest = true;
  auto r = connected_components(m, o);
  EXPECT_EQ(r.count, 1);
  EXPECT_EQ(r.mask(4, 0, 0), 1);
  EXPECT_EQ(r.mask(0, 5, 5), 0);
  ComponentOptions o2;
  o2.min_size = 2;
  EXPECT_EQ(connected_components(m, o2).count, 2);
  EXPECT_EQ(connected_components(VolumeU8(Dims{4, 4, 4}, 0)).count, 0);
  // keep_largest removed the 3-voxel component, 60 % of the largest: the warning says so.
  EXPECT_NE(r.warning.find("removed a component of 3 voxels, 60 % of the largest (5 voxels)"), std::string::npos)
      << r.warning;
  EXPECT_NE(r.warning.find("2 components with 4 voxels removed in all by keep_largest"), std::string::npos) << r.warning;
  // min_size removed the 1-voxel one: 20 % of the largest here, so it is named too.
  EXPECT_NE(connected_components(m, o2).warning.find("1 component with 1 voxel removed in all by min_size"),
            std::string::npos);
  ComponentOptions o3;
  o3.min_size = 4;  // the 3-voxel one (60 %) and the 1-voxel one (20 %): the larger is named
  EXPECT_NE(connected_components(m, o3).warning.find("removed a component of 3 voxels, 60 % of the largest (5 voxels) and 1 more"),
            std::string::npos) << connected_components(m, o3).warning;
}

// A network cut in two halves by the threshold (what the 1024³ vessel benchmark did): keep_largest
// keeps one half and warns with its size; min_fraction keeps both halves and removes the noise.
TEST(ConnectedComponents, MinFractionKeepsLargePiecesAndRemovesNoise) {
  VolumeU8 m(Dims{40, 20, 20}, 0);
  for (int x = 0; x < 18; ++x)
    for (int y = 5; y < 9; ++y)
      for (int z = 5; z < 9; ++z) m(x, y, z) = 1;  // 288 voxels
  for (int x = 21; x < 38; ++x)
    for (int y = 5; y < 9; ++y)
      for (int z = 5; z < 9; ++z) m(x, y, z) = 1;  // 272 voxels
  m(2, 15, 15) = 1;                               // noise
  m(30, 15, 15) = m(31, 15, 15) = 1;
  ComponentOptions largest;
  largest.keep_largest = true;
  const auto a = connected_components(m, largest);
  EXPECT_EQ(a.count, 1);
  EXPECT_NE(a.warning.find("removed a component of 272 voxels, 94 % of the largest (288 voxels)"), std::string::npos)
      << a.warning;
  EXPECT_NE(a.warning.find("min_fraction"), std::string::npos) << a.warning;
  ComponentOptions fraction;
  fraction.min_fraction = 0.05;
  const auto b = connected_components(m, fraction);
  EXPECT_EQ(b.count, 2);
  EXPECT_TRUE(b.warning.empty()) << b.warning;
  EXPECT_EQ(b.mask(0, 5, 5), 1);
  EXPECT_EQ(b.mask(37, 8, 8), 1);
  EXPECT_EQ(b.mask(2, 15, 15), 0);
  EXPECT_EQ(b.mask(30, 15, 15), 0);
  // min_fraction 1 keeps the largest only (and ties with it); 0 keeps everything.
  fraction.min_fraction = 1.0;
  EXPECT_EQ(connected_components(m, fraction).count, 1);
  fraction.min_fraction = 0.0;
  EXPECT_EQ(connected_components(m, fraction).count, 4);
}

TEST(FillCavities, FillsEnclosedBackgroundOnly) {
  VolumeU8 m(Dims{9, 9, 9}, 0);
  for (int z = 1; z < 8; ++z)
    for (int y = 1; y < 8; ++y)
      for (int x = 1; x < 8; ++x) m(x, y, z) = (x == 1 || x == 7 || y == 1 || y == 7 || z == 1 || z == 7);
  m(4, 4, 4) = 1;
  int64_t filled = 0;
  VolumeU8 f = fill_cavities(m, &filled);
  EXPECT_EQ(filled, 5 * 5 * 5 - 1);
  for (int64_t i = 0; i < m.size(); ++i) {
    if (m[i]) {
      EXPECT_EQ(f[i], 1);
    }
  }
  EXPECT_EQ(f(0, 0, 0), 0);
  // Open the box: nothing is enclosed any more.
  m(1, 4, 4) = 0;
  fill_cavities(m, &filled);
  EXPECT_EQ(filled, 0);
}

TEST(Gaussian, EqualsBruteForceAndIsThreadIndependent) {
  VolumeF32 v(Dims{12, 10, 8}, 0.0f, {1.0, 2.0, 0.5});
  std::mt19937 rng(3);
  for (auto& x : v) x = static_cast<float>(rng() % 100);
  GaussianOptions o;
  o.sigma = {1.5, 2.0, 1.0};
  o.threads = 1;
  VolumeF32 g = gaussian(v, o);
  o.threads = 3;
  EXPECT_TRUE(g == gaussian(v, o));
  // Brute force: separable product kernel with replicated borders.
  const double s[3] = {1.5 / 1.0, 2.0 / 2.0, 1.0 / 0.5};
  int r[3];
  std::vector<double> k[3];
  for (int a = 0; a < 3; ++a) {
    r[a] = static_cast<int>(std::ceil(3.5 * s[a]));
    double sum = 0;
    for (int i = -r[a]; i <= r[a]; ++i) {
      k[a].push_back(std::exp(-0.5 * i * i / (s[a] * s[a])));
      sum += k[a].back();
    }
    for (auto& x : k[a]) x /= sum;
  }
  auto clampi = [](int64_t x, int64_t n) { return std::clamp<int64_t>(x, 0, n - 1); };
  for (int64_t z = 0; z < 8; z += 3)
    for (int64_t y = 0; y < 10; y += 3)
      for (int64_t x = 0; x < 12; x += 3) {
        double acc = 0;
        for (int dz = -r[2]; dz <= r[2]; ++dz)
          for (int dy = -r[1]; dy <= r[1]; ++dy)
            for (int dx = -r[0]; dx <= r[0]; ++dx)
              acc += k[0][dx + r[0]] * k[1][dy + r[1]] * k[2][dz + r[2]] * v(clampi(x + dx, 12), clampi(y + dy, 10), clampi(z + dz, 8));
        EXPECT_NEAR(g(x, y, z), acc, 1e-3);
      }
}

TEST(Threshold, ObjectVoxelsCountedInParallelForAnyThreadCount) {
  // 9.4 M voxels: three chunks of the parallel count; the count is the mask's sum for 1, 2, 4 threads.
  VolumeF32 v(Dims{300, 250, 125});
  std::mt19937 rng(3);
  std::uniform_real_distribution<float> u(0.0f, 1.0f);
  for (auto& x : v) x = u(rng);
  for (int t : {1, 2, 4}) {
    ThresholdOptions o;
    o.method = ThresholdMethod::manual;
    o.low = 0.25;
    o.high = 0.5;
    o.threads = t;
    const ThresholdResult r = threshold(v, o);
    int64_t brute = 0;
    for (float x : v) brute += x >= 0.25f && x <= 0.5f;
    EXPECT_EQ(r.object_voxels, brute) << t;
    EXPECT_GT(brute, v.size() / 5);
  }
}

TEST(Threshold, OtsuSplitsABimodalImageAndMasksAreCheckedByPort) {
  VolumeF32 v(Dims{20, 20, 2}, 0.0f);
  std::mt19937 rng(1);
  std::normal_distribution<float> lo(10, 1), hi(50, 2);
  for (int64_t i = 0; i < v.size(); ++i) v[i] = i % 3 == 0 ? hi(rng) : lo(rng);
  const double t = otsu_threshold(v);
  EXPECT_GT(t, 15);
  EXPECT_LT(t, 44);
  auto r = run_module("segmentation.threshold", {{"image", std::make_shared<VolumeF32>(v)}}, {{"method", std::string("otsu")}});
  auto m = r.get<VolumeU8>("mask");
  for (int64_t i = 0; i < v.size(); ++i) EXPECT_EQ((*m)[i], i % 3 == 0 ? 1 : 0);
  // Mask rule: integer volumes count "> 0" as object; float volumes are an error naming the port.
  VolumeU32 lab(Dims{3, 3, 3}, 0);
  lab(1, 1, 1) = 7;
  EXPECT_EQ(to_mask(lab, "mask")(1, 1, 1), 1);
  try {
    run_module("segmentation.fill_cavities", {{"mask", std::make_shared<VolumeF32>(v)}});
    FAIL();
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("does not accept volume.f32"), std::string::npos) << e.what();
  }
  EXPECT_THROW(threshold(v, 5, 1), InputError);
}
