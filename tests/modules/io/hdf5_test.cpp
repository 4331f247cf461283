// HDF5 volumes: round trips of every type with spacing/origin, sub-boxes, compression, and a clear
// error for each way a file can be wrong.
#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>
#include <random>

#include "io/hdf5_volume.hpp"
#include "skel/run_module.hpp"
#include "skel/table.hpp"

namespace fs = std::filesystem;
using namespace skel;

namespace {
fs::path scratch() {
  static fs::path d = [] {
    fs::path p = fs::path(SKEL_BINARY_DIR) / "tests" / "scratch" / "io";
    fs::remove_all(p);
    fs::create_directories(p);
    return p;
  }();
  return d;
}
template <class T>
Volume<T> random_volume(Dims d, uint64_t seed) {
  Volume<T> v(d, T{}, {0.5, 0.75, 2.0}, {-3.0, 1.5, 10.0});
  std::mt19937_64 rng(seed);
  for (auto& x : v) x = static_cast<T>(rng() % 200);
  return v;
}
std::string error_of(const std::function<void()>& f) {
  try {
    f();
  } catch (const InputError& e) {
    return e.what();
  }
  return "(no InputError)";
}
template <class T>
void round_trip(int compression) {
  const auto v = random_volume<T>(Dims{17, 9, 5}, 3);
  const fs::path f = scratch() / ("rt_" + std::string(VoxelTraits<T>::name) + std::to_string(compression) + ".h5");
  io::WriteOptions o;
  o.compression = compression;
  io::write_volume(f, v, "/group/data", o);
  auto back = std::dynamic_pointer_cast<const Volume<T>>(io::read_volume(f, "/group/data"));
  ASSERT_TRUE(back) << VoxelTraits<T>::name;
  EXPECT_TRUE(*back == v) << VoxelTraits<T>::name;
}
}  // namespace

TEST(Hdf5, RoundTripEveryTypeWithSpacingAndOrigin) {
  for (int c : {0, 4}) {
    round_trip<uint8_t>(c);
    round_trip<uint16_t>(c);
    round_trip<uint32_t>(c);
    round_trip<uint64_t>(c);
    round_trip<int32_t>(c);
    round_trip<float>(c);
    round_trip<double>(c);
  }
  const fs::path f = scratch() / "rt_uint82.h5";
  io::write_volume(f, random_volume<uint8_t>(Dims{3, 3, 3}, 1));
  const auto info = io::read_volume_info(f);
  EXPECT_EQ(info.dims, (Dims{3, 3, 3}));
  EXPECT_EQ(info.spacing, (Vec3{0.5, 0.75, 2.0}));
  EXPECT_EQ(info.origin, (Vec3{-3.0, 1.5, 10.0}));
  EXPECT_EQ(info.filters, (std::vector<std::string>{"deflate"}));
}

TEST(Hdf5, SubBoxEqualsCrop) {
  const auto v = random_volume<uint16_t>(Dims{20, 12, 7}, 9);
  const fs::path f = scratch() / "box.h5";
  io::write_volume(f, v);
  auto b = io::read_box<uint16_t>(f, "/volume", Dims{3, 2, 1}, Dims{10, 5, 4});
  for (int64_t z = 0; z < 4; ++z)
    for (int64_t y = 0; y < 5; ++y)
      for (int64_t x = 0; x < 10; ++x) EXPECT_EQ(b(x, y, z), v(x + 3, y + 2, z + 1));
  EXPECT_DOUBLE_EQ(b.origin()[0], -3.0 + 3 * 0.5);  // physical positions kept
  EXPECT_THROW(io::read_box<uint16_t>(f, "/volume", Dims{15, 0, 0}, Dims{10, 1, 1}), InputError);
}

