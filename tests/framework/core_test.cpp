#include <gtest/gtest.h>

#include <algorithm>
#include <atomic>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <memory>
#include <numeric>
#include <vector>

#include "skel/big_vector.hpp"
#include "skel/fs.hpp"
#include "skel/module.hpp"
#include "skel/parallel.hpp"
#include "skel/table.hpp"
#include "skel/volume.hpp"

using namespace skel;

TEST(Volume, IndexingIsXFastest) {
  VolumeU16 v({4, 3, 2}, 0);
  EXPECT_EQ(v.size(), 24);
  v(1, 2, 1) = 7;
  EXPECT_EQ(v[1 + 4 * (2 + 3 * 1)], 7);
  EXPECT_EQ(v.type_id(), "volume.u16");
  EXPECT_EQ(v.bytes(), 48u);
  VolumeU16 c = v;
  EXPECT_EQ(c, v);
  c(0, 0, 0) = 1;
  EXPECT_FALSE(c == v);
}

// Volume::wrap (the Python module's NumPy arrays): the volume reads the owner's memory in place,
// keeps the owner alive while it lives, never frees the memory itself, and copies own a new buffer.
TEST(Volume, WrapsMemoryItDoesNotOwn) {
  auto buffer = std::make_shared<std::vector<float>>(4 * 3 * 2, 1.5f);
  std::weak_ptr<std::vector<float>> alive = buffer;
  float* data = buffer->data();
  {
    VolumeF32 v = VolumeF32::wrap(Grid(Dims{4, 3, 2}, Vec3{0.5, 1, 2}), data, buffer);
    buffer.reset();  // the volume is now the only owner
    EXPECT_FALSE(alive.expired());
    EXPECT_TRUE(v.wraps_external_memory());
    EXPECT_EQ(v.data(), data);
    EXPECT_EQ(v(3, 2, 1), 1.5f);
    v(3, 2, 1) = 7.0f;
    EXPECT_EQ(data[23], 7.0f);  // same memory, x fastest
    VolumeF32 copy = v;
    EXPECT_FALSE(copy.wraps_external_memory());
    EXPECT_NE(copy.data(), data);
    EXPECT_EQ(copy, v);
    VolumeF32 moved = std::move(v);
    EXPECT_EQ(moved.data(), data);
    EXPECT_FALSE(alive.expired());
  }
  EXPECT_TRUE(alive.expired());  // released with the last volume, freed by its owner
  EXPECT_FALSE(VolumeU8(Dims{2, 2, 2}).wraps_external_memory());
  EXPECT_THROW(VolumeU8::wrap(Grid(Dims{2, 2, 2}), nullptr, nullptr), Error);
  EXPECT_THROW(VolumeU8::wrap(Grid(Dims{2, 2, 2}, Vec3{0, 1, 1}), nullptr, nullptr), InputError);
}

TEST(Volume, RejectsBadSpacing) {
  try {
    VolumeU8 v({2, 2, 2}, 0, {1.0, 0.0, 1.0});
    FAIL() << "expected an error";
  } catch (const InputError& e) {
    EXPECT_STREQ(e.what(), "spacing y = 0; expected > 0");
  }
}

TEST(Volume, VisitAndConvert) {
  VolumeF32 f({2, 1, 1}, 2.5f);
  auto u = convert_volume<uint8_t>(f, "input 'x'");
  EXPECT_EQ(u[0], 2);
  EXPECT_EQ(volume_grid(f, "x").dims[0], 2);
  Table t;
  EXPECT_THROW((void)volume_grid(t, "input 'mask'"), InputError);
}

TEST(BigVector, ReleasePagesGivesBackWholePagesOnly) {
  // 4 KiB-aligned buffer of 5 pages: a range inside one page releases nothing; a range over pages
  // 1..3 releases exactly those, which then read as zeros, and leaves pages 0 and 4 as they were.
  constexpr size_t kPage = 4096;
  auto* raw = static_cast<unsigned char*>(std::aligned_alloc(kPage, 5 * kPage));
  ASSERT_NE(raw, nullptr);
  std::fill(raw, raw + 5 * kPage, static_cast<unsigned char>(7));
  EXPECT_EQ(release_pages(raw + 10, 100), 0u);
  EXPECT_EQ(release_pages(raw + kPage - 1, 3 * kPage + 2), 3 * kPage);
  EXPECT_EQ(raw[kPage - 1], 7);
  for (size_t i = kPage; i < 4 * kPage; i += 97) ASSERT_EQ(raw[i], 0) << i;
  EXPECT_EQ(raw[4 * kPage], 7);
  EXPECT_EQ(raw[5 * kPage - 1], 7);
  std::free(raw);
}

