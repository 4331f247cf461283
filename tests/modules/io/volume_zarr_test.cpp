// Zarr v2 / OME-Zarr volumes (directory stores): round trips of every voxel type (blosc and
// uncompressed, empty chunks left out), read_box touching only some chunks, arrays written by the
// zarr package (blosc zstd/lz4, zlib, gzip, zstd, none; "." and "/" keys; big endian; missing chunks
// = fill_value; OME multiscales with t, c axes, units and levels), our stores read by zarr, bad stores.
#include <gtest/gtest.h>

#include "io/volume_bytes.hpp"
#include "io/zarr_volume.hpp"
#include "volume_test_util.hpp"

using namespace skel;
using namespace skel::test;

namespace {
int64_t count_files(const fs::path& d) {
  int64_t n = 0;
  for (const auto& e : fs::recursive_directory_iterator(d))
    if (e.is_regular_file()) ++n;
  return n;
}
}  // namespace

TEST(VolumeZarr, RoundTripEveryTypeBloscAndRaw) {
  for (int c : {0, 5}) {
    for_every_voxel_type([&](auto t) {
      using T = decltype(t);
      const auto v = random_volume<T>(Dims{70, 33, 9}, 23, "mm");
      io::VolumeWriteOptions o;
      o.compression = c;
      expect_round_trip(v, scratch() / ("rt_" + std::string(VoxelTraits<T>::name) + "_" + std::to_string(c) + ".ome.zarr"), o);
    });
  }
  // Rewriting replaces the store and leaves no temporary next to it.
  const auto v = random_volume<uint8_t>(Dims{5, 5, 5}, 1, kDefaultUnit);
  expect_round_trip(v, scratch() / "rt_uint8_0.ome.zarr");
  for (const auto& e : fs::directory_iterator(scratch()))
    EXPECT_EQ(e.path().filename().string().find("skelflow-"), std::string::npos) << e.path();
}

TEST(VolumeZarr, EmptyChunksAreNotStoredAndReadBoxTouchesOnlyItsChunks) {
  // 300 x 200 x 40 uint8: chunks of 128x128x64 -> 3 x 2 x 1 chunks; only the first holds data.
  Grid g(Dims{300, 200, 40}, {0.5, 0.5, 2}, {10, 20, 30}, "nm");
  VolumeU8 v(g, 0);
  for (int64_t z = 0; z < 40; ++z) v(5, 6, z) = static_cast<uint8_t>(z + 1);
  const fs::path f = scratch() / "sparse.zarr";
  io::write_any_volume(f, v);
  EXPECT_EQ(count_files(f / "0"), 2);  // .zarray + one chunk
  const auto back = std::dynamic_pointer_cast<const VolumeU8>(io::read_any_volume(f));
  ASSERT_TRUE(back);
  EXPECT_TRUE(*back == v);
  // A box inside the one stored chunk; then delete a chunk the box does not touch: still readable.
  const auto& fmt = io::volume_format_for_read(f);
  ASSERT_TRUE(fmt.read_box);
  const auto box = std::dynamic_pointer_cast<const VolumeU8>(fmt.read_box(f, {}, Dims{4, 6, 10}, Dims{3, 2, 5}));
  ASSERT_TRUE(box);
  EXPECT_EQ(box->dims(), (Dims{3, 2, 5}));
  EXPECT_EQ(box->origin(), (Vec3{12, 23, 50}));
  for (int64_t z = 0; z < 5; ++z) {
    EXPECT_EQ((*box)(1, 0, z), z + 11);
    EXPECT_EQ((*box)(0, 0, z), 0);
  }
  std::string e = error_of([&] { fmt.read_box(f, {}, Dims{290, 0, 0}, Dims{20, 1, 1}); });
  EXPECT_NE(e.find("sparse.zarr/0: box 290,0,0 + 20x1x1 is outside the array (300x200x40)"), std::string::npos) << e;
  // The corrupt far chunk is not touched by a box near the origin.
  fs::create_directories(f / "0" / "0" / "1");
  write_bytes(f / "0" / "0" / "1" / "2", "garbage");
  EXPECT_NO_THROW(fmt.read_box(f, {}, Dims{0, 0, 0}, Dims{10, 10, 10}));
  e = error_of([&] { io::read_any_volume(f); });
  EXPECT_NE(e.find("2: corrupt blosc chunk"), std::string::npos) << e;
}

