// Our own decoding of HDF5 chunks on the read path (io/hdf5_chunks.hpp): every stored type, byte
// order and filter combination reads exactly as H5Dread reads it (SKEL_HDF5_OWN_CHUNKS=0), missing
// chunks take the fill value, and a damaged chunk in the middle of a large dataset (the case the
// structure probe does not read) is refused naming the file, the dataset and the chunk.
#include <gtest/gtest.h>
#include <hdf5.h>
#include <zlib.h>

#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <functional>
#include <fstream>
#include <random>
#include <thread>

#include "io/hdf5_chunks.hpp"
#include "io/hdf5_probe.hpp"
#include "io/hdf5_volume.hpp"

namespace fs = std::filesystem;
using namespace skel;

namespace {

fs::path scratch() {
  static fs::path d = [] {
    const auto* info = ::testing::UnitTest::GetInstance()->current_test_info();
    const std::string name = info ? std::string(info->test_suite_name()) + "." + info->name() : "io";
    fs::path p = fs::path(SKEL_BINARY_DIR) / "tests" / "scratch" / "io_chunks" / name;
    fs::remove_all(p);
    fs::create_directories(p);
    return p;
  }();
  return d;
}

std::string error_of(const std::function<void()>& f) {
  try {
    f();
  } catch (const InputError& e) {
    return e.what();
  }
  return "(no InputError)";
}

// Runs f with our chunk decoding off (every read through H5Dread), as before this decoder existed.
template <class F>
auto with_h5dread(F&& f) {
  EXPECT_EQ(setenv("SKEL_HDF5_OWN_CHUNKS", "0", 1), 0);
  struct Restore {
    ~Restore() { unsetenv("SKEL_HDF5_OWN_CHUNKS"); }
  } restore;
  return f();
}

template <class T>
Volume<T> random_volume(Dims d, uint64_t seed) {
  Volume<T> v(d, T{}, {0.5, 0.75, 2.0}, {-3.0, 1.5, 10.0});
  std::mt19937_64 rng(seed);
  for (auto& x : v) x = static_cast<T>(rng() % 200);
  return v;
}

template <class T>
void expect_same(const Volume<T>& a, const Volume<T>& b, const std::string& what) {
  ASSERT_EQ(a.dims(), b.dims()) << what;
  EXPECT_EQ(a.grid().origin, b.grid().origin) << what;
  EXPECT_EQ(std::memcmp(a.data(), b.data(), static_cast<size_t>(a.size()) * sizeof(T)), 0) << what;
}

// A dataset written through libhdf5's own filter pipeline (H5Dwrite), independent of our writer:
// `file_type` as stored (any order), `values` (dims x, y, z, x fastest) given as doubles and written
// through H5T_NATIVE_DOUBLE, chunks (x, y, z); filters in this order: fletcher32, shuffle, deflate.
// When `skip_chunk` is set, that chunk (x, y, z index) is never written (fill value `fill`, if set).
struct RawSpec {
  hid_t file_type = H5T_STD_U8LE;
  Dims dims{1, 1, 1};
  std::array<int64_t, 3> chunks{1, 1, 1};
  bool fletcher = false, shuffle = false;
  int deflate = 0;
  bool fletcher_last = false;  // Fletcher32 after deflate (its checksum then ends the stored chunk)
  const double* fill = nullptr;
  const std::array<int64_t, 3>* skip_chunk = nullptr;
};
void write_raw(const fs::path& file, const RawSpec& s, const std::vector<double>& values) {
  const hid_t f = H5Fcreate(file.c_str(), H5F_ACC_TRUNC, H5P_DEFAULT, H5P_DEFAULT);
  ASSERT_GE(f, 0);
  const hsize_t dims[3] = {static_cast<hsize_t>(s.dims[2]), static_cast<hsize_t>(s.dims[1]), static_cast<hsize_t>(s.dims[0])};
  const hsize_t ch[3] = {static_cast<hsize_t>(s.chunks[2]), static_cast<hsize_t>(s.chunks[1]), static_cast<hsize_t>(s.chunks[0])};
  const hid_t space = H5Screate_simple(3, dims, nullptr);
  const hid_t dcpl = H5Pcreate(H5P_DATASET_CREATE);
  H5Pset_chunk(dcpl, 3, ch);
  if (s.fletcher) H5Pset_fletcher32(dcpl);
  if (s.shuffle) H5Pset_shuffle(dcpl);
  if (s.deflate > 0) H5Pset_deflate(dcpl, static_cast<unsigned>(s.deflate));
  if (s.fletcher_last) H5Pset_fletcher32(dcpl);
  if (s.fill) H5Pset_fill_value(dcpl, H5T_NATIVE_DOUBLE, s.fill);
  const hid_t d = H5Dcreate2(f, "/volume", s.file_type, space, H5P_DEFAULT, dcpl, H5P_DEFAULT);
  ASSERT_GE(d, 0);
  // Chunk by chunk, so that a skipped chunk is never allocated.
  for (int64_t cz = 0; cz * s.chunks[2] < s.dims[2]; ++cz)
    for (int64_t cy = 0; cy * s.chunks[1] < s.dims[1]; ++cy)
      for (int64_t cx = 0; cx * s.chunks[0] < s.dims[0]; ++cx) {
        if (s.skip_chunk && *s.skip_chunk == std::array<int64_t, 3>{cx, cy, cz}) continue;
        const int64_t x0 = cx * s.chunks[0], y0 = cy * s.chunks[1], z0 = cz * s.chunks[2];
        const int64_t wx = std::min(s.chunks[0], s.dims[0] - x0), wy = std::min(s.chunks[1], s.dims[1] - y0),
                      wz = std::min(s.chunks[2], s.dims[2] - z0);
        std::vector<double> part;
        for (int64_t z = 0; z < wz; ++z)
          for (int64_t y = 0; y < wy; ++y)
            for (int64_t x = 0; x < wx; ++x)
              part.push_back(values[static_cast<size_t>(((z0 + z) * s.dims[1] + y0 + y) * s.dims[0] + x0 + x)]);
        const hsize_t start[3] = {static_cast<hsize_t>(z0), static_cast<hsize_t>(y0), static_cast<hsize_t>(x0)};
        const hsize_t count[3] = {static_cast<hsize_t>(wz), static_cast<hsize_t>(wy), static_cast<hsize_t>(wx)};
        H5Sselect_hyperslab(space, H5S_SELECT_SET, start, nullptr, count, nullptr);
        const hid_t mem = H5Screate_simple(3, count, nullptr);
        ASSERT_GE(H5Dwrite(d, H5T_NATIVE_DOUBLE, mem, space, H5P_DEFAULT, part.data()), 0);
        H5Sclose(mem);
      }
  H5Dclose(d);
  H5Pclose(dcpl);
  H5Sclose(space);
  H5Fclose(f);
}

std::vector<double> pattern(Dims d, bool is_signed, double scale, uint64_t seed) {
  std::mt19937_64 rng(seed);
  std::vector<double> v(static_cast<size_t>(d[0] * d[1] * d[2]));
  for (auto& x : v) x = static_cast<double>(rng() % 120) * scale - (is_signed ? 50.0 * scale : 0.0);
  return v;
}

// read_volume / read_box of `file` with our decoding and with H5Dread; equal, and our path taken
// (when `own` is expected) or declined.
template <class T>
void expect_box_paths_agree(const fs::path& file, Dims begin, Dims size, bool own) {
  const int64_t decoded = io::detail::own_chunks_decoded(), declined = io::detail::own_chunk_reads_declined();
  const Volume<T> ours = io::read_box<T>(file, "/volume", begin, size);
  if (own) {
    EXPECT_GT(io::detail::own_chunks_decoded(), decoded) << file;
    EXPECT_EQ(io::detail::own_chunk_reads_declined(), declined) << file;
  } else {
    EXPECT_GT(io::detail::own_chunk_reads_declined(), declined) << file;
  }
  const Volume<T> theirs = with_h5dread([&] { return io::read_box<T>(file, "/volume", begin, size); });
  expect_same(ours, theirs, file.string() + " box");
}

void expect_volume_paths_agree(const fs::path& file, bool own = true) {
  const int64_t decoded = io::detail::own_chunks_decoded();
  const DataPtr ours = io::read_volume(file, "/volume", 2);
  EXPECT_EQ(io::detail::own_chunks_decoded() > decoded, own) << file;
  const DataPtr theirs = with_h5dread([&] { return io::read_volume(file); });
  ASSERT_EQ(ours->type_id(), theirs->type_id()) << file;
  visit_volume(*ours, "v", [&](const auto& a) {
    using V = std::decay_t<decltype(a)>;
    expect_same(a, dynamic_cast<const V&>(*theirs), file.string());
  });
}

}  // namespace