TEST(BigVector, GrowReleasingKeepsTheElements) {
  // Several 2 MiB chunks plus a partial one, from a buffer that is not page aligned (the vector's
  // own allocation): every element survives, in order, and the capacity at least doubles.
  for (const size_t n : {size_t{0}, size_t{1}, size_t{1000}, (size_t{5} << 20) / sizeof(uint32_t) + 13}) {
    BigVector<uint32_t> v;
    v.reserve(n);
    for (size_t i = 0; i < n; ++i) v.push_back(static_cast<uint32_t>(i * 2654435761u));
    const size_t cap = v.capacity();
    grow_releasing(v, n + 1);
    ASSERT_EQ(v.size(), n);
    EXPECT_GE(v.capacity(), std::max<size_t>(n + 1, 2 * cap));
    for (size_t i = 0; i < n; ++i) ASSERT_EQ(v[i], static_cast<uint32_t>(i * 2654435761u)) << i;
    v.push_back(5);
    EXPECT_EQ(v.back(), 5u);
    grow_releasing(v, 1);  // fits: nothing changes
    EXPECT_EQ(v.size(), n + 1);
  }
}

TEST(Table, CsvAndTypes) {
  Table t;
  t.add("id", std::vector<int64_t>{1, 2}).add("size", std::vector<double>{0.5, 3}, "µm").add(
      "name", std::vector<std::string>{"a", "b,c"});
  EXPECT_EQ(t.rows(), 2);
  EXPECT_EQ(t.to_csv(), "id,size [µm],name\n1,0.5,a\n2,3,\"b,c\"\n");
  EXPECT_THROW(t.add("x", std::vector<int64_t>{1}), Error);
  EXPECT_THROW((void)t.reals("id"), Error);
}

TEST(Parallel, ChunksCoverRangeOnce) {
  for (int threads : {1, 2, 4}) {
    std::vector<std::atomic<int>> hits(1000);
    parallel_for(0, 1000, threads, [&](int64_t b, int64_t e) {
      for (int64_t i = b; i < e; ++i) hits[static_cast<size_t>(i)]++;
    });
    for (auto& h : hits) EXPECT_EQ(h.load(), 1);
    std::vector<int64_t> sums(7, 0);
    parallel_chunks(0, 1000, 7, threads, [&](int64_t c, int64_t b, int64_t e) {
      for (int64_t i = b; i < e; ++i) sums[static_cast<size_t>(c)] += i;
    });
    EXPECT_EQ(std::accumulate(sums.begin(), sums.end(), int64_t{0}), 999 * 1000 / 2);
  }
}

TEST(Interrupter, SubRangesAndCancel) {
  std::atomic<bool> cancel{false};
  double last = -1;
  Interrupter it([&](double f) { last = f; }, &cancel);
  it.sub(0.5, 1.0).check(0.5);
  EXPECT_DOUBLE_EQ(last, 0.75);
  cancel = true;
  EXPECT_THROW(it.check(), Cancelled);
  EXPECT_NO_THROW(Interrupter{}.check(0.3));
}

TEST(Fs, FailedWriteLeavesNoFile) {
  namespace fs = std::filesystem;
  fs::path dir = fs::temp_directory_path() / "skel_fs_test";
  fs::remove_all(dir);
  fs::path target = dir / "sub" / "out.txt";
  EXPECT_THROW(write_atomically(target,
                                [](const fs::path& tmp) {
                                  std::ofstream(tmp) << "partial";
                                  throw Error("disk full");
                                }),
               Error);
  EXPECT_FALSE(fs::exists(target));
  EXPECT_TRUE(fs::is_empty(dir / "sub"));
  write_atomically(target, [](const fs::path& tmp) { std::ofstream(tmp) << "ok"; });
  EXPECT_TRUE(fs::exists(target));
  fs::remove_all(dir);
}

TEST(ParamSpec, Checks) {
  ModuleSpec s("test.x", "doc");
  s.param<double>("sigma", 1.0, "s").range(0, 10).unit("µm");
  s.choice("shape", {"rods", "plates"}, "rods", "shape");
  s.param<std::vector<int64_t>>("size", {1, 2, 3}, "size").length(3).min(1);
  EXPECT_EQ(s.find_param("sigma")->check(11.0), "value 11 is out of range [0, 10] µm");
  EXPECT_EQ(s.find_param("shape")->check(std::string("tubes")), "'tubes' is not one of: rods plates");
  EXPECT_EQ(s.find_param("size")->check(std::vector<int64_t>{1, 2}), "expected a list of 3 values, got 2");
  EXPECT_EQ(s.find_param("size")->check(std::vector<int64_t>{1, 2, 3}), "");
}
