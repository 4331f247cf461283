// thinning.lee94: identical to scikit-image skeletonize_3d (committed references made by
// data/make_lee94_references.py, Fiji's own skeleton of scikit-image's blobs volume, a literal port of
// the scikit-image code, and - when /usr/bin/python3 has scikit-image - a live comparison).
#include <gtest/gtest.h>

#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <memory>
#include <random>
#include <sstream>
#include <string>

#include "lee94_port.hpp"
#include "shapes.hpp"
#include "skel/run_module.hpp"
#include "skel/table.hpp"
#include "thinning/lee94.hpp"
#include "thinning/names.hpp"

using namespace skel::thinning;

namespace skel {
namespace {

struct Case {
  VolumeU8 mask, skeleton;
};

// data/lee94/<name>.bin: "nx ny nz\n", then mask and skeleton as little-endian packed bits (x fastest).
Case read_case(const std::string& name) {
  const std::string path = std::string(SKEL_SOURCE_DIR) + "/tests/modules/thinning/data/lee94/" + name + ".bin";
  std::ifstream f(path, std::ios::binary);
  if (!f) throw Error("cannot read " + path);
  std::string header;
  std::getline(f, header);
  std::istringstream hs(header);
  int64_t nx = 0, ny = 0, nz = 0;
  hs >> nx >> ny >> nz;
  Case c{VolumeU8(Dims{nx, ny, nz}, 0), VolumeU8(Dims{nx, ny, nz}, 0)};
  const int64_t n = nx * ny * nz, bytes = (n + 7) / 8;
  for (VolumeU8* v : {&c.mask, &c.skeleton}) {
    std::string bits(static_cast<size_t>(bytes), '\0');
    f.read(bits.data(), bytes);
    if (f.gcount() != bytes) throw Error(path + ": truncated");
    for (int64_t i = 0; i < n; ++i) (*v)[i] = (static_cast<uint8_t>(bits[static_cast<size_t>(i / 8)]) >> (i % 8)) & 1u;
  }
  return c;
}

int64_t count(const VolumeU8& v) {
  int64_t s = 0;
  for (uint8_t x : v) s += x != 0;
  return s;
}

const char* kCases[] = {"fiji_blobs", "blobs_a", "blobs_b", "blobs_dense", "noise", "tubes",
                        "torus", "plates", "cube", "hollow_cube", "corner_cube", "full",
                        "empty", "thin_walk", "thin_plane", "tiny", "slice", "one_row"};

TEST(Lee94, IdenticalToScikitImageReferences) {
  for (const char* name : kCases) {
    const Case c = read_case(name);
    for (int threads : {1, 3}) {
      Lee94Options o;
      o.threads = threads;
      const Lee94Result r = thin_lee94(c.mask, o);
      EXPECT_TRUE(r.skeleton == c.skeleton) << name << " threads " << threads << ": " << count(r.skeleton)
                                            << " voxels, skimage " << count(c.skeleton);
      EXPECT_EQ(r.stats.object_voxels, count(c.mask)) << name;
      EXPECT_EQ(r.stats.skeleton_voxels, count(c.skeleton)) << name;
      EXPECT_EQ(r.stats.removed, r.stats.object_voxels - r.stats.skeleton_voxels) << name;
      EXPECT_EQ(r.stats.candidates, r.stats.removed + r.stats.rejected) << name;
    }
  }
}

TEST(Lee94, FijiSkeletonOfScikitImageBlobs) {
  // scikit-image's test_3d_vs_fiji: binary_blobs(32, 0.05, n_dim=3, seed=1234)[:-2] and the skeleton
  // Fiji's Skeletonize3D computed for it (4003 voxels).
  const Case c = read_case("fiji_blobs");
  ASSERT_EQ(c.mask.dims(), (Dims{32, 32, 30}));
  EXPECT_EQ(count(c.mask), 15375);
  EXPECT_EQ(count(c.skeleton), 4003);
  EXPECT_TRUE(thin_lee94(c.mask).skeleton == c.skeleton);
}

TEST(Lee94, LosesSmallComponentsAsScikitImageDoes) {
  // The documented difference from thinning.doht: a solid cube vanishes (the last voxel is deleted by
  // the re-check, which only tests the connectivity of its neighbours), and so does a flat plate.
  for (const char* name : {"cube", "full", "thin_plane"}) {
    const Case c = read_case(name);
    const Lee94Result r = thin_lee94(c.mask);
    EXPECT_EQ(count(c.skeleton), 0) << name;
    EXPECT_EQ(r.stats.skeleton_voxels, 0) << name;
    EXPECT_EQ(r.stats.vanished_components, 1) << name;
  }
  // Isolated voxels and pairs are never candidates (not Euler invariant / end points): they stay.
  const Case tiny = read_case("tiny");
  const Lee94Result r = thin_lee94(tiny.mask);
  EXPECT_EQ(r.stats.vanished_components, 0);
  EXPECT_TRUE(r.skeleton == tiny.mask);
}

TEST(Lee94, MatchesLiteralPortOfScikitImage) {
  // Random volumes of several shapes, densities and sizes (including flat and one-slice ones):
  // the fast implementation (row flags, table tests, threads) against the literal port.
  std::mt19937 rng(11);
  int tested = 0;
  for (int round = 0; round < 24; ++round) {
    const int64_t nx = 1 + static_cast<int64_t>(rng() % 23), ny = 1 + static_cast<int64_t>(rng() % 19),
                  nz = round % 6 == 0 ? 1 : 1 + static_cast<int64_t>(rng() % 17);
    VolumeU8 m(Dims{nx, ny, nz}, 0);
    if (round % 3 == 0) {
      const double p = 0.2 + 0.06 * (round % 10);
      std::uniform_real_distribution<double> u(0, 1);
      for (auto& v : m) v = u(rng) < p;
    } else {
      const VolumeU8 b = test::random_blobs(24, static_cast<uint32_t>(round), 0.45 + 0.01 * (round % 5), 1 + round % 3);
      for (int64_t z = 0; z < nz; ++z)
        for (int64_t y = 0; y < ny; ++y)
          for (int64_t x = 0; x < nx; ++x) m(x, y, z) = static_cast<uint8_t>(b(x, y, z) ? 1 + round : 0);
    }
    const VolumeU8 ref = test::lee94_port::skeletonize_3d(m);
    for (int threads : {1, 2, 5}) {
      Lee94Options o;
      o.threads = threads;
      EXPECT_TRUE(thin_lee94(m, o).skeleton == ref) << "round " << round << " dims " << nx << " " << ny << " "
                                                    << nz << " threads " << threads;
    }
    ++tested;
  }
  EXPECT_EQ(tested, 24);
  // Rows longer than one 64-bit word of the packed image (x crossing word boundaries at 63/64, 127/128).
  for (int64_t nx : {62, 63, 64, 65, 127, 130, 200}) {
    const VolumeU8 b = test::random_blobs(48, static_cast<uint32_t>(nx), 0.47, 2);
    VolumeU8 m(Dims{nx, 14, 11}, 0);
    for (int64_t z = 0; z < 11; ++z)
      for (int64_t y = 0; y < 14; ++y)
        for (int64_t x = 0; x < nx; ++x) m(x, y, z) = b((x * 7) % 48, y + 3, z + 5);  // x scrambled: no period
    for (int64_t y = 0; y < 14; y += 5) m(nx - 1, y, 5) = 1;  // voxels on the last column
    const VolumeU8 ref = test::lee94_port::skeletonize_3d(m);
    EXPECT_GT(count(ref), 0) << nx;
    for (int threads : {1, 3}) {
      Lee94Options o;
      o.threads = threads;
      EXPECT_TRUE(thin_lee94(m, o).skeleton == ref) << "nx " << nx << " threads " << threads;
    }
  }
  // Larger: blobs 40^3 at two densities.
  for (double t : {0.46, 0.5}) {
    const VolumeU8 m = test::random_blobs(40, 9, t, 2);
    const VolumeU8 ref = test::lee94_port::skeletonize_3d(m);
    EXPECT_TRUE(thin_lee94(m).skeleton == ref) << t;
    EXPECT_GT(count(ref), 0);
  }
}

TEST(Lee94, LocalTestsMatchTheLiteralPort) {
  // Euler invariance (table look-ups) and the component test (dilations) against skimage's octant
  // code on random neighbourhoods of every density and on all single- and two-voxel ones.
  const std::vector<int> lut = test::lee94_port::euler_lut();
  auto check = [&](uint32_t cube) {
    cube |= 1u << 13;
    uint8_t n[27];
    for (int k = 0; k < 27; ++k) {  // skimage numbering k = 9 dz' + 3 dx' + dy' (dx' = dx + 1, ...)
      const int bit = (k / 3) % 3 + 3 * (k % 3) + 9 * (k / 9);
      n[k] = (cube >> bit) & 1u;
    }
    EXPECT_EQ(lee94_detail::euler_invariant(cube), test::lee94_port::is_Euler_invariant(n, lut.data())) << cube;
    EXPECT_EQ(lee94_detail::at_most_one_component(cube), test::lee94_port::is_simple_point(n)) << cube;
  };
  std::mt19937 rng(3);
  for (int i = 0; i < 200000; ++i) {
    const uint32_t density = rng() % 32;
    uint32_t cube = 0;
    for (int b = 0; b < 27; ++b)
      if (rng() % 32 < density) cube |= 1u << b;
    check(cube);
  }
  for (int a = 0; a < 27; ++a)
    for (int b = 0; b < 27; ++b) check((1u << a) | (1u << b));
}

TEST(Lee94, ModuleMatchesLibraryAndWarnsAboutVanishedComponents) {
  const Case c = read_case("blobs_a");
  const ModuleRunResult r = run_module(names::lee94, {{"mask", std::make_shared<VolumeU8>(c.mask)}}, {}, {.threads = 2});
  EXPECT_TRUE(*r.get<VolumeU8>("skeleton") == c.skeleton);
  const auto t = r.get<Table>("table");
  EXPECT_EQ(t->ints("object_voxels").at(0), count(c.mask));
  EXPECT_EQ(t->ints("skeleton_voxels").at(0), count(c.skeleton));
  EXPECT_GT(t->ints("passes").at(0), 1);
  EXPECT_GT(t->ints("working_bytes").at(0), 0);
  EXPECT_EQ(t->ints("vanished_components").at(0), 0);
  EXPECT_TRUE(r.warnings.empty());

  const Case cube = read_case("cube");
  const ModuleRunResult rc = run_module(names::lee94, {{"mask", std::make_shared<VolumeU8>(cube.mask)}});
  ASSERT_EQ(rc.warnings.size(), 1u);
  EXPECT_NE(rc.warnings[0].find("1 component(s) of the mask vanished"), std::string::npos) << rc.warnings[0];
  EXPECT_EQ(rc.get<Table>("table")->ints("vanished_components").at(0), 1);

  const ModuleRunResult re =
      run_module(names::lee94, {{"mask", std::make_shared<VolumeU8>(Dims{3, 4, 5}, 0)}});
  ASSERT_EQ(re.warnings.size(), 1u);
  EXPECT_NE(re.warnings[0].find("empty"), std::string::npos);
  EXPECT_THROW(run_module(names::lee94, {}), InputError);
}

TEST(Lee94, Cancellation) {
  const VolumeU8 m = test::random_blobs(32, 5, 0.45, 2);
  std::atomic<bool> cancel{true};
  EXPECT_THROW(run_module(names::lee94, {{"mask", std::make_shared<VolumeU8>(m)}}, {}, {.cancel = &cancel}),
               Cancelled);
}

TEST(Lee94, IdenticalToLiveScikitImage) {
  // A volume larger than the committed ones, thinned by /usr/bin/python3's scikit-image in this run.
  if (std::system("/usr/bin/python3 -c 'import numpy, skimage.morphology' >/dev/null 2>&1") != 0)
    GTEST_SKIP() << "/usr/bin/python3 with numpy and scikit-image is not available; the committed references "
                    "(IdenticalToScikitImageReferences) still run";
  const std::filesystem::path dir = std::filesystem::path(SKEL_BINARY_DIR) / "lee94_live";
  std::filesystem::create_directories(dir);
  const VolumeU8 blobs = test::random_blobs(68, 21, 0.47, 2);
  VolumeU8 m(Dims{136, 48, 40}, 0);  // non-cubic, rows longer than two 64-bit words, touching the border
  for (int64_t z = 0; z < 40; ++z)
    for (int64_t y = 0; y < 48; ++y)
      for (int64_t x = 0; x < 136; ++x) m(x, y, z) = blobs(x < 68 ? x : x - 68, y, z);
  const std::string in = (dir / "mask.raw").string(), out = (dir / "skeleton.raw").string();
  {
    std::ofstream f(in, std::ios::binary);
    f.write(reinterpret_cast<const char*>(m.data()), m.size());
  }
  const std::string cmd = "/usr/bin/python3 -c \"import numpy as np\ntry:\n from skimage.morphology import "
                          "skeletonize_3d as s\nexcept ImportError:\n from skimage.morphology import skeletonize "
                          "as s\na = np.fromfile('" + in + "', np.uint8).reshape(40, 48, 136)\n(s(a) > "
                          "0).astype(np.uint8).tofile('" + out + "')\"";
  ASSERT_EQ(std::system(cmd.c_str()), 0) << cmd;
  VolumeU8 ref(m.dims(), 0);
  {
    std::ifstream f(out, std::ios::binary);
    f.read(reinterpret_cast<char*>(ref.data()), ref.size());
    ASSERT_EQ(f.gcount(), ref.size());
  }
  std::filesystem::remove_all(dir);
  EXPECT_GT(count(ref), 100);
  EXPECT_TRUE(thin_lee94(m).skeleton == ref) << count(thin_lee94(m).skeleton) << " vs " << count(ref);
}

}  // namespace
}  // namespace skel