TEST(VolumeZarr, ReadsStoresWrittenByZarr) {
  const fs::path d = scratch();
  const int rc = run_python(d, R"(
try:
    import zarr
    from numcodecs import Blosc, Zlib, Zstd, GZip
except ImportError:
    sys.exit(77)
import json, os
out = sys.argv[0].replace("make.py", "")
a = (numpy.arange(7 * 6 * 5, dtype=numpy.int64).reshape((5, 6, 7)) * 37 % 3000 - 1000)  # z, y, x
cases = {"blosc_zstd": (Blosc(cname="zstd", clevel=3, shuffle=Blosc.SHUFFLE), "<i2", "."),
         "blosc_lz4_bit": (Blosc(cname="lz4", clevel=5, shuffle=Blosc.BITSHUFFLE), "<u2", "/"),
         "zlib": (Zlib(level=4), ">i4", "."), "gzip": (GZip(level=5), "<f4", "/"),
         "zstd": (Zstd(level=3), "<f8", "."), "none": (None, ">u2", "/")}
for name, (comp, dt, sep) in cases.items():
    z = zarr.open(zarr.DirectoryStore(out + name + ".zarr", dimension_separator=sep), mode="w", shape=a.shape,
                  chunks=(2, 4, 3), dtype=dt, compressor=comp, fill_value=0)
    z[...] = (a + (1000 if dt[1] == "u" else 0)).astype(dt)
# Missing chunks: only the first chunk written, fill_value 7.
z = zarr.open(out + "fill.zarr", mode="w", shape=(5, 6, 7), chunks=(2, 4, 3), dtype="|u1", fill_value=7)
z[0:2, 0:4, 0:3] = 1
# OME-Zarr: t, c, z, y, x with two levels and units.
root = zarr.open_group(out + "ome.ome.zarr", mode="w")
l0 = root.create_dataset("s0", shape=(1, 1, 5, 6, 7), chunks=(1, 1, 2, 4, 3), dtype="<u2")
l0[0, 0] = a + 1000
l1 = root.create_dataset("s1", shape=(1, 1, 5, 3, 4), chunks=(1, 1, 5, 3, 4), dtype="<u2")
l1[0, 0] = (a[:, ::2, ::2] + 1000)
axes = [{"name": "t", "type": "time", "unit": "second"}, {"name": "c", "type": "channel"}] + \
       [{"name": n, "type": "space", "unit": "micrometer"} for n in "zyx"]
root.attrs["multiscales"] = [{"version": "0.4", "axes": axes, "datasets": [
    {"path": "s0", "coordinateTransformations": [{"type": "scale", "scale": [1, 1, 2.0, 0.5, 0.25]},
                                                 {"type": "translation", "translation": [0, 0, 3, 2, 1]}]},
    {"path": "s1", "coordinateTransformations": [{"type": "scale", "scale": [1, 1, 2.0, 1.0, 0.5]}]}]}]
)");
  if (rc == 77) GTEST_SKIP() << "python3-zarr is not installed";
  ASSERT_EQ(rc, 0) << "see " << d / "python.log";
  auto expected = [](int64_t i) { return (i * 37) % 3000 - 1000; };  // C order z, y, x = our index
  for (const char* name : {"blosc_zstd", "zlib", "gzip", "zstd"}) {
    const auto v = io::read_any_volume(d / (std::string(name) + ".zarr"));
    const auto f = convert_volume<double>(*v, name);
    ASSERT_EQ(f.dims(), (Dims{7, 6, 5})) << name;
    for (int64_t i = 0; i < f.size(); ++i) ASSERT_EQ(f[i], static_cast<double>(expected(i))) << name << " voxel " << i;
  }
  for (const char* name : {"blosc_lz4_bit", "none"}) {
    const auto v = std::dynamic_pointer_cast<const VolumeU16>(io::read_any_volume(d / (std::string(name) + ".zarr")));
    ASSERT_TRUE(v) << name;
    for (int64_t i = 0; i < v->size(); ++i) ASSERT_EQ((*v)[i], expected(i) + 1000) << name << " voxel " << i;
  }
  EXPECT_EQ(io::read_volume_header(d / "blosc_zstd.zarr").dtype, "int16");
  EXPECT_EQ(io::read_volume_header(d / "zlib.zarr").dtype, "int32");

  const auto fill = std::dynamic_pointer_cast<const VolumeU8>(io::read_any_volume(d / "fill.zarr"));
  ASSERT_TRUE(fill);
  EXPECT_EQ((*fill)(0, 0, 0), 1);
  EXPECT_EQ((*fill)(2, 3, 1), 1);
  EXPECT_EQ((*fill)(3, 0, 0), 7);
  EXPECT_EQ((*fill)(6, 5, 4), 7);

  const auto ome = std::dynamic_pointer_cast<const VolumeU16>(io::read_any_volume(d / "ome.ome.zarr"));
  ASSERT_TRUE(ome);
  EXPECT_EQ(ome->dims(), (Dims{7, 6, 5}));
  EXPECT_EQ(ome->spacing(), (Vec3{0.25, 0.5, 2}));
  EXPECT_EQ(ome->origin(), (Vec3{1, 2, 3}));
  EXPECT_EQ(ome->unit(), kDefaultUnit);
  for (int64_t i = 0; i < ome->size(); ++i) ASSERT_EQ((*ome)[i], expected(i) + 1000);
  io::VolumeReadOptions l1;
  l1.level = 1;
  const auto low = std::dynamic_pointer_cast<const VolumeU16>(io::read_any_volume(d / "ome.ome.zarr", l1));
  ASSERT_TRUE(low);
  EXPECT_EQ(low->dims(), (Dims{4, 3, 5}));
  EXPECT_EQ(low->spacing(), (Vec3{0.5, 1, 2}));
  EXPECT_EQ((*low)(1, 1, 1), (*ome)(2, 2, 1));
  l1.level = 2;
  const std::string e = error_of([&] { io::read_any_volume(d / "ome.ome.zarr", l1); });
  EXPECT_NE(e.find("ome.ome.zarr: level 2 does not exist (the image has 2 levels, 0 to 1)"), std::string::npos) << e;
  const std::string info = io::describe_volume_file(d / "ome.ome.zarr");
  EXPECT_NE(info.find("array: s0 (level 0 of 2)"), std::string::npos) << info;
}