// write_volume's own files (every type, chunk edges not dividing the dims, with and without
// compression, i.e. deflate + shuffle for multi-byte types) read back identical through our decoding,
// and identical to H5Dread, whole and by sub-boxes. Chunked unfiltered files are ours too.
TEST(Hdf5Chunks, EveryTypeRoundTripsIdenticalToH5Dread) {
  auto one = [](auto tag) {
    using T = decltype(tag);
    const auto v = random_volume<T>(Dims{23, 11, 9}, 7);
    for (int level : {0, 1, 6}) {
      const fs::path f = scratch() / ("rt_" + std::string(VoxelTraits<T>::name) + std::to_string(level) + ".h5");
      io::WriteOptions o;
      o.compression = level;
      o.chunks = {5, 4, 3};
      io::write_volume(f, v, "/volume", o);
      const int64_t decoded = io::detail::own_chunks_decoded();  // level 0: unfiltered chunks, ours too
      const DataPtr back = io::read_volume(f);
      EXPECT_EQ(io::detail::own_chunks_decoded() - decoded, 5 * 3 * 3) << f;
      expect_same(dynamic_cast<const Volume<T>&>(*back), v, f.string());
      expect_volume_paths_agree(f);
      expect_box_paths_agree<T>(f, {3, 2, 1}, {17, 7, 7}, true);
      expect_box_paths_agree<T>(f, {22, 10, 8}, {1, 1, 1}, true);
      expect_box_paths_agree<T>(f, {5, 4, 3}, {5, 4, 3}, true);
      expect_box_paths_agree<double>(f, {0, 0, 0}, {23, 11, 9}, true);  // widened like H5Dread
      const int64_t before = io::detail::own_chunks_decoded();
      (void)io::read_box<T>(f, "/volume", {6, 0, 0}, {3, 3, 2});  // touches one chunk only
      EXPECT_EQ(io::detail::own_chunks_decoded() - before, 1) << f;
    }
  };
  one(uint8_t{});
  one(uint16_t{});
  one(uint32_t{});
  one(uint64_t{});
  one(int32_t{});
  one(float{});
  one(double{});
}

