// Out-of-core building blocks: memory sizes, the pipeline's `execution:` section, block layouts,
// the block size chosen from a budget, and ChunkedVolume over an in-memory store.
#include <gtest/gtest.h>

#include <cstring>
#include <map>

#include "skel/out_of_core.hpp"
#include "skel/pipeline.hpp"

namespace skel {
namespace {

std::string error_of(const std::function<void()>& f) {
  try {
    f();
  } catch (const InputError& e) {
    return e.what();
  }
  return "(no InputError)";
}

TEST(ByteSize, UnitsAndNumbers) {
  EXPECT_EQ(parse_byte_size("512MiB", "x"), 512ull << 20);
  EXPECT_EQ(parse_byte_size("2GiB", "x"), 2ull << 30);
  EXPECT_EQ(parse_byte_size("1.5GB", "x"), 1500000000ull);
  EXPECT_EQ(parse_byte_size("1048576", "x"), 1048576ull);
  EXPECT_EQ(parse_byte_size("64 kib", "x"), 65536ull);
  EXPECT_EQ(parse_byte_size("3TB", "x"), 3000000000000ull);
  EXPECT_EQ(format_byte_size(2ull << 30), "2 GiB");
  EXPECT_EQ(format_byte_size(1536ull << 20), "1.5 GiB");
  EXPECT_EQ(format_byte_size(300), "300 B");
}

TEST(ByteSize, ErrorsNameTheOption) {
  EXPECT_EQ(error_of([] { parse_byte_size("2XB", "--memory-budget"); }),
            "--memory-budget: unknown unit 'XB' in '2XB' (expected a size such as 512MiB, 2GiB or 1.5GB)");
  EXPECT_EQ(error_of([] { parse_byte_size("GiB", "--memory-budget"); }),
            "--memory-budget: 'GiB' is not a memory size (expected a size such as 512MiB, 2GiB or 1.5GB)");
  EXPECT_EQ(error_of([] { parse_byte_size("-1GiB", "--memory-budget"); }),
            "--memory-budget: '-1GiB' is not a memory size (expected a size such as 512MiB, 2GiB or 1.5GB)");
  EXPECT_EQ(error_of([] { parse_byte_size("0", "--memory-budget"); }),
            "--memory-budget: '0' is no memory at all (expected a size such as 512MiB, 2GiB or 1.5GB)");
  EXPECT_EQ(error_of([] { parse_byte_size("1.2.3MiB", "m"); }),
            "m: '1.2.3MiB' is not a memory size (expected a size such as 512MiB, 2GiB or 1.5GB)");
}

TEST(ExecutionSection, ParsedSavedAndCompared) {
  const std::string text = "skelflow: 1\nnodes: {}\nexecution: {memory_budget: 2GiB, block: [16, 13, 11]}\n";
  Pipeline p = Pipeline::parse(text, "p.yaml");
  EXPECT_EQ(p.execution().memory_budget, 2ull << 30);
  EXPECT_EQ(p.execution().block, (Dims{16, 13, 11}));
  EXPECT_EQ(p.execution().memory_budget_pos.line, 3);
  const Pipeline q = Pipeline::parse(p.to_yaml(), "q.yaml");
  EXPECT_EQ(q.execution().memory_budget, 2ull << 30);
  EXPECT_EQ(q.execution().block, (Dims{16, 13, 11}));
  EXPECT_NE(p.to_yaml().find("memory_budget: 2GiB"), std::string::npos) << p.to_yaml();
  EXPECT_TRUE(p == q);
  EXPECT_FALSE(p == Pipeline::parse("skelflow: 1\nnodes: {}\n", "r.yaml"));
  // No section: nothing saved, no budget.
  const Pipeline none = Pipeline::parse("skelflow: 1\nnodes: {}\n", "n.yaml");
  EXPECT_TRUE(none.execution().empty());
  EXPECT_EQ(none.to_yaml().find("execution"), std::string::npos);
}

TEST(ExecutionSection, ErrorsAtLineAndColumn) {
  EXPECT_EQ(error_of([] { Pipeline::parse("skelflow: 1\nnodes: {}\nexecution:\n  memory_budget: 2 parsecs\n", "p.yaml"); }),
            "p.yaml:4:18: execution: memory_budget: unknown unit 'parsecs' in '2 parsecs' (expected a size such as "
            "512MiB, 2GiB or 1.5GB)");
  EXPECT_EQ(error_of([] { Pipeline::parse("skelflow: 1\nnodes: {}\nexecution: {block: [16, 0, 8]}\n", "p.yaml"); }),
            "p.yaml:3:25: execution: block must be a list of three whole numbers >= 1 (x, y, z), e.g. [64, 64, 64]");
  EXPECT_EQ(error_of([] { Pipeline::parse("skelflow: 1\nnodes: {}\nexecution: {block: [16, 8]}\n", "p.yaml"); }),
            "p.yaml:3:20: execution: block must be a list of three whole numbers >= 1 (x, y, z), e.g. [64, 64, 64]");
  EXPECT_EQ(error_of([] { Pipeline::parse("skelflow: 1\nnodes: {}\nexecution: {budget: 1GiB}\n", "p.yaml"); }),
            "p.yaml:3:13: execution: unknown key 'budget' (expected memory_budget, block)");
  EXPECT_EQ(error_of([] { Pipeline::parse("skelflow: 1\nnodes: {}\nexecution: 2GiB\n", "p.yaml"); }),
            "p.yaml:3:12: 'execution' must be a mapping (memory_budget, block)");
}

TEST(BlockLayout, CoversTheGridOnceWithClippedHalos) {
  const BlockLayout l({23, 19, 17}, {13, 17, 11}, 2);
  EXPECT_EQ(l.count(), (Dims{2, 2, 2}));
  std::vector<int> covered(23 * 19 * 17, 0);
  for (int64_t bz = 0; bz < 2; ++bz)
    for (int64_t by = 0; by < 2; ++by)
      for (int64_t bx = 0; bx < 2; ++bx) {
        const Block b = l.at(bx, by, bz);
        for (int k = 0; k < 3; ++k) {
          EXPECT_GE(b.outer_begin[k], 0);
          EXPECT_LE(b.outer_begin[k] + b.outer_size[k], l.dims[k]);
          EXPECT_EQ(b.outer_begin[k], std::max<int64_t>(0, b.begin[k] - 2));
        }
        for (int64_t z = b.begin[2]; z < b.begin[2] + b.size[2]; ++z)
          for (int64_t y = b.begin[1]; y < b.begin[1] + b.size[1]; ++y)
            for (int64_t x = b.begin[0]; x < b.begin[0] + b.size[0]; ++x) ++covered[static_cast<size_t>(x + 23 * (y + 19 * z))];
      }
  for (int c : covered) EXPECT_EQ(c, 1);
  EXPECT_EQ(l.at(1, 1, 1).size, (Dims{10, 2, 6}));
}

TEST(BlockLayout, BlockSizeFromBudget) {
  // 256 MiB, 5 bytes per voxel, halo 1: (e + 2)³ · 5 <= 64 MiB -> e = 232 (a multiple of 8).
  EXPECT_EQ(block_for_budget(256ull << 20, 1, 5, {1000, 1000, 1000}), (Dims{232, 232, 232}));
  // Tiny budgets still give 16³ blocks (the floor), and never larger than the grid needs.
  EXPECT_EQ(block_for_budget(1024, 0, 9, {100, 100, 100}), (Dims{16, 16, 16}));
  EXPECT_EQ(block_for_budget(1ull << 40, 0, 1, {40, 30, 20}), (Dims{40, 40, 40}));
}

TEST(BlockLayout, ScratchChunksDivideTheBlock) {
  // The largest divisor up to 32 (so a block interior is whole chunks): 72 -> 24, 232 -> 29, 160 -> 32.
  EXPECT_EQ(scratch_chunk({72, 232, 160}), (Dims{24, 29, 32}));
  // Blocks up to 32 are one chunk; an edge whose divisors up to 32 are all below 16 keeps 32 (no
  // chunks of 8³: 376 = 8 · 47).
  EXPECT_EQ(scratch_chunk({13, 1, 37}), (Dims{13, 1, 32}));
  EXPECT_EQ(scratch_chunk({376, 472, 16}), (Dims{32, 32, 16}));
  for (int64_t e = 16; e <= 1024; e += 8) {
    const Dims c = scratch_chunk({e, e, e});
    EXPECT_TRUE(e % c[0] == 0 || c[0] == 32) << e;
    EXPECT_GE(c[0], 16) << e;
    EXPECT_LE(c[0], 32) << e;
  }
}

// A store in memory, to test ChunkedVolume without a file format.
class MemoryStore final : public VolumeStore {
public:
  MemoryStore(const Grid& g, int64_t voxel) : g_(g), voxel_(voxel), data_(static_cast<size_t>(g.voxel_count() * voxel), 0) {}
  void read(const Dims& b, const Dims& s, void* out) const override {
    auto* o = static_cast<char*>(out);
    for (int64_t z = 0; z < s[2]; ++z)
      for (int64_t y = 0; y < s[1]; ++y, o += s[0] * voxel_)
        std::memcpy(o, data_.data() + g_.index(b[0], b[1] + y, b[2] + z) * voxel_, static_cast<size_t>(s[0] * voxel_));
  }
  void write(const Dims& b, const Dims& s, const void* in) override {
    auto* i = static_cast<const char*>(in);
    for (int64_t z = 0; z < s[2]; ++z)
      for (int64_t y = 0; y < s[1]; ++y, i += s[0] * voxel_)
        std::memcpy(data_.data() + g_.index(b[0], b[1] + y, b[2] + z) * voxel_, i, static_cast<size_t>(s[0] * voxel_));
  }
  [[nodiscard]] const std::filesystem::path& file() const override { return file_; }

private:
  Grid g_;
  int64_t voxel_;
  std::vector<char> data_;
  std::filesystem::path file_ = "memory";
};

TEST(ChunkedVolume, BlocksRoundTripAndMaterialize) {
  const Grid g({7, 5, 3}, {0.5, 1, 2}, {10, 20, 30});
  auto c = std::make_shared<ChunkedVolume>(g, type_ids::volume_u16, std::make_shared<MemoryStore>(g, 2));
  EXPECT_EQ(c->type_id(), "volume.u16");
  EXPECT_EQ(c->bytes(), 0u);
  EXPECT_EQ(c->voxel_data_bytes(), 7u * 5 * 3 * 2);
  VolumeU16 ref(g);
  for (int64_t i = 0; i < ref.size(); ++i) ref[i] = static_cast<uint16_t>(i * 7 + 1);
  const BlockLayout l(g.dims, {3, 2, 2});
  for (int64_t bz = 0; bz < l.count()[2]; ++bz)
    for (int64_t by = 0; by < l.count()[1]; ++by)
      for (int64_t bx = 0; bx < l.count()[0]; ++bx) {
        const Block b = l.at(bx, by, bz);
        c->write(read_block<uint16_t>(ref, b.begin, b.size, "ref"), b.begin);
      }
  DataPtr whole = materialize(c);
  EXPECT_TRUE(dynamic_cast<const VolumeU16&>(*whole) == ref);
  const VolumeU16 box = c->read<uint16_t>({2, 1, 1}, {3, 3, 2});
  EXPECT_EQ(box(0, 0, 0), ref(2, 1, 1));
  EXPECT_EQ(box.origin(), (Vec3{11, 21, 32}));
  EXPECT_THROW((void)c->read<uint8_t>({0, 0, 0}, {1, 1, 1}), Error);
  EXPECT_THROW((void)c->read<uint16_t>({5, 0, 0}, {3, 1, 1}), Error);
  EXPECT_EQ(any_volume_grid(*c, "x"), g);
  EXPECT_TRUE(is_on_disk(*c));
  EXPECT_FALSE(is_on_disk(ref));
}

}  // namespace
}  // namespace skel