TEST(Hdf5, AutomaticChunksAreAboutOneMebibyteAndCubeLike) {
  EXPECT_EQ(io::automatic_chunks(Dims{512, 512, 512}, 1), (std::array<int64_t, 3>{128, 128, 64}));
  EXPECT_EQ(io::automatic_chunks(Dims{512, 512, 512}, 2), (std::array<int64_t, 3>{128, 128, 32}));
  EXPECT_EQ(io::automatic_chunks(Dims{512, 512, 512}, 4), (std::array<int64_t, 3>{64, 64, 64}));
  EXPECT_EQ(io::automatic_chunks(Dims{512, 512, 512}, 8), (std::array<int64_t, 3>{64, 64, 32}));
  // Small or flat volumes: never larger than the volume, still about 1 MiB when it is larger.
  EXPECT_EQ(io::automatic_chunks(Dims{30, 26, 20}, 4), (std::array<int64_t, 3>{30, 26, 20}));
  EXPECT_EQ(io::automatic_chunks(Dims{2000, 3, 1000}, 1), (std::array<int64_t, 3>{128, 3, 1000}));
  EXPECT_EQ(io::automatic_chunks(Dims{0, 0, 0}, 1), (std::array<int64_t, 3>{1, 1, 1}));
  for (int64_t b : {1, 2, 4, 8}) {
    const auto c = io::automatic_chunks(Dims{1280, 1280, 1280}, b);
    const int64_t bytes = c[0] * c[1] * c[2] * b;
    EXPECT_GE(bytes, int64_t{1} << 19) << b;
    EXPECT_LE(bytes, int64_t{1} << 20) << b;
  }
  // The file records the chosen shape.
  const fs::path f = scratch() / "chunks.h5";
  io::write_volume(f, VolumeF32(Dims{100, 90, 80}, 1.0f));
  EXPECT_EQ(io::read_volume_info(f).chunks, io::automatic_chunks(Dims{100, 90, 80}, 4));
}

TEST(Hdf5, ClearErrors) {
  const fs::path good = scratch() / "good.h5";
  io::write_volume(good, random_volume<uint8_t>(Dims{64, 64, 32}, 2), "/volume", io::WriteOptions{0, {0, 0, 0}});
  EXPECT_NE(error_of([&] { io::read_volume(scratch() / "missing.h5"); }).find("missing.h5: file not found"), std::string::npos);
  std::ofstream(scratch() / "text.h5") << "this is not HDF5\n";
  EXPECT_NE(error_of([&] { io::read_volume(scratch() / "text.h5"); }).find("not an HDF5 file"), std::string::npos);
  // Truncated copy of a valid file.
  {
    std::ifstream in(good, std::ios::binary);
    std::string bytes((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
    std::ofstream(scratch() / "truncated.h5", std::ios::binary).write(bytes.data(), static_cast<std::streamsize>(bytes.size() / 2));
  }
  const std::string t = error_of([&] { io::read_volume(scratch() / "truncated.h5"); });
  EXPECT_NE(t.find("truncated.h5"), std::string::npos) << t;
  EXPECT_TRUE(t.find("truncated") != std::string::npos || t.find("corrupt") != std::string::npos) << t;
  const std::string nd = error_of([&] { io::read_volume(good, "/nothing"); });
  EXPECT_NE(nd.find("no dataset '/nothing' (datasets: /volume)"), std::string::npos) << nd;
}

TEST(Hdf5, ModulesWriteAtomicallyAndConvert) {
  const fs::path dir = scratch() / "modules";
  fs::create_directories(dir);
  DataPtr v = std::make_shared<VolumeF32>(random_volume<float>(Dims{8, 8, 8}, 4));
  run_module("io.write_volume", {{"volume", v}}, {{"path", std::string("a/v.h5")}}, {.threads = 1, .base_dir = dir});
  EXPECT_TRUE(fs::exists(dir / "a" / "v.h5"));
  auto r = run_module("io.read_volume", {}, {{"path", std::string("a/v.h5")}, {"dtype", std::string("uint8")}},
                      {.threads = 1, .base_dir = dir});
  auto u = r.get<VolumeU8>("volume");
  EXPECT_EQ((*u)[0], static_cast<uint8_t>(std::lround((*std::dynamic_pointer_cast<const VolumeF32>(v))[0])));
  EXPECT_THROW(run_module("io.read_volume", {}, {{"path", std::string("nope.h5")}}, {.threads = 1, .base_dir = dir}), InputError);
  Table t;
  t.add("a", std::vector<int64_t>{1, 2}).add("b", std::vector<std::string>{"x,y", "z"});
  run_module("io.write_table", {{"table", std::make_shared<Table>(t)}}, {{"path", std::string("t.csv")}}, {.threads = 1, .base_dir = dir});
  std::ifstream in(dir / "t.csv");
  std::string all((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  EXPECT_EQ(all, "a,b\n1,\"x,y\"\n2,z\n");
}