// Files written by libhdf5's own pipeline: stored types of both byte orders (big-endian as h5py or
// another machine writes them), shuffle on and off, deflate on and off, Fletcher32, 8- and 16-bit
// signed types (read as int32) and int64 (read as float64): identical to H5Dread. Conversions that
// are not exact (float to integer, narrowing) are declined and read by H5Dread.
TEST(Hdf5Chunks, ByteOrdersFiltersAndConversionsMatchH5Dread) {
  const Dims dims{19, 10, 7};
  struct Case {
    hid_t type;
    bool is_signed;
    double scale;
  };
  const Case cases[] = {{H5T_STD_U8LE, false, 1},   {H5T_STD_I8BE, true, 1},     {H5T_STD_I16LE, true, 100},
                        {H5T_STD_I16BE, true, 100}, {H5T_STD_U16BE, false, 500}, {H5T_STD_U32BE, false, 1e6},
                        {H5T_STD_I32BE, true, 1e6}, {H5T_STD_I64LE, true, 1e9},  {H5T_STD_U64BE, false, 1e12},
                        {H5T_IEEE_F32BE, true, 0.37}, {H5T_IEEE_F64BE, true, 0.37}, {H5T_IEEE_F32LE, true, 0.37}};
  int n = 0;
  for (const Case& c : cases)
    for (int variant = 0; variant < 4; ++variant) {
      RawSpec s;
      s.file_type = c.type;
      s.dims = dims;
      s.chunks = {6, 4, 3};
      s.shuffle = variant & 1;
      s.deflate = variant & 2 ? 3 : 0;
      s.fletcher = variant == 3;
      const fs::path f = scratch() / ("raw_" + std::to_string(n++) + ".h5");
      write_raw(f, s, pattern(dims, c.is_signed, c.scale, static_cast<uint64_t>(n)));
      SCOPED_TRACE(f.string());
      // Every variant is decoded by us, the unfiltered one (0) too.
      expect_volume_paths_agree(f);
      expect_box_paths_agree<double>(f, {1, 3, 2}, {17, 6, 5}, true);
      const size_t size = H5Tget_size(c.type);
      const bool is_float = H5Tget_class(c.type) == H5T_FLOAT;
      // Float to integer and narrowing integer conversions stay with H5Dread.
      expect_box_paths_agree<uint8_t>(f, {0, 0, 0}, dims, !is_float && !c.is_signed && size == 1);
      expect_box_paths_agree<int32_t>(f, {2, 1, 0}, {10, 9, 7}, !is_float && (c.is_signed ? size <= 4 : size < 4));
    }
}

