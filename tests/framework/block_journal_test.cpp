// Per-block resume journals (skel/block_journal.hpp): committed blocks and their writes survive a
// reopen, the block that was running (writes without a commit) and a torn tail are dropped, a
// journal of another stage key starts empty, and for_each_block_resumable skips exactly the kept
// blocks and gives the same volume as an uninterrupted walk; payloads carry in-memory state across
// blocks and passes (a torn payload is cut off).
#include "skel/block_journal.hpp"

#include <gtest/gtest.h>
#include <unistd.h>

#include <cstring>
#include <filesystem>
#include <fstream>
#include <vector>

namespace skel {
namespace {

namespace fs = std::filesystem;

// A volume store in memory (u16 voxels), for the journal's replay.
class MemoryStore final : public VolumeStore {
public:
  explicit MemoryStore(Dims dims) : dims_(dims), data_(static_cast<size_t>(dims[0] * dims[1] * dims[2]), 0) {}
  void read(const Dims& b, const Dims& s, void* out) const override {
    auto* o = static_cast<uint16_t*>(out);
    for (int64_t z = 0; z < s[2]; ++z)
      for (int64_t y = 0; y < s[1]; ++y)
        for (int64_t x = 0; x < s[0]; ++x) *o++ = data_[index(b[0] + x, b[1] + y, b[2] + z)];
  }
  void write(const Dims& b, const Dims& s, const void* in) override {
    const auto* p = static_cast<const uint16_t*>(in);
    for (int64_t z = 0; z < s[2]; ++z)
      for (int64_t y = 0; y < s[1]; ++y)
        for (int64_t x = 0; x < s[0]; ++x) data_[index(b[0] + x, b[1] + y, b[2] + z)] = *p++;
    ++writes;
  }
  [[nodiscard]] const fs::path& file() const override { return file_; }
  [[nodiscard]] const std::vector<uint16_t>& data() const { return data_; }
  int writes = 0;

private:
  [[nodiscard]] size_t index(int64_t x, int64_t y, int64_t z) const {
    return static_cast<size_t>(x + dims_[0] * (y + dims_[1] * z));
  }
  Dims dims_;
  fs::path file_{"memory"};
  std::vector<uint16_t> data_;
};

fs::path journal_file(const std::string& name) {
  return fs::path(SKEL_BINARY_DIR) / "tests" / ("block_journal_" + name + "_" + std::to_string(::getpid()) + ".blocks");
}

// One pass over 3x2x2 blocks of 4x3x5 voxels writing value(block, voxel) into `name`; the walk
// stops (as a kill would) after `stop_after` blocks were computed. Returns the blocks computed.
int64_t walk(BlockJournal* journal, VolumeStore& store, int64_t stop_after) {
  const BlockLayout layout({12, 6, 10}, {4, 3, 5});
  const ScopedBlockJournal scoped(journal);
  int64_t computed = 0;
  struct Stop {};
  try {
    for_each_block_resumable(layout, Interrupter(), "test", [&](const Block& b) {
      std::vector<uint16_t> v(static_cast<size_t>(b.size[0] * b.size[1] * b.size[2]));
      for (size_t k = 0; k < v.size(); ++k)
        v[k] = static_cast<uint16_t>(1000 * (b.index[0] + 3 * b.index[1] + 6 * b.index[2] + 1) + k);
      // Two writes per block: halves of the block, in reverse order.
      Dims half = b.size;
      half[2] = b.size[2] / 2;
      Dims second_begin = b.begin;
      second_begin[2] += half[2];
      Dims second = b.size;
      second[2] -= half[2];
      store.write(second_begin, second, v.data() + half[0] * half[1] * half[2]);
      if (computed == stop_after) throw Stop{};  // killed between the block's writes: not committed
      store.write(b.begin, half, v.data());
      ++computed;
    });
  } catch (const Stop&) {
  }
  return computed;
}

TEST(BlockJournal, KilledWalkResumesFromCommittedBlocksWithTheSameBytes) {
  const fs::path f = journal_file("resume");
  fs::remove(f);
  MemoryStore reference({12, 6, 10});
  EXPECT_EQ(walk(nullptr, reference, -1), 12);

  {
    BlockJournalFile j(f, 42);
    EXPECT_EQ(j.kept_blocks(), 0);
    MemoryStore first({12, 6, 10});
    auto store = j.wrap("out.h5", 2, {12, 6, 10}, std::shared_ptr<VolumeStore>(&first, [](VolumeStore*) {}));
    EXPECT_EQ(walk(&j, *store, 5), 5);  // "killed" in the sixth block
  }
  // A torn record at the end (a kill in the middle of a write): ignored and cut off, with the write
  // of the block that was running (appended, but not committed).
  const auto killed_size = fs::file_size(f);
  {
    std::ofstream out(f, std::ios::binary | std::ios::app);
    out << "W\x07garbage";
  }
  {
    BlockJournalFile j(f, 42);
    EXPECT_EQ(j.kept_blocks(), 5);
    EXPECT_EQ(fs::file_size(f), j.size());
    EXPECT_EQ(killed_size - j.size(), 1 + 8 + 6 + 48 + 8 + 4 * 3 * 3 * 2 + 8);  // the half block's write record
    MemoryStore second({12, 6, 10});
    auto store = j.wrap("out.h5", 2, {12, 6, 10}, std::shared_ptr<VolumeStore>(&second, [](VolumeStore*) {}));
    EXPECT_EQ(second.writes, 10);  // the five kept blocks replayed, two writes each
    MemoryStore other({12, 6, 10});
    (void)j.wrap("other.h5", 2, {12, 6, 10}, std::shared_ptr<VolumeStore>(&other, [](VolumeStore*) {}));
    EXPECT_EQ(other.writes, 0);  // writes of another volume are not replayed into this one
    EXPECT_EQ(walk(&j, *store, 3), 3);  // killed again
  }
  {
    BlockJournalFile j(f, 42);
    EXPECT_EQ(j.kept_blocks(), 8);
    MemoryStore third({12, 6, 10});
    auto store = j.wrap("out.h5", 2, {12, 6, 10}, std::shared_ptr<VolumeStore>(&third, [](VolumeStore*) {}));
    EXPECT_EQ(walk(&j, *store, -1), 4);  // only the blocks not kept are computed
    EXPECT_EQ(third.data(), reference.data());
  }
  // Another stage key (changed parameters): nothing is kept.
  {
    BlockJournalFile j(f, 43);
    EXPECT_EQ(j.kept_blocks(), 0);
    EXPECT_FALSE(j.finished(0, 0));
  }
  fs::remove(f);
}

// Two passes with state carried in memory: pass 0 (for_each_block_resumable with payloads) writes
// each block and commits its voxel sum; pass 1 (a ResumablePass in reverse block order) adds the
// running total of the sums so far and of the blocks before it in pass 1 to every voxel of its
// block. The walk stops after `stop_after` blocks computed over both passes. Returns the total the
// walk ends with (the in-memory state).
struct TwoPass {
  int64_t computed = 0;
  int64_t total = 0;
  bool stopped = false;
};
TwoPass two_passes(BlockJournal* journal, VolumeStore& store, int64_t stop_after) {
  const BlockLayout layout({12, 6, 10}, {4, 3, 5});
  const ScopedBlockJournal scoped(journal);
  TwoPass r;
  struct Stop {};
  auto tick = [&] {
    if (r.computed++ == stop_after) throw Stop{};
  };
  try {
    for_each_block_resumable(
        layout, Interrupter(), "sum",
        [&](const Block& b) {
          tick();
          std::vector<uint16_t> v(static_cast<size_t>(b.size[0] * b.size[1] * b.size[2]));
          int64_t sum = 0;
          for (size_t k = 0; k < v.size(); ++k) sum += v[k] = static_cast<uint16_t>(7 * b.index[0] + 5 * b.index[1] + 3 * b.index[2] + k % 11);
          store.write(b.begin, b.size, v.data());
          r.total += sum;
          return payload_of(sum);
        },
        [&](const Block&, const std::string& p) { r.total += payload_as<int64_t>(p); });
    ResumablePass pass;
    for (int64_t i = layout.total() - 1; i >= 0; --i) {
      const Dims c = layout.count();
      const Block b = layout.at(i % c[0], i / c[0] % c[1], i / (c[0] * c[1]));
      if (const std::string* p = pass.kept(i)) {
        r.total = payload_as<int64_t>(*p);
        continue;
      }
      tick();
      std::vector<uint16_t> v(static_cast<size_t>(b.size[0] * b.size[1] * b.size[2]));
      store.read(b.begin, b.size, v.data());
      for (auto& x : v) x = static_cast<uint16_t>(x + r.total % 1000);
      store.write(b.begin, b.size, v.data());
      r.total += i;
      pass.commit(i, payload_of(r.total));
    }
  } catch (const Stop&) {
    r.stopped = true;
  }
  return r;
}

TEST(BlockJournal, PayloadsCarryStateAcrossPassesAndATornPayloadIsCutOff) {
  const fs::path f = journal_file("payload");
  fs::remove(f);
  MemoryStore reference({12, 6, 10});
  const TwoPass ref = two_passes(nullptr, reference, -1);
  ASSERT_FALSE(ref.stopped);
  EXPECT_EQ(ref.computed, 24);

  {  // killed in the fifth block of pass 1
    BlockJournalFile j(f, 7);
    MemoryStore first({12, 6, 10});
    auto store = j.wrap("out.h5", 2, {12, 6, 10}, std::shared_ptr<VolumeStore>(&first, [](VolumeStore*) {}));
    EXPECT_TRUE(two_passes(&j, *store, 16).stopped);
  }
  // A commit record torn in the middle of its payload (kill -9 while appending it): cut off.
  const auto committed_size = fs::file_size(f);
  {
    std::ofstream out(f, std::ios::binary | std::ios::app);
    const int64_t pass = 1, index = 3;
    const uint64_t length = 8;
    out << 'C';
    out.write(reinterpret_cast<const char*>(&pass), 8).write(reinterpret_cast<const char*>(&index), 8);
    out.write(reinterpret_cast<const char*>(&length), 8) << "abc";
  }
  {
    BlockJournalFile j(f, 7);
    EXPECT_EQ(j.kept_blocks(), 16);  // 12 of pass 0, 4 of pass 1
    EXPECT_EQ(fs::file_size(f), committed_size);
    ASSERT_NE(j.kept(0, 5), nullptr);
    EXPECT_EQ(j.kept(0, 5)->size(), sizeof(int64_t));
    ASSERT_NE(j.kept(1, 8), nullptr);  // pass 1 goes 11, 10, 9, 8: kept
    EXPECT_EQ(j.kept(1, 7), nullptr);  // the block that was running
    EXPECT_FALSE(j.finished(1, 3));    // the torn record
    MemoryStore second({12, 6, 10});
    auto store = j.wrap("out.h5", 2, {12, 6, 10}, std::shared_ptr<VolumeStore>(&second, [](VolumeStore*) {}));
    const TwoPass resumed = two_passes(&j, *store, -1);
    EXPECT_FALSE(resumed.stopped);
    EXPECT_EQ(resumed.computed, 8);  // only the blocks of pass 1 not kept
    EXPECT_EQ(resumed.total, ref.total);
    EXPECT_EQ(second.data(), reference.data());
  }
  // Another stage key: the journal starts over (only its header is left), nothing is kept.
  {
    BlockJournalFile j(f, 8);
    EXPECT_EQ(j.kept_blocks(), 0);
    EXPECT_EQ(j.kept(0, 0), nullptr);
    EXPECT_EQ(fs::file_size(f), std::string("skelflow-blocks 2\n").size() + 8);
  }
  // A journal of the earlier format (version 1) is not read: nothing is kept.
  {
    std::ofstream(f, std::ios::binary | std::ios::trunc) << "skelflow-blocks 1\n" << std::string(8, '\0');
    BlockJournalFile j(f, 0);
    EXPECT_EQ(j.kept_blocks(), 0);
  }
  fs::remove(f);
}

TEST(BlockJournal, BoundedByTwiceTheVolumesAndCompactedWhenAPassBegins) {
  // No lower bound: the journal of the 1440-byte volume holds at most 2 × 1440 bytes and one block
  // (240 bytes: its write and commit records) more. Pass 0 fills it; pass 1 begins by compacting it
  // (the volume and one record committing the 12 blocks), journals four blocks, then keeps its
  // commits in memory: a kill then resumes from the 16 blocks written.
  const fs::path f = journal_file("bounded");
  fs::remove(f);
  MemoryStore reference({12, 6, 10});
  const TwoPass ref = two_passes(nullptr, reference, -1);
  const uint64_t bound = 26 + 2 * 1440 + 240;
  {
    BlockJournalFile j(f, 9, 0);
    MemoryStore first({12, 6, 10});
    auto store = j.wrap("out.h5", 2, {12, 6, 10}, std::shared_ptr<VolumeStore>(&first, [](VolumeStore*) {}));
    EXPECT_TRUE(two_passes(&j, *store, 21).stopped);  // killed in the tenth block of pass 1
    EXPECT_LE(j.size(), bound);
  }
  {
    BlockJournalFile j(f, 9, 0);
    EXPECT_EQ(j.kept_blocks(), 16);
    MemoryStore second({12, 6, 10});
    auto store = j.wrap("out.h5", 2, {12, 6, 10}, std::shared_ptr<VolumeStore>(&second, [](VolumeStore*) {}));
    const TwoPass resumed = two_passes(&j, *store, -1);
    EXPECT_EQ(resumed.computed, 8);
    EXPECT_EQ(resumed.total, ref.total);
    EXPECT_EQ(second.data(), reference.data());
    EXPECT_LE(j.size(), bound);
  }
  fs::remove(f);
}

TEST(BlockJournal, APayloadOfTheWrongSizeIsAnError) {
  EXPECT_EQ(payload_as<int64_t>(payload_of(int64_t{-42})), -42);
  EXPECT_THROW((void)payload_as<int64_t>(std::string("abc")), Error);
}

TEST(BlockJournal, WithoutAJournalEveryBlockRuns) {
  MemoryStore s({12, 6, 10});
  EXPECT_EQ(current_block_journal(), nullptr);
  EXPECT_EQ(walk(nullptr, s, -1), 12);
  EXPECT_EQ(s.writes, 24);
}

}  // namespace
}  // namespace skel
