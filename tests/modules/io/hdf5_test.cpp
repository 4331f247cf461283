// HDF5 volumes: round trips of every type with spacing/origin, sub-boxes, compression, and a clear
// error for each way a file can be wrong.
#include <gtest/gtest.h>
#include <hdf5.h>
#include <poll.h>
#include <sys/wait.h>
#include <unistd.h>

#include <cerrno>

#include <filesystem>
#include <fstream>
#include <limits>
#include <random>
#include <thread>

#include "io/hdf5_probe.hpp"
#include "io/hdf5_volume.hpp"
#include "skel/fs.hpp"
#include "skel/run_module.hpp"
#include "skel/table.hpp"

namespace fs = std::filesystem;
using namespace skel;

namespace {
// One folder per test: ctest runs the tests of this binary as parallel processes, and a shared
// folder wiped by one process's first call removed files another was about to read.
fs::path scratch() {
  static fs::path d = [] {
    const auto* info = ::testing::UnitTest::GetInstance()->current_test_info();
    const std::string name = info ? std::string(info->test_suite_name()) + "." + info->name() : "io";
    fs::path p = fs::path(SKEL_BINARY_DIR) / "tests" / "scratch" / "io" / name;
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

namespace {
// Compressed write of a volume whose dims are not multiples of the chunk shape (partial edge chunks
// on every axis), read back with our reader (plain H5Dread through HDF5's filter pipeline).
template <class T>
void compressed_round_trip(int level, int threads) {
  const auto v = random_volume<T>(Dims{23, 11, 9}, 5 + static_cast<uint64_t>(level));
  const std::string name = std::string(VoxelTraits<T>::name) + "_" + std::to_string(level) + "_" + std::to_string(threads);
  const fs::path f = scratch() / ("edge_" + name + ".h5");
  io::WriteOptions o;
  o.compression = level;
  o.chunks = {8, 4, 5};
  o.threads = threads;
  io::write_volume(f, v, "/g/v", o);
  const auto info = io::read_volume_info(f, "/g/v");
  EXPECT_EQ(info.chunks, (std::array<int64_t, 3>{8, 4, 5})) << name;
  const std::vector<std::string> filters =
      sizeof(T) > 1 ? std::vector<std::string>{"shuffle", "deflate"} : std::vector<std::string>{"deflate"};
  EXPECT_EQ(info.filters, filters) << name;
  auto back = std::dynamic_pointer_cast<const Volume<T>>(io::read_volume(f, "/g/v"));
  ASSERT_TRUE(back) << name;
  EXPECT_TRUE(*back == v) << name;
  // Boxes that straddle edge chunks, read by hyperslab.
  const auto b = io::read_box<T>(f, "/g/v", Dims{6, 3, 4}, Dims{17, 8, 5});
  bool same = true;
  for (int64_t z = 0; z < 5; ++z)
    for (int64_t y = 0; y < 8; ++y)
      for (int64_t x = 0; x < 17; ++x) same = same && b(x, y, z) == v(x + 6, y + 3, z + 4);
  EXPECT_TRUE(same) << name;
}
}  // namespace

TEST(Hdf5, CompressedWritesOfEveryTypeWithPartialEdgeChunks) {
  for (int level : {1, 9})
    for (int threads : {1, 3}) {
      compressed_round_trip<uint8_t>(level, threads);
      compressed_round_trip<uint16_t>(level, threads);
      compressed_round_trip<uint32_t>(level, threads);
      compressed_round_trip<uint64_t>(level, threads);
      compressed_round_trip<int32_t>(level, threads);
      compressed_round_trip<float>(level, threads);
      compressed_round_trip<double>(level, threads);
    }
  // Extreme values survive the byte shuffle.
  VolumeF64 e(Dims{7, 3, 2}, 0.0);
  e(0, 0, 0) = -1e308;
  e(6, 2, 1) = 5e-324;
  e(3, 1, 0) = std::numeric_limits<double>::infinity();
  io::WriteOptions o;
  o.chunks = {4, 2, 1};
  io::write_volume(scratch() / "extreme.h5", e, "/volume", o);
  auto back = std::dynamic_pointer_cast<const VolumeF64>(io::read_volume(scratch() / "extreme.h5"));
  ASSERT_TRUE(back);
  EXPECT_TRUE(*back == e);
}

TEST(Hdf5, CompressedChunksAreTheBytesOfHdf5sOwnFilterPipeline) {
  // Same volume, same dataset properties: once written by write_volume (our parallel shuffle +
  // deflate, H5Dwrite_chunk), once through HDF5's filter pipeline (create_volume_dataset +
  // write_box, i.e. H5Dwrite). Every stored chunk must be byte-identical with the same filter mask.
  // Dims are multiples of the chunk here: HDF5 leaves the padding of its own edge chunks undefined.
  for (int level : {1, 6}) {
    const auto v = random_volume<float>(Dims{16, 12, 6}, 11);
    io::WriteOptions o;
    o.compression = level;
    o.chunks = {8, 4, 3};
    o.threads = 2;
    const fs::path ours = scratch() / ("pipe_ours" + std::to_string(level) + ".h5");
    const fs::path lib = scratch() / ("pipe_hdf5" + std::to_string(level) + ".h5");
    io::write_volume(ours, v, "/volume", o);
    io::create_volume_dataset(lib, "/volume", "float32", v.grid(), o);
    io::write_box(lib, "/volume", v, Dims{0, 0, 0});
    const hid_t fa = H5Fopen(ours.c_str(), H5F_ACC_RDONLY, H5P_DEFAULT);
    const hid_t fb = H5Fopen(lib.c_str(), H5F_ACC_RDONLY, H5P_DEFAULT);
    ASSERT_GE(fa, 0);
    ASSERT_GE(fb, 0);
    const hid_t da = H5Dopen2(fa, "/volume", H5P_DEFAULT), db = H5Dopen2(fb, "/volume", H5P_DEFAULT);
    int chunks = 0;
    for (hsize_t z = 0; z < 6; z += 3)
      for (hsize_t y = 0; y < 12; y += 4)
        for (hsize_t x = 0; x < 16; x += 8) {
          const hsize_t off[3] = {z, y, x};
          hsize_t sa = 0, sb = 0;
          ASSERT_GE(H5Dget_chunk_storage_size(da, off, &sa), 0);
          ASSERT_GE(H5Dget_chunk_storage_size(db, off, &sb), 0);
          ASSERT_EQ(sa, sb) << "chunk at (" << x << ", " << y << ", " << z << ")";
          std::vector<unsigned char> a(sa), b(sb);
          uint32_t ma = 99, mb = 99;
          ASSERT_GE(H5Dread_chunk(da, H5P_DEFAULT, off, &ma, a.data()), 0);
          ASSERT_GE(H5Dread_chunk(db, H5P_DEFAULT, off, &mb, b.data()), 0);
          EXPECT_EQ(ma, 0u);
          EXPECT_EQ(ma, mb);
          EXPECT_TRUE(a == b) << "chunk at (" << x << ", " << y << ", " << z << ")";
          ++chunks;
        }
    EXPECT_EQ(chunks, 12);
    H5Dclose(da);
    H5Dclose(db);
    H5Fclose(fa);
    H5Fclose(fb);
  }
}

// A dataset with a zero dimension is not a volume: read_volume says so, naming the file and dataset
// (it used to return an empty volume that ran through a whole pipeline).
TEST(Hdf5, ZeroSizeDatasetIsRefused) {
  const fs::path f = scratch() / "zero.h5";
  {
    const hid_t file = H5Fcreate(f.string().c_str(), H5F_ACC_TRUNC, H5P_DEFAULT, H5P_DEFAULT);
    ASSERT_GE(file, 0);
    const hsize_t dims[3] = {4, 0, 3};  // [z][y][x]
    const hid_t space = H5Screate_simple(3, dims, nullptr);
    const hid_t dset = H5Dcreate2(file, "/volume", H5T_NATIVE_UINT8, space, H5P_DEFAULT, H5P_DEFAULT, H5P_DEFAULT);
    ASSERT_GE(dset, 0);
    H5Dclose(dset);
    H5Sclose(space);
    H5Fclose(file);
  }
  EXPECT_EQ(error_of([&] { io::read_volume(f, "/volume"); }),
            f.string() + ": dataset '/volume' is empty (3x0x4 voxels as x,y,z); a volume needs at least one voxel on every axis");
  // The module reports the same.
  EXPECT_THROW(io::read_volume(f), InputError);
  // Describing the file still works.
  EXPECT_EQ(io::read_volume_info(f).dims, (Dims{3, 0, 4}));
}

namespace {
std::string file_bytes(const fs::path& p) {
  std::ifstream in(p, std::ios::binary);
  return std::string(std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>());
}
}  // namespace

// The same volume written twice, a second apart, gives the same bytes (before: HDF5 stored the
// dataset's modification time, one byte differed), compressed or not, in a group or not.
TEST(Hdf5, WritingTheSameVolumeTwiceGivesTheSameBytes) {
  const auto v = random_volume<uint16_t>(Dims{40, 30, 20}, 5);
  for (const int compression : {0, 1}) {
    for (const std::string dataset : {"/volume", "/group/sub/volume"}) {
      io::WriteOptions o;
      o.compression = compression;
      const fs::path a = scratch() / "same_a.h5", b = scratch() / "same_b.h5";
      io::write_volume(a, v, dataset, o);
      std::this_thread::sleep_for(std::chrono::milliseconds(1100));
      io::write_volume(b, v, dataset, o);
      const std::string x = file_bytes(a), y = file_bytes(b);
      ASSERT_FALSE(x.empty());
      EXPECT_TRUE(x == y) << "compression " << compression << ", " << dataset;
    }
  }
}

// The engine's temporary is written in place and a failed write names the final file
// (before: the writer made a temporary of the temporary and named it in its messages).
TEST(Hdf5, WritesTheEnginesTemporaryInPlaceAndNamesTheFinalFile) {
  const fs::path dir = scratch() / "engine_tmp";
  fs::create_directories(dir);
  const fs::path tmp = temp_sibling(dir / "image.h5", "5eed5eed");
  const auto v = random_volume<uint8_t>(Dims{8, 8, 8}, 1);
  io::write_volume(tmp, v, "/volume");
  std::vector<std::string> names;
  for (const auto& e : fs::directory_iterator(dir)) names.push_back(e.path().filename().string());
  EXPECT_EQ(names, std::vector<std::string>{tmp.filename().string()});
  const auto back = std::dynamic_pointer_cast<const VolumeU8>(io::read_volume(tmp, "/volume"));
  ASSERT_TRUE(back);
  EXPECT_TRUE(std::equal(back->begin(), back->end(), v.begin(), v.end()));
  // A temporary in a folder that does not exist cannot be created.
  const fs::path missing = temp_sibling(dir / "gone" / "image.h5", "5eed5eed");
  try {
    io::write_volume(missing, v, "/volume");
    FAIL() << "expected an error";
  } catch (const Error& e) {
    EXPECT_EQ(std::string(e.what()), "cannot write " + (dir / "gone" / "image.h5").string() +
                                         ": cannot create the file: No such file or directory");
  }
}

// A small file that declares a huge dataset is refused before anything is allocated (before: a
// 4 KB file declaring 2000³ voxels made read_volume allocate 8 GB and then fail reading; the fuzz
// reproducer fuzz/corpus/hdf5/declared_2tib_volume.h5 is such a file). Unfiltered data must be all there; a
// deflate-compressed dataset may declare at most ~1100 times the bytes it stores.
TEST(Hdf5, DeclaredSizeIsCheckedAgainstTheStoredDataBeforeAllocating) {
  auto make = [](const fs::path& f, bool chunked) {
    const hid_t file = H5Fcreate(f.string().c_str(), H5F_ACC_TRUNC, H5P_DEFAULT, H5P_DEFAULT);
    ASSERT_GE(file, 0);
    const hsize_t dims[3] = {2000, 2000, 2000};  // [z][y][x], never written
    const hid_t space = H5Screate_simple(3, dims, nullptr);
    const hid_t dcpl = H5Pcreate(H5P_DATASET_CREATE);
    if (chunked) {
      const hsize_t chunk[3] = {64, 64, 64};
      H5Pset_chunk(dcpl, 3, chunk);
      H5Pset_deflate(dcpl, 1);
      // One chunk written: 64³ zeros compress to a few hundred bytes.
    }
    const hid_t dset = H5Dcreate2(file, "/volume", H5T_NATIVE_DOUBLE, space, H5P_DEFAULT, dcpl, H5P_DEFAULT);
    ASSERT_GE(dset, 0);
    if (chunked) {
      std::vector<double> zeros(64 * 64 * 64, 0.0);
      const hsize_t start[3] = {0, 0, 0}, count[3] = {64, 64, 64};
      const hid_t fspace = H5Dget_space(dset);
      H5Sselect_hyperslab(fspace, H5S_SELECT_SET, start, nullptr, count, nullptr);
      const hid_t mspace = H5Screate_simple(3, count, nullptr);
      ASSERT_GE(H5Dwrite(dset, H5T_NATIVE_DOUBLE, mspace, fspace, H5P_DEFAULT, zeros.data()), 0);
      H5Sclose(mspace);
      H5Sclose(fspace);
    }
    H5Pclose(dcpl);
    H5Dclose(dset);
    H5Sclose(space);
    H5Fclose(file);
  };
  for (const bool chunked : {false, true}) {
    const fs::path f = scratch() / (chunked ? "huge_chunked.h5" : "huge_contiguous.h5");
    make(f, chunked);
    ASSERT_LT(fs::file_size(f), 1u << 20);
    const std::string e = error_of([&] { io::read_volume(f, "/volume"); });
    EXPECT_NE(e.find(f.string() + ": dataset '/volume' declares 2000x2000x2000 voxels (x,y,z) of float64"), std::string::npos) << e;
    EXPECT_NE(e.find("truncated or corrupt"), std::string::npos) << e;
  }
  // A well-formed compressed volume that compresses extremely well (all zeros) still reads.
  const fs::path ok = scratch() / "zeros.h5";
  io::write_volume(ok, VolumeU8(Dims{256, 256, 64}, 0));
  EXPECT_EQ(io::read_volume(ok)->bytes(), 256u * 256u * 64u);
}

// A 4x4x4 float dataset whose one chunk claims 4294967295 stored bytes in a 4 KB file (libFuzzer's
// reproducer): H5Dread allocated a 4 GB buffer for that chunk before failing. The stored size is
// now checked against the file's size before the read.
TEST(Hdf5, StoredSizeBeyondTheFileIsRefusedBeforeReading) {
  const fs::path path = fs::path(SKEL_SOURCE_DIR) / "fuzz" / "corpus" / "hdf5" / "h5dread_4gb_malloc.h5";
  ASSERT_TRUE(fs::exists(path)) << path;
  const std::string e = error_of([&] { io::read_volume(path, "/volume"); });
  EXPECT_NE(e.find(path.string() + ": dataset '/volume' claims 4294967295 bytes of stored data but the file is only " +
                   std::to_string(fs::file_size(path)) + " bytes: the file is truncated or corrupt"),
            std::string::npos)
      << e;
  // Valid files, compressed or not, still read.
  const fs::path ok = scratch() / "stored_ok.h5";
  io::write_volume(ok, VolumeU8(Dims{32, 16, 8}, 3));
  EXPECT_EQ(io::read_volume(ok)->bytes(), 32u * 16u * 8u);
}

// The libFuzzer reproducers of the HDF5 target (seeds now) are clear errors, not crashes.
TEST(Hdf5, FuzzReproducersAreClearErrors) {
  const fs::path dir = fs::path(SKEL_SOURCE_DIR) / "fuzz" / "corpus" / "hdf5";
  int n = 0;
  for (const char* name : {"declared_2tib_volume.h5", "h5dread_4gb_malloc.h5", "libhdf5_superblock_leak.h5"}) {
    const fs::path path = dir / name;
    ASSERT_TRUE(fs::exists(path)) << path;
    ++n;
    try {
      (void)io::read_volume_info(path, "/volume");
      (void)io::read_volume(path, "/volume");
    } catch (const InputError& err) {
      EXPECT_NE(std::string(err.what()).find(path.string()), std::string::npos) << err.what();
    }
  }
  EXPECT_GT(n, 0);
}

// Integer and float types whose bit fields lie outside their bytes are refused before H5Dread:
// libhdf5's conversions trust those fields, and the libFuzzer input
// libhdf5_int_to_double_bit_copy_sigbus.h5 (an 8-byte integer of precision 0 at bit offset 256) made
// the integer-to-double conversion fault with SIGBUS in this process (session 9). Valid types with
// fewer bits than bytes (a 40-bit integer) or another exponent bias still read, converted by libhdf5.
TEST(Hdf5, NumberTypesWithFieldsOutsideTheirBytesAreRefusedBeforeReading) {
  const fs::path bus = fs::path(SKEL_SOURCE_DIR) / "fuzz" / "corpus" / "hdf5" / "libhdf5_int_to_double_bit_copy_sigbus.h5";
  ASSERT_TRUE(fs::exists(bus));
  try {
    (void)io::read_volume(bus, "/volume");
    ADD_FAILURE() << "read";
  } catch (const InputError& err) {
    EXPECT_EQ(std::string(err.what()), bus.string() + ": dataset '/volume' has a damaged int64 type (0 bits of precision at "
                                                      "bit offset 256 in 8 bytes): the file is damaged");
  }
  const fs::path file = scratch() / "odd_types.h5";
  {
    const hid_t f = H5Fcreate(file.c_str(), H5F_ACC_TRUNC, H5P_DEFAULT, H5P_DEFAULT);
    const hsize_t dims[3] = {2, 2, 2};
    const hid_t space = H5Screate_simple(3, dims, nullptr);
    const hid_t i40 = H5Tcopy(H5T_STD_I64LE);
    H5Tset_precision(i40, 40);
    const hid_t f32 = H5Tcopy(H5T_IEEE_F32LE);
    H5Tset_ebias(f32, 100);
    for (auto [name, type] : {std::pair{"/i40", i40}, std::pair{"/f32", f32}}) {
      const hid_t d = H5Dcreate2(f, name, type, space, H5P_DEFAULT, H5P_DEFAULT, H5P_DEFAULT);
      ASSERT_GE(d, 0);
      const double v[8] = {1, 2, 3, 4, 5, 6, 7, 8};
      H5Dwrite(d, H5T_NATIVE_DOUBLE, H5S_ALL, H5S_ALL, H5P_DEFAULT, v);
      H5Dclose(d);
    }
    H5Tclose(i40);
    H5Tclose(f32);
    H5Sclose(space);
    H5Fclose(f);
  }
  for (const char* name : {"/i40", "/f32"}) {
    const DataPtr v = io::read_volume(file, name);
    const auto* d = dynamic_cast<const VolumeF64*>(v.get());
    const auto* f = dynamic_cast<const VolumeF32*>(v.get());
    ASSERT_TRUE(d || f) << name;
    EXPECT_EQ(d ? (*d)(1, 1, 1) : (*f)(1, 1, 1), 8.0) << name;
  }
}

// The 8 libFuzzer findings inside libhdf5 1.10.8 go through the structure probe
// (io/hdf5_probe.hpp), all refused naming the file. A SEGV under H5G__stab_lookup and 1.4 / 4.1 GB
// metadata mallocs: the probe crashes or runs out of its 1 GiB (before the probe this test crashed:
// SKEL_HDF5_PROBE=0 shows it). Heap overflows and use-after-free in memcpy under H5Aexists: the
// helper skelflow-hdf5-probe is built with AddressSanitizer (which intercepts libhdf5's memcpy and
// malloc), so they stop it in every build. Before the helper, the probe was a forked child of this
// process, which in a normal build survived these five silently: the file was read in-process and
// one of them gave a volume with a garbage origin (4.7e-310).
TEST(Hdf5Probe, LibHdf5CrashReproducersAreRefusedNamingTheFile) {
  const fs::path dir = fs::path(SKEL_SOURCE_DIR) / "fuzz" / "corpus" / "hdf5";
  ASSERT_NE(io::detail::hdf5_probe_helper(), "") << "skelflow-hdf5-probe not found";
#if !defined(SKEL_HDF5_PROBE_WITH_ASAN)
  GTEST_SKIP() << "skelflow-hdf5-probe built without AddressSanitizer (SKEL_HDF5_PROBE_ASAN=OFF or no compiler support)";
#endif
  // libhdf5_group_iterate_unbounded_alloc.h5 (libFuzzer, session 9): H5Ovisit allocates without end
  // (~350 MB/s) and calls back nothing. Under AddressSanitizer the helper's address space does not
  // grow (its allocator's range is reserved at start-up), so RLIMIT_AS never stopped it: the walk
  // ran to the timeout, growing by gigabytes. RLIMIT_DATA stops it at the limit now.
  const std::string memory = "needed more than 1024 MiB of memory reading its structure in a separate process; not opened "
                             "(SKEL_HDF5_PROBE_MEMORY_MB sets the limit)";
  const std::pair<const char*, std::string> files[] = {  // name, the reason given
      {"libhdf5_stab_lookup_segv.h5", "crashed (SIGSEGV)"},
      {"libhdf5_metadata_malloc_1.h5", memory},
      {"libhdf5_metadata_malloc_2.h5", memory},
      {"libhdf5_group_iterate_unbounded_alloc.h5", memory},
      {"libhdf5_attr_exists_heap_overflow_1.h5", "made a memory error (AddressSanitizer)"},
      {"libhdf5_attr_exists_heap_overflow_2.h5", "made a memory error (AddressSanitizer)"},
      {"libhdf5_attr_exists_heap_overflow_3.h5", "made a memory error (AddressSanitizer)"},
      {"libhdf5_attr_exists_use_after_free_1.h5", "made a memory error (AddressSanitizer)"},
      {"libhdf5_attr_exists_use_after_free_2.h5", "made a memory error (AddressSanitizer)"}};
  for (const auto& [name, reason] : files) {
    SCOPED_TRACE(name);
    const fs::path path = dir / name;
    ASSERT_TRUE(fs::exists(path)) << path;
    const int64_t before = io::detail::hdf5_probes_started();
    for (int round = 0; round < 2; ++round) {  // the second round is answered from the cache
      try {
        (void)io::read_volume_info(path, "/volume");
        (void)io::read_volume(path, "/volume");
        ADD_FAILURE() << "read";
      } catch (const InputError& err) {
        const std::string what = err.what();
        const std::string given = reason.find("; not opened") == std::string::npos
                                      ? reason + " reading its structure in a separate process; not opened"
                                      : reason;
        EXPECT_EQ(what, path.string() + " is damaged: the HDF5 library " + given);
      }
      EXPECT_THROW((void)io::describe_file(path), InputError);
    }
    EXPECT_EQ(io::detail::hdf5_probes_started(), before + 1);
  }
}

// Mutated deflated 3x3x3 volumes (libFuzzer, session 8) whose voxels crash libhdf5 1.10.8 inside
// H5Dread (heap overflows and SEGVs in H5VM_memcpyvv under H5D__select_read): the structure walk alone
// passed them, so they were read in-process. The walk now reads small datasets' voxels (and the first
// and last chunk of large ones) in the helper too; each is refused before this process reads it.
TEST(Hdf5Probe, LibHdf5VoxelReadCrashesAreRefusedNamingTheFile) {
  const fs::path dir = fs::path(SKEL_SOURCE_DIR) / "fuzz" / "corpus" / "hdf5";
  ASSERT_NE(io::detail::hdf5_probe_helper(), "") << "skelflow-hdf5-probe not found";
#if !defined(SKEL_HDF5_PROBE_WITH_ASAN)
  GTEST_SKIP() << "skelflow-hdf5-probe built without AddressSanitizer (SKEL_HDF5_PROBE_ASAN=OFF or no compiler support)";
#endif
  for (int i = 1; i <= 9; ++i) {
    const fs::path path = dir / ("libhdf5_deflate_chunk_read_" + std::to_string(i) + ".h5");
    SCOPED_TRACE(path.string());
    ASSERT_TRUE(fs::exists(path));
    try {
      (void)io::read_volume(path, "/volume");
      ADD_FAILURE() << "read";
    } catch (const InputError& err) {
      const std::string what = err.what();
      EXPECT_EQ(what.rfind(path.string() + " is damaged: the HDF5 library ", 0), 0u) << what;
      EXPECT_NE(what.find("reading its structure in a separate process; not opened"), std::string::npos) << what;
    }
  }
}

// SKEL_HDF5_PROBE=fork: the walk in a forked child of this process (also what happens when no helper
// is found). It refuses what crashes or exhausts the child; in a build without AddressSanitizer the
// five silent H5Aexists memory errors are not seen there (the reason for the helper).
TEST(Hdf5Probe, ForkedChildWhenAskedFor) {
  const fs::path dir = fs::path(SKEL_SOURCE_DIR) / "fuzz" / "corpus" / "hdf5";
  io::detail::stop_hdf5_probe_worker();
  ASSERT_EQ(setenv("SKEL_HDF5_PROBE", "fork", 1), 0);
  io::detail::forget_hdf5_probes();
  EXPECT_EQ(io::detail::hdf5_probe_helper(), "");
  const int64_t workers = io::detail::hdf5_probe_workers_started();
  const int64_t before = io::detail::hdf5_probes_started();
  const fs::path good = scratch() / "forked.h5";
  io::write_volume(good, random_volume<uint8_t>({5, 4, 3}, 2));
  EXPECT_EQ(io::read_volume_info(good).dims, (Dims{5, 4, 3}));
  const fs::path segv = dir / "libhdf5_stab_lookup_segv.h5";
  EXPECT_EQ(error_of([&] { (void)io::read_volume_info(segv); }),
            segv.string() + " is damaged: the HDF5 library crashed (SIGSEGV) reading its structure in a separate process; not opened");
  const fs::path malloc = dir / "libhdf5_metadata_malloc_1.h5";
  // (needed more than 1024 MiB; in a sanitizer build the forked child's ASan, with this process's
  // ASAN_OPTIONS, may stop the allocation itself: failed with its exit status)
  EXPECT_EQ(error_of([&] { (void)io::read_volume_info(malloc); }).rfind(malloc.string() + " is damaged: the HDF5 library ", 0), 0u);
  EXPECT_EQ(io::detail::hdf5_probes_started(), before + 3);
  EXPECT_EQ(io::detail::hdf5_probe_workers_started(), workers);
  unsetenv("SKEL_HDF5_PROBE");
  io::detail::forget_hdf5_probes();
  errno = 0;
  EXPECT_EQ(waitpid(-1, nullptr, WNOHANG), -1);
  EXPECT_EQ(errno, ECHILD);
}

namespace {
// Whether `pid` is a zombie (state Z in /proc/PID/stat) or gone.
bool zombie_or_gone(int pid) {
  std::ifstream in("/proc/" + std::to_string(pid) + "/stat");
  std::string line;
  if (!std::getline(in, line)) return true;
  const size_t close = line.rfind(')');
  return close == std::string::npos || line.substr(close + 2, 1) == "Z";
}

// The children of process `pid` (/proc/PID/task/PID/children).
std::vector<int> children_of(int pid) {
  std::ifstream in("/proc/" + std::to_string(pid) + "/task/" + std::to_string(pid) + "/children");
  std::vector<int> c;
  for (int x; in >> x;) c.push_back(x);
  return c;
}

void expect_no_child_left() {
  errno = 0;
  EXPECT_EQ(waitpid(-1, nullptr, WNOHANG), -1);  // no child at all, so no zombie either
  EXPECT_EQ(errno, ECHILD);
}
}  // namespace

// One helper process serves every file. A crash of libhdf5 in it refuses that file only: the walk
// runs in a child the worker forks (its "walker"), which is replaced, and the worker goes on. A
// worker that dies is reaped and replaced at the next file; a timeout kills the worker and its walker;
// stopping it leaves no process. Before the helper, each file forked this process
// (hdf5_probe_workers_started did not exist).
TEST(Hdf5Probe, OneWorkerServesManyFilesAndSurvivesACrash) {
  ASSERT_NE(io::detail::hdf5_probe_helper(), "") << "skelflow-hdf5-probe not found";
  io::detail::stop_hdf5_probe_worker();
  const int64_t workers = io::detail::hdf5_probe_workers_started();
  const int64_t probes = io::detail::hdf5_probes_started();
  std::vector<fs::path> files;
  for (int i = 0; i < 8; ++i) {
    files.push_back(scratch() / ("many_" + std::to_string(i) + ".h5"));
    io::write_volume(files.back(), random_volume<uint16_t>({4 + i, 3, 2}, static_cast<uint64_t>(i)));
  }
  for (int i = 0; i < 5; ++i) EXPECT_EQ(io::read_volume_info(files[static_cast<size_t>(i)]).dims, (Dims{4 + i, 3, 2}));
  EXPECT_EQ(io::detail::hdf5_probes_started(), probes + 5);
  EXPECT_EQ(io::detail::hdf5_probe_workers_started(), workers + 1);
  const int worker = io::detail::hdf5_probe_worker_pid();
  ASSERT_GT(worker, 0);
  EXPECT_FALSE(zombie_or_gone(worker));
  const std::vector<int> walker = children_of(worker);
  ASSERT_EQ(walker.size(), 1u);
  // A crash in the walker: that file is refused; the worker forks a new walker and serves the next file.
  const fs::path segv = fs::path(SKEL_SOURCE_DIR) / "fuzz" / "corpus" / "hdf5" / "libhdf5_stab_lookup_segv.h5";
  EXPECT_NE(error_of([&] { (void)io::read_volume_info(segv); }).find("crashed (SIGSEGV)"), std::string::npos);
  EXPECT_EQ(io::read_volume_info(files[5]).dims, (Dims{9, 3, 2}));
  EXPECT_EQ(io::detail::hdf5_probe_worker_pid(), worker);
  EXPECT_EQ(io::detail::hdf5_probe_workers_started(), workers + 1);
  const std::vector<int> walker2 = children_of(worker);
  ASSERT_EQ(walker2.size(), 1u);
  EXPECT_NE(walker2[0], walker[0]);
  EXPECT_TRUE(zombie_or_gone(walker[0]));
  // The worker killed from outside: reaped, and the next file starts a new one and reads.
  ASSERT_EQ(kill(worker, SIGKILL), 0);
  for (int i = 0; i < 400 && !zombie_or_gone(walker2[0]); ++i) std::this_thread::sleep_for(std::chrono::milliseconds(5));
  EXPECT_EQ(io::read_volume_info(files[6]).dims, (Dims{10, 3, 2}));
  EXPECT_EQ(io::detail::hdf5_probe_workers_started(), workers + 2);
  const int second = io::detail::hdf5_probe_worker_pid();
  ASSERT_GT(second, 0);
  EXPECT_NE(second, worker);
  EXPECT_TRUE(zombie_or_gone(worker));
  // A timeout kills the worker and its walker; the next file starts a new worker.
  const std::vector<int> walker3 = children_of(second);
  ASSERT_EQ(setenv("SKEL_HDF5_PROBE_TIMEOUT", "0.000001", 1), 0);
  EXPECT_NE(error_of([&] { (void)io::read_volume_info(files[7]); }).find("did not finish within 1e-06 s"), std::string::npos);
  unsetenv("SKEL_HDF5_PROBE_TIMEOUT");
  EXPECT_EQ(io::detail::hdf5_probe_worker_pid(), -1);
  EXPECT_TRUE(zombie_or_gone(second));
  for (int w : walker3) {
    for (int i = 0; i < 400 && !zombie_or_gone(w); ++i) std::this_thread::sleep_for(std::chrono::milliseconds(5));
    EXPECT_TRUE(zombie_or_gone(w));
  }
  expect_no_child_left();
  io::detail::forget_hdf5_probes();
  EXPECT_EQ(io::read_volume_info(files[7]).dims, (Dims{11, 3, 2}));
  EXPECT_EQ(io::detail::hdf5_probe_workers_started(), workers + 3);
  const int third = io::detail::hdf5_probe_worker_pid();
  io::detail::stop_hdf5_probe_worker();
  EXPECT_EQ(io::detail::hdf5_probe_worker_pid(), -1);
  EXPECT_TRUE(zombie_or_gone(third));
  expect_no_child_left();
}

// The worker holds no descriptor of the caller: a pipe opened without close-on-exec (as std::ofstream
// opens files) is not kept open by it, so a reader of that pipe sees its end. Failed before
// posix_spawn closed the descriptors from 3 on in the worker.
TEST(Hdf5Probe, TheWorkerKeepsNoDescriptorOfTheCaller) {
  ASSERT_NE(io::detail::hdf5_probe_helper(), "") << "skelflow-hdf5-probe not found";
  io::detail::stop_hdf5_probe_worker();
  int p[2];
  ASSERT_EQ(pipe(p), 0);
  const fs::path file = scratch() / "fds.h5";
  io::write_volume(file, random_volume<uint8_t>({3, 3, 3}, 1));
  EXPECT_EQ(io::read_volume_info(file).dims, (Dims{3, 3, 3}));
  ASSERT_GT(io::detail::hdf5_probe_worker_pid(), 0);
  close(p[1]);
  pollfd q{p[0], POLLIN, 0};
  ASSERT_EQ(poll(&q, 1, 0), 1);
  EXPECT_TRUE(q.revents & POLLHUP) << "a process still holds the pipe's write end";
  close(p[0]);
  io::detail::stop_hdf5_probe_worker();
}

// A worker started by a thread that ends dies with it (PR_SET_PDEATHSIG names the thread, not the
// process); the next probe from another thread starts a new one and the file reads (it is not
// refused as a crash). Several threads probing at once share the worker one request at a time.
TEST(Hdf5Probe, WorkerOfAnEndedThreadIsReplacedAndThreadsShareIt) {
  ASSERT_NE(io::detail::hdf5_probe_helper(), "") << "skelflow-hdf5-probe not found";
  io::detail::stop_hdf5_probe_worker();
  std::vector<fs::path> files;
  for (int i = 0; i < 8; ++i) {
    files.push_back(scratch() / ("thread_" + std::to_string(i) + ".h5"));
    io::write_volume(files.back(), random_volume<uint8_t>({3 + i, 2, 2}, static_cast<uint64_t>(i)));
  }
  std::thread([&] { EXPECT_EQ(io::read_volume_info(files[0]).dims, (Dims{3, 2, 2})); }).join();
  const int first = io::detail::hdf5_probe_worker_pid();
  ASSERT_GT(first, 0);
  for (int i = 0; i < 200 && !zombie_or_gone(first); ++i) std::this_thread::sleep_for(std::chrono::milliseconds(5));
  EXPECT_TRUE(zombie_or_gone(first)) << "PR_SET_PDEATHSIG: the worker ends with the thread that started it";
  EXPECT_EQ(io::read_volume_info(files[1]).dims, (Dims{4, 2, 2}));
  EXPECT_NE(io::detail::hdf5_probe_worker_pid(), first);
  std::vector<std::thread> threads;
  for (int t = 2; t < 8; ++t)
    threads.emplace_back([&, t] { EXPECT_EQ(io::read_volume_info(files[static_cast<size_t>(t)]).dims, (Dims{3 + t, 2, 2})); });
  for (auto& t : threads) t.join();
  io::detail::stop_hdf5_probe_worker();
  errno = 0;
  EXPECT_EQ(waitpid(-1, nullptr, WNOHANG), -1);
  EXPECT_EQ(errno, ECHILD);
}

// A good file reads as before, and every reader of it in this process shares one probe.
TEST(Hdf5Probe, AGoodFileIsProbedOnceAndReads) {
  const fs::path file = scratch() / "probed.h5";
  const VolumeF32 v = random_volume<float>({9, 7, 5}, 11);
  io::write_volume(file, v);
  const int64_t before = io::detail::hdf5_probes_started();
  const io::VolumeInfo info = io::read_volume_info(file);
  EXPECT_EQ(info.dims, (Dims{9, 7, 5}));
  const auto back = std::dynamic_pointer_cast<const VolumeF32>(io::read_volume(file));
  ASSERT_TRUE(back);
  EXPECT_TRUE(std::equal(back->begin(), back->end(), v.begin()));
  EXPECT_EQ(io::read_box<float>(file, "/volume", {1, 1, 1}, {2, 2, 2})(0, 0, 0), v(1, 1, 1));
  EXPECT_NE(io::describe_file(file).find("/volume: float32 9x7x5"), std::string::npos);
  EXPECT_EQ(io::read_string_attribute(file, "/volume", "unit"), v.grid().unit);
  EXPECT_EQ(io::detail::hdf5_probes_started(), before + 1);
  // A dataset name the first walk did not cover (absent here) is looked up by one more probe.
  EXPECT_THROW((void)io::read_volume_info(file, "/missing/volume"), InputError);
  EXPECT_THROW((void)io::read_volume_info(file, "/missing/volume"), InputError);
  EXPECT_EQ(io::detail::hdf5_probes_started(), before + 2);
  // A changed file is probed again.
  io::write_volume(file, random_volume<float>({4, 4, 4}, 12));
  EXPECT_EQ(io::read_volume_info(file).dims, (Dims{4, 4, 4}));
  EXPECT_EQ(io::detail::hdf5_probes_started(), before + 3);
  // No probe process is left behind once the worker is stopped.
  io::detail::stop_hdf5_probe_worker();
  errno = 0;
  EXPECT_EQ(waitpid(-1, nullptr, WNOHANG), -1);
  EXPECT_EQ(errno, ECHILD);
}

// SKEL_HDF5_PROBE=0 reads trusted files without a probe; SKEL_HDF5_PROBE_TIMEOUT bounds the probe's
// time (a tiny limit refuses even a good file, with the limit in the message).
TEST(Hdf5Probe, EnvironmentTurnsItOffAndSetsTheTimeout) {
  const fs::path file = scratch() / "trusted.h5";
  io::write_volume(file, random_volume<uint8_t>({3, 3, 3}, 5));
  const int64_t before = io::detail::hdf5_probes_started();
  ASSERT_EQ(setenv("SKEL_HDF5_PROBE", "0", 1), 0);
  EXPECT_EQ(io::read_volume_info(file).dims, (Dims{3, 3, 3}));
  EXPECT_EQ(io::detail::hdf5_probes_started(), before);
  unsetenv("SKEL_HDF5_PROBE");
  ASSERT_EQ(setenv("SKEL_HDF5_PROBE_TIMEOUT", "0.000001", 1), 0);
  try {
    (void)io::read_volume_info(file);
    ADD_FAILURE() << "read within 1 microsecond";
  } catch (const InputError& err) {
    EXPECT_NE(std::string(err.what()).find(file.string() + " is damaged: the HDF5 library did not finish within 1e-06 s"),
              std::string::npos)
        << err.what();
  }
  io::detail::forget_hdf5_probes();
  ASSERT_EQ(setenv("SKEL_HDF5_PROBE_TIMEOUT", "soon", 1), 0);
  EXPECT_THROW((void)io::read_volume_info(file), Error);
  unsetenv("SKEL_HDF5_PROBE_TIMEOUT");
  for (const char* bad : {"lots", "63", "-1", "2097152"}) {
    io::detail::forget_hdf5_probes();
    ASSERT_EQ(setenv("SKEL_HDF5_PROBE_MEMORY_MB", bad, 1), 0);
    try {
      (void)io::read_volume_info(file);
      ADD_FAILURE() << bad;
    } catch (const Error& err) {
      EXPECT_NE(std::string(err.what()).find("SKEL_HDF5_PROBE_MEMORY_MB must be a number of MiB from 64 to 1048576"),
                std::string::npos)
          << err.what();
    }
  }
  unsetenv("SKEL_HDF5_PROBE_MEMORY_MB");
  EXPECT_EQ(io::read_volume_info(file).dims, (Dims{3, 3, 3}));
  EXPECT_EQ(io::detail::hdf5_probes_started(), before + 2);
  // Values that are not understood are errors, not a silent default.
  io::detail::forget_hdf5_probes();
  ASSERT_EQ(setenv("SKEL_HDF5_PROBE", "yes", 1), 0);
  EXPECT_THROW((void)io::read_volume_info(file), Error);
  unsetenv("SKEL_HDF5_PROBE");
  ASSERT_EQ(setenv("SKEL_HDF5_PROBE_HELPER", "/nonexistent/skelflow-hdf5-probe", 1), 0);
  try {
    (void)io::read_volume_info(file);
    ADD_FAILURE() << "read with a missing helper";
  } catch (const Error& err) {
    EXPECT_NE(std::string(err.what()).find("SKEL_HDF5_PROBE_HELPER=/nonexistent/skelflow-hdf5-probe is not an executable program"),
              std::string::npos)
        << err.what();
  }
  // A helper that does not start (here a program that exits at once, as one whose shared library is
  // missing does) is an error about the helper, not a verdict on the file (before the start-up
  // handshake the file was called damaged: "failed (exit status 1)").
  ASSERT_EQ(setenv("SKEL_HDF5_PROBE_HELPER", "/bin/false", 1), 0);
  try {
    (void)io::read_volume_info(file);
    ADD_FAILURE() << "read with a helper that does not start";
  } catch (const InputError& err) {
    ADD_FAILURE() << "an input error: " << err.what();
  } catch (const Error& err) {
    EXPECT_NE(std::string(err.what()).find("the probe helper /bin/false exited with status 1"), std::string::npos) << err.what();
  }
  unsetenv("SKEL_HDF5_PROBE_HELPER");
  EXPECT_EQ(io::read_volume_info(file).dims, (Dims{3, 3, 3}));
  io::detail::stop_hdf5_probe_worker();
  errno = 0;
  EXPECT_EQ(waitpid(-1, nullptr, WNOHANG), -1);
  EXPECT_EQ(errno, ECHILD);
}