// Chunks never written take the dataset's fill value (a user-defined one, and 0 by default), as
// H5Dread gives them; the chunk's stored filter mask is honoured (a chunk stored unfiltered in a
// deflated dataset, as HDF5 does when deflate would not shrink it).
TEST(Hdf5Chunks, MissingChunksTakeTheFillValueAndFilterMasksAreHonoured) {
  const Dims dims{13, 9, 8};
  const std::array<int64_t, 3> skip{1, 1, 1};
  const double fill = 42;
  for (int with_fill = 0; with_fill < 2; ++with_fill) {
    RawSpec s;
    s.file_type = H5T_STD_U16BE;
    s.dims = dims;
    s.chunks = {5, 4, 3};
    s.shuffle = true;
    s.deflate = 1;
    s.fill = with_fill ? &fill : nullptr;
    s.skip_chunk = &skip;
    const fs::path f = scratch() / ("missing_" + std::to_string(with_fill) + ".h5");
    write_raw(f, s, pattern(dims, false, 300, 5));
    expect_volume_paths_agree(f);
    const auto v = dynamic_cast<const VolumeU16&>(*io::read_volume(f));
    EXPECT_EQ(v(5, 4, 3), with_fill ? 42 : 0);
    EXPECT_EQ(v(9, 7, 5), with_fill ? 42 : 0);
    expect_box_paths_agree<uint16_t>(f, {4, 3, 2}, {3, 3, 3}, true);
  }
  // Block-wise files with blocks left unwritten (create_volume_dataset + write_box): zeros.
  const fs::path blocks = scratch() / "blocks.h5";
  io::WriteOptions o;
  o.chunks = {4, 4, 4};
  o.compression = 1;
  io::create_volume_dataset(blocks, "/volume", "float32", Grid(Dims{10, 9, 8}), o);
  io::write_box(blocks, "/volume", random_volume<float>({4, 4, 4}, 3), {4, 4, 0});
  expect_volume_paths_agree(blocks);
  EXPECT_EQ(dynamic_cast<const VolumeF32&>(*io::read_volume(blocks))(0, 0, 7), 0.0f);

  // A uint16 dataset with shuffle + deflate whose chunk (1, 0, 0) is stored shuffled but not deflated
  // (filter mask bit 1: the second filter skipped).
  const fs::path masked = scratch() / "masked.h5";
  {
    RawSpec s;
    s.file_type = H5T_STD_U16LE;
    s.dims = {8, 4, 2};
    s.chunks = {4, 4, 2};
    s.shuffle = true;
    s.deflate = 1;
    write_raw(masked, s, pattern(s.dims, false, 300, 9));
    const hid_t f = H5Fopen(masked.c_str(), H5F_ACC_RDWR, H5P_DEFAULT);
    const hid_t d = H5Dopen2(f, "/volume", H5P_DEFAULT);
    std::vector<uint16_t> chunk(32);
    for (size_t i = 0; i < chunk.size(); ++i) chunk[i] = static_cast<uint16_t>(1000 + 7 * i);
    std::vector<unsigned char> shuffled(64);
    for (size_t i = 0; i < 32; ++i) {
      shuffled[i] = static_cast<unsigned char>(chunk[i] & 0xff);
      shuffled[32 + i] = static_cast<unsigned char>(chunk[i] >> 8);
    }
    const hsize_t offset[3] = {0, 0, 4};
    ASSERT_GE(H5Dwrite_chunk(d, H5P_DEFAULT, 0x2, offset, shuffled.size(), shuffled.data()), 0);
    H5Dclose(d);
    H5Fclose(f);
  }
  expect_volume_paths_agree(masked);
  EXPECT_EQ(dynamic_cast<const VolumeU16&>(*io::read_volume(masked))(5, 0, 0), 1007);
}