TEST(VolumeZarr, ZarrReadsOurStores) {
  const fs::path d = scratch();
  const auto v = random_volume<uint16_t>(Dims{70, 33, 9}, 5, "mm");
  io::write_any_volume(d / "ours.ome.zarr", v);
  const int rc = run_python(d, R"(
try:
    import zarr
except ImportError:
    sys.exit(77)
g = zarr.open_group(sys.argv[0].replace("make.py", "ours.ome.zarr"), mode="r")
ms = g.attrs["multiscales"][0]
a = g[ms["datasets"][0]["path"]][...]
with open(sys.argv[0].replace("make.py", "out.txt"), "w") as f:
    f.write("%s %s %d %s %s %s\n" % (a.shape, a.dtype, int(a.astype(numpy.int64).sum()), ms["axes"][2]["unit"],
                                      ms["datasets"][0]["coordinateTransformations"][0]["scale"],
                                      ms["datasets"][0]["coordinateTransformations"][1]["translation"]))
)");
  if (rc == 77) GTEST_SKIP() << "python3-zarr is not installed";
  ASSERT_EQ(rc, 0) << "see " << d / "python.log";
  std::ifstream in(d / "out.txt");
  std::string line;
  std::getline(in, line);
  int64_t sum = 0;
  for (auto x : v) sum += x;
  EXPECT_EQ(line, "(9, 33, 70) uint16 " + std::to_string(sum) + " millimeter [2.0, 0.75, 0.5] [10.0, 1.5, -3.0]");
}