// Filters we do not decode (here nbit, built into libhdf5) keep H5Dread.
TEST(Hdf5Chunks, OtherFiltersAreReadByH5Dread) {
  const fs::path f = scratch() / "nbit.h5";
  const Dims dims{9, 8, 7};
  const auto values = pattern(dims, false, 1, 4);
  {
    const hid_t file = H5Fcreate(f.c_str(), H5F_ACC_TRUNC, H5P_DEFAULT, H5P_DEFAULT);
    const hsize_t hd[3] = {7, 8, 9}, hc[3] = {3, 4, 4};
    const hid_t space = H5Screate_simple(3, hd, nullptr);
    const hid_t dcpl = H5Pcreate(H5P_DATASET_CREATE);
    H5Pset_chunk(dcpl, 3, hc);
    H5Pset_nbit(dcpl);
    const hid_t type = H5Tcopy(H5T_STD_U16LE);
    H5Tset_precision(type, 9);
    const hid_t d = H5Dcreate2(file, "/volume", type, space, H5P_DEFAULT, dcpl, H5P_DEFAULT);
    ASSERT_GE(H5Dwrite(d, H5T_NATIVE_DOUBLE, H5S_ALL, H5S_ALL, H5P_DEFAULT, values.data()), 0);
    H5Dclose(d);
    H5Tclose(type);
    H5Pclose(dcpl);
    H5Sclose(space);
    H5Fclose(file);
  }
  const int64_t declined = io::detail::own_chunk_reads_declined();
  const auto v = dynamic_cast<const VolumeU16&>(*io::read_volume(f));
  EXPECT_GT(io::detail::own_chunk_reads_declined(), declined);
  EXPECT_EQ(v(3, 2, 1), static_cast<uint16_t>(values[(1 * 8 + 2) * 9 + 3]));
}

namespace {

// A uint8 deflated dataset of `dims` with chunks `chunk`, every chunk zeros except the ones the
// writer puts in with H5Dwrite_chunk (the way the fuzzer's mutations damage chunks): chunk `bad`
// (x, y, z index) holds `bad_bytes` (compressed by the caller).
void write_with_bad_chunk(const fs::path& file, Dims dims, std::array<int64_t, 3> chunk, std::array<int64_t, 3> bad,
                          const std::vector<unsigned char>& bad_bytes) {
  const hid_t f = H5Fcreate(file.c_str(), H5F_ACC_TRUNC, H5P_DEFAULT, H5P_DEFAULT);
  const hsize_t hd[3] = {static_cast<hsize_t>(dims[2]), static_cast<hsize_t>(dims[1]), static_cast<hsize_t>(dims[0])};
  const hsize_t hc[3] = {static_cast<hsize_t>(chunk[2]), static_cast<hsize_t>(chunk[1]), static_cast<hsize_t>(chunk[0])};
  const hid_t space = H5Screate_simple(3, hd, nullptr);
  const hid_t dcpl = H5Pcreate(H5P_DATASET_CREATE);
  H5Pset_chunk(dcpl, 3, hc);
  H5Pset_deflate(dcpl, 1);
  const hid_t d = H5Dcreate2(f, "/volume", H5T_STD_U8LE, space, H5P_DEFAULT, dcpl, H5P_DEFAULT);
  ASSERT_GE(d, 0);
  const size_t bytes = static_cast<size_t>(chunk[0] * chunk[1] * chunk[2]);
  std::vector<unsigned char> zeros(bytes, 7), good(compressBound(static_cast<uLong>(bytes)));
  uLongf n = good.size();
  ASSERT_EQ(compress2(good.data(), &n, zeros.data(), static_cast<uLong>(bytes), 1), Z_OK);
  good.resize(n);
  for (int64_t z = 0; z * chunk[2] < dims[2]; ++z)
    for (int64_t y = 0; y * chunk[1] < dims[1]; ++y)
      for (int64_t x = 0; x * chunk[0] < dims[0]; ++x) {
        const hsize_t offset[3] = {static_cast<hsize_t>(z * chunk[2]), static_cast<hsize_t>(y * chunk[1]),
                                   static_cast<hsize_t>(x * chunk[0])};
        const auto& b = std::array<int64_t, 3>{x, y, z} == bad ? bad_bytes : good;
        ASSERT_GE(H5Dwrite_chunk(d, H5P_DEFAULT, 0, offset, b.size(), b.data()), 0);
      }
  H5Dclose(d);
  H5Pclose(dcpl);
  H5Sclose(space);
  H5Fclose(f);
}

std::vector<unsigned char> deflated(size_t bytes) {
  std::vector<unsigned char> raw(bytes, 7), out(compressBound(static_cast<uLong>(bytes)));
  uLongf n = out.size();
  compress2(out.data(), &n, raw.data(), static_cast<uLong>(bytes), 1);
  out.resize(n);
  return out;
}

}  // namespace