TEST(VolumeZarr, BadStoresNameTheFileAndTheProblem) {
  const fs::path d = scratch();
  auto store = [&](const std::string& name, const std::string& zarray) {
    fs::create_directories(d / name);
    write_bytes(d / name / ".zarray", zarray);
    return error_of([&] { io::read_any_volume(d / name); });
  };
  const std::string ok_tail = "\"dtype\": \"<u2\", \"order\": \"C\", \"fill_value\": 0, \"filters\": null, \"zarr_format\": 2";
  std::string e = error_of([&] { io::read_any_volume(d / "missing.zarr"); });
  EXPECT_NE(e.find("missing.zarr: not a Zarr folder"), std::string::npos) << e;
  e = store("json.zarr", "{ not json");
  EXPECT_NE(e.find("json.zarr/.zarray: not valid JSON"), std::string::npos) << e;
  e = store("v3.zarr", "{\"shape\": [2, 2, 2], \"chunks\": [2, 2, 2], \"dtype\": \"<u2\", \"zarr_format\": 3}");
  EXPECT_NE(e.find("v3.zarr/.zarray: zarr_format is 3; Skelflow reads Zarr v2"), std::string::npos) << e;
  e = store("chunks.zarr", "{\"shape\": [2, 2, 2], \"chunks\": [2, 2], \"compressor\": null, " + ok_tail + "}");
  EXPECT_NE(e.find("chunks.zarr/.zarray: 'chunks' has 2 values but 'shape' 3"), std::string::npos) << e;
  e = store("lzma.zarr", "{\"shape\": [2, 2, 2], \"chunks\": [2, 2, 2], \"compressor\": {\"id\": \"lzma\"}, " + ok_tail + "}");
  EXPECT_NE(e.find("lzma.zarr/.zarray: unsupported compressor 'lzma'"), std::string::npos) << e;
  e = store("dtype.zarr", "{\"shape\": [2, 2, 2], \"chunks\": [2, 2, 2], \"compressor\": null, \"dtype\": \"<c8\", \"zarr_format\": 2}");
  EXPECT_NE(e.find("dtype.zarr/.zarray: unsupported dtype '<c8'"), std::string::npos) << e;
  e = store("series.zarr", "{\"shape\": [3, 2, 2, 2], \"chunks\": [1, 2, 2, 2], \"compressor\": null, " + ok_tail + "}");
  EXPECT_NE(e.find("series.zarr/.zarray: dimension 0 of shape [3,2,2,2] is not 1"), std::string::npos) << e;
  // Truncated chunk (no compressor): 8 voxels need 16 bytes.
  e = store("trunc.zarr", "{\"shape\": [2, 2, 2], \"chunks\": [2, 2, 2], \"compressor\": null, " + ok_tail + "}");
  write_bytes(d / "trunc.zarr" / "0.0.0", std::string(10, 'x'));
  e = error_of([&] { io::read_any_volume(d / "trunc.zarr"); });
  EXPECT_NE(e.find("trunc.zarr/0.0.0: chunk holds 10 bytes; the chunk shape needs 16"), std::string::npos) << e;
  // A 1 KB header claiming far more than the machine's memory is refused before allocating.
  e = store("huge.zarr", "{\"shape\": [1000000, 1000000, 1000000], \"chunks\": [64, 64, 64], \"compressor\": null, " + ok_tail + "}");
  EXPECT_NE(e.find("huge.zarr: the array holds 2000000000000000000 bytes, more than this machine's memory"), std::string::npos) << e;
  e = store("bigchunk.zarr", "{\"shape\": [100000, 100000, 100000], \"chunks\": [100000, 100000, 100000], \"compressor\": null, " + ok_tail + "}");
  EXPECT_NE(e.find("bigchunk.zarr/.zarray: chunks [100000,100000,100000] are larger than 2 GiB"), std::string::npos) << e;
  // Writing a rotated volume is refused and leaves nothing.
  e = error_of([&] { io::write_any_volume(d / "rot.zarr", random_volume<uint8_t>(Dims{2, 2, 2}, 1, "mm", true)); });
  EXPECT_NE(e.find("rot.zarr: OME-Zarr 0.4 stores no rotation"), std::string::npos) << e;
  EXPECT_FALSE(fs::exists(d / "rot.zarr"));
}