// A deflated chunk that inflates to fewer or more bytes than a chunk holds, or does not inflate, in
// the middle of a dataset larger than the 64 MiB the structure probe reads whole (it reads only the
// first and last chunk there): refused naming the file, the dataset and the chunk, in this process,
// with the probe on and off. Before: libhdf5 copied out of the short buffer (a heap over-read, a crash
// under AddressSanitizer) or read it silently. Boxes that do not touch the chunk still read.
TEST(Hdf5Chunks, DamagedMiddleChunkOfALargeDatasetIsRefusedNamingIt) {
  const Dims dims{512, 512, 260};  // 65 MiB of uint8 (the file: ~90 KiB)
  const std::array<int64_t, 3> chunk{128, 128, 64}, bad{1, 2, 2};
  const size_t bytes = 128 * 128 * 64;
  struct Damage {
    std::string name;
    std::vector<unsigned char> stored;
    std::string says;
  };
  std::vector<unsigned char> garbage(2000);  // more than 1/1100 of the chunk: not refused by the ratio alone
  for (size_t i = 0; i < garbage.size(); ++i) garbage[i] = static_cast<unsigned char>(i * 37 + 11);
  const Damage damages[] = {
      {"short", deflated(bytes - 1000), "inflates to " + std::to_string(bytes - 1000) + " bytes, not the " + std::to_string(bytes)},
      {"long", deflated(bytes + 4096), "inflates to more than the " + std::to_string(bytes) + " bytes of a chunk"},
      {"garbage", garbage, "cannot be inflated"},
  };
  for (const Damage& dmg : damages) {
    const fs::path f = scratch() / ("bad_" + dmg.name + ".h5");
    write_with_bad_chunk(f, dims, chunk, bad, dmg.stored);
    ASSERT_LT(fs::file_size(f), 1u << 20);
    for (const char* probe : {"1", "0"}) {
      SCOPED_TRACE(f.string() + " probe " + probe);
      if (std::string(probe) == "0") {
        ASSERT_EQ(setenv("SKEL_HDF5_PROBE", "0", 1), 0);
      }
      io::detail::forget_hdf5_probes();
      const std::string what = error_of([&] { (void)io::read_volume(f); });
      EXPECT_EQ(what.rfind(f.string() + ": dataset '/volume': chunk (1, 2, 2) (x, y, z; its first voxel (128, 256, 128)) ", 0), 0u)
          << what;
      EXPECT_NE(what.find(dmg.says), std::string::npos) << what;
      EXPECT_NE(what.find("the file is damaged"), std::string::npos) << what;
      EXPECT_NE(error_of([&] { (void)io::read_box<uint8_t>(f, "/volume", {200, 300, 150}, {10, 10, 10}); }).find("chunk (1, 2, 2)"),
                std::string::npos);
      const VolumeU8 fine = io::read_box<uint8_t>(f, "/volume", {0, 0, 0}, {128, 256, 260});
      EXPECT_EQ(fine(127, 255, 259), 7);
      unsetenv("SKEL_HDF5_PROBE");
    }
  }
}

// Fletcher32 (with shuffle + deflate, written by libhdf5's pipeline): read identical to H5Dread;
// a chunk whose stored checksum does not match is refused naming it (H5Dread: a generic error).
TEST(Hdf5Chunks, Fletcher32IsCheckedAndAMismatchIsRefusedNamingTheChunk) {
  RawSpec s;
  s.file_type = H5T_STD_I32LE;
  s.dims = {8, 8, 8};
  s.chunks = {4, 4, 4};
  s.fletcher = s.shuffle = true;
  s.deflate = 2;
  write_raw(scratch() / "fletcher_first.h5", s, pattern(s.dims, true, 1000, 3));
  expect_volume_paths_agree(scratch() / "fletcher_first.h5");
  s.fletcher = false;
  s.fletcher_last = true;  // the checksum of the deflated bytes ends each stored chunk
  const fs::path f = scratch() / "fletcher.h5";
  write_raw(f, s, pattern(s.dims, true, 1000, 3));
  expect_volume_paths_agree(f);
  {
    const hid_t file = H5Fopen(f.c_str(), H5F_ACC_RDWR, H5P_DEFAULT);
    const hid_t d = H5Dopen2(file, "/volume", H5P_DEFAULT);
    const hsize_t offset[3] = {4, 0, 4};
    hsize_t n = 0;
    ASSERT_GE(H5Dget_chunk_storage_size(d, offset, &n), 0);
    std::vector<unsigned char> raw(n);
    uint32_t mask = 0;
    ASSERT_GE(H5Dread_chunk(d, H5P_DEFAULT, offset, &mask, raw.data()), 0);
    raw[n - 2] ^= 0x5a;  // the checksum (the last 4 bytes)
    ASSERT_GE(H5Dwrite_chunk(d, H5P_DEFAULT, mask, offset, n, raw.data()), 0);
    H5Dclose(d);
    H5Fclose(file);
  }
  const std::string what = error_of([&] { (void)io::read_volume(f); });
  EXPECT_EQ(what.rfind(f.string() + ": dataset '/volume': chunk (1, 0, 1) ", 0), 0u) << what;
  EXPECT_NE(what.find("fails its Fletcher32 checksum"), std::string::npos) << what;
}

namespace {
uint64_t peak_rss_bytes() {
  std::ifstream in("/proc/self/status");
  std::string line;
  while (std::getline(in, line))
    if (line.rfind("VmHWM:", 0) == 0) return std::stoull(line.substr(6)) << 10;
  return 0;
}
}  // namespace

// A chunk shape of 1.8 GB (allowed with unlimited dims) whose stored bytes are a few dozen (libFuzzer,
// session 9: the decoder zero-filled a 1.8 GB buffer before it inflated, and the fuzzer's process
// went past its 2 GB RSS limit): deflate expands at most ~1032:1, so the chunk is refused before any
// buffer is allocated. Before: "inflates to 100 bytes, not the 1811939328" after touching 1.8 GB.
TEST(Hdf5Chunks, AChunkClaimingMoreThanDeflateCanExpandIsRefusedBeforeAllocating) {
  const fs::path file = scratch() / "huge_chunk.h5";
  const hid_t f = H5Fcreate(file.c_str(), H5F_ACC_TRUNC, H5P_DEFAULT, H5P_DEFAULT);
  const hsize_t dims[3] = {3, 3, 515}, max[3] = {H5S_UNLIMITED, H5S_UNLIMITED, H5S_UNLIMITED};
  const hsize_t chunk[3] = {3, 50331648, 3};
  const hid_t space = H5Screate_simple(3, dims, max);
  const hid_t dcpl = H5Pcreate(H5P_DATASET_CREATE);
  H5Pset_chunk(dcpl, 3, chunk);
  H5Pset_deflate(dcpl, 1);
  const hid_t d = H5Dcreate2(f, "/volume", H5T_STD_U32LE, space, H5P_DEFAULT, dcpl, H5P_DEFAULT);
  ASSERT_GE(d, 0);
  const std::vector<unsigned char> stored = deflated(100);
  const hsize_t offset[3] = {0, 0, 0};
  ASSERT_GE(H5Dwrite_chunk(d, H5P_DEFAULT, 0, offset, stored.size(), stored.data()), 0);
  H5Dclose(d);
  H5Pclose(dcpl);
  H5Sclose(space);
  H5Fclose(f);
  const uint64_t before = peak_rss_bytes();
  const std::string what = error_of([&] { (void)io::read_box<uint32_t>(file, "/volume", {0, 0, 0}, {3, 3, 3}); });
  EXPECT_NE(what.find("chunk (0, 0, 0)"), std::string::npos) << what;
  EXPECT_NE(what.find("claims 1811939328 bytes but is stored in " + std::to_string(stored.size()) +
                      ", more than deflate can expand"),
            std::string::npos)
      << what;
  EXPECT_LT(peak_rss_bytes(), before + (uint64_t{256} << 20));
}

// Debian's libhdf5 is thread-safe, with its error printing set per thread: a read on a thread other
// than the first one to read printed HDF5's error stack on stderr (the decoder's workers, a
// pipeline's node threads). Before: "HDF5-DIAG: Error detected in HDF5 (1.10.8) thread 2: ...".
TEST(Hdf5Chunks, NoThreadPrintsHdf5ErrorStacks) {
  const fs::path file = scratch() / "plain.h5";
  io::write_volume(file, random_volume<uint8_t>({4, 4, 4}, 1));
  const hid_t f = H5Fopen(file.c_str(), H5F_ACC_RDWR, H5P_DEFAULT);
  H5Gclose(H5Gcreate2(f, "/group", H5P_DEFAULT, H5P_DEFAULT, H5P_DEFAULT));
  H5Fclose(f);
  (void)io::read_volume(file);  // this thread first
  ::testing::internal::CaptureStderr();
  std::string what;
  // H5Dopen2 of a group fails inside libhdf5 (an error stack).
  std::thread other([&] { what = error_of([&] { (void)io::read_volume(file, "/group"); }); });
  other.join();
  const std::string printed = ::testing::internal::GetCapturedStderr();
  EXPECT_NE(what.find("'/group' is not a dataset"), std::string::npos) << what;
  EXPECT_EQ(printed, "");
}