TEST(VolumeZarr, BlockWiseWritingMatchesTheWholeVolume) {
  // Blocks that do not fall on chunk boundaries (chunks 16^3, blocks split at 37/50/20) in any order.
  const auto v = random_volume<uint16_t>(Dims{70, 60, 33}, 8, "mm");
  const fs::path f = scratch() / "blocks.ome.zarr";
  io::create_zarr_volume(f, "uint16", v.grid(), {}, {16, 16, 16});
  const int64_t sx[] = {0, 37, 70}, sy[] = {0, 50, 60}, sz[] = {0, 20, 33};
  for (int k = 1; k >= 0; --k)
    for (int j = 0; j < 2; ++j)
      for (int i = 1; i >= 0; --i) {
        VolumeU16 b(Dims{sx[i + 1] - sx[i], sy[j + 1] - sy[j], sz[k + 1] - sz[k]}, 0);
        for (int64_t z = 0; z < b.nz(); ++z)
          for (int64_t y = 0; y < b.ny(); ++y)
            for (int64_t x = 0; x < b.nx(); ++x) b(x, y, z) = v(sx[i] + x, sy[j] + y, sz[k] + z);
        io::write_zarr_box(f, b, Dims{sx[i], sy[j], sz[k]});
      }
  const auto back = std::dynamic_pointer_cast<const VolumeU16>(io::read_any_volume(f));
  ASSERT_TRUE(back);
  EXPECT_TRUE(*back == v);
  // A zero block over whole chunks removes them; a partial one keeps the rest of its chunks.
  const int64_t before = count_files(f / "0");
  io::write_zarr_box(f, VolumeU16(Dims{32, 32, 16}, 0), Dims{0, 0, 0});
  EXPECT_EQ(count_files(f / "0"), before - 4);
  io::write_zarr_box(f, VolumeU16(Dims{3, 3, 3}, 0), Dims{40, 40, 20});
  auto expected = v;
  for (int64_t z = 0; z < 16; ++z)
    for (int64_t y = 0; y < 32; ++y)
      for (int64_t x = 0; x < 32; ++x) expected(x, y, z) = 0;
  for (int64_t z = 20; z < 23; ++z)
    for (int64_t y = 40; y < 43; ++y)
      for (int64_t x = 40; x < 43; ++x) expected(x, y, z) = 0;
  const auto again = std::dynamic_pointer_cast<const VolumeU16>(io::read_any_volume(f));
  ASSERT_TRUE(again);
  EXPECT_TRUE(*again == expected);
  std::string e = error_of([&] { io::write_zarr_box(f, VolumeU8(Dims{2, 2, 2}, 1), Dims{0, 0, 0}); });
  EXPECT_NE(e.find("blocks.ome.zarr: the Zarr array holds uint16 voxels; cannot write a block of uint8"), std::string::npos) << e;
  e = error_of([&] { io::write_zarr_box(f, VolumeU16(Dims{2, 2, 2}, 1), Dims{69, 0, 0}); });
  EXPECT_NE(e.find("blocks.ome.zarr: a block of 2x2x2 at 69,0,0 does not fit the array (70x60x33)"), std::string::npos) << e;
  e = error_of([&] { io::create_zarr_volume(scratch() / "i16.zarr", "int16", v.grid()); });
  EXPECT_NE(e.find("i16.zarr: cannot create a Zarr array of voxel type 'int16'"), std::string::npos) << e;
}
