#pragma once
// Per-block resume of out-of-core stages (`skelflow run --resume`, docs/architecture.md
// "Out-of-core execution"). A stage whose blocks are independent — each block reads only the
// stage's inputs and writes only its own part of the outputs, and nothing is carried in memory from
// one block to the next — walks its blocks with for_each_block_resumable instead of for_each_block.
// In a resumable run the executor gives such a stage a journal: every write to its scratch
// volumes is recorded, and after each block the block's writes and a commit record are appended to
// `<node>.blocks` in the resume folder (bounded by twice the volumes' bytes: block_journal.cpp). A run killed with kill -9 and started
// again with --resume replays the committed writes into the new scratch volumes and skips the
// committed blocks, so the stage's outputs are the bytes of an uninterrupted run. Stages with
// several passes, blocks in an order of their own, or state carried in memory from block to block
// use ResumablePass and commit that state with each block as a payload (below).
#include <cstdint>
#include <cstring>
#include <filesystem>
#include <memory>
#include <string>
#include <string_view>
#include <type_traits>

#include "skel/error.hpp"
#include "skel/out_of_core.hpp"

namespace skel {

class BlockJournal {
public:
  virtual ~BlockJournal() = default;
  // Starts the next resumable pass of the stage; returns its number (0, 1, ...).
  virtual int64_t begin_pass() = 0;
  // The payload committed with block `index` of pass `pass` by an earlier run, or null when that
  // block was not committed (it is to run).
  [[nodiscard]] virtual const std::string* kept(int64_t pass, int64_t index) const = 0;
  // True when block `index` of pass `pass` was committed by an earlier run.
  [[nodiscard]] bool finished(int64_t pass, int64_t index) const { return kept(pass, index) != nullptr; }
  // Records the writes since the last commit together with the record that block `index` of pass
  // `pass` is finished (appended with write(): kept through kill -9), and `payload`: what the block leaves in memory for the blocks after it
  // (a count, the blocks it marks for another pass), given back by kept() when the run is resumed.
  virtual void commit(int64_t pass, int64_t index, std::string_view payload) = 0;
};

// The journal of the stage running on this thread (set by the executor), or null.
BlockJournal* current_block_journal();
// Sets it for the lifetime of the object (the executor, around a block-wise stage's run()).
class ScopedBlockJournal {
public:
  explicit ScopedBlockJournal(BlockJournal* journal);
  ~ScopedBlockJournal();
  ScopedBlockJournal(const ScopedBlockJournal&) = delete;
  ScopedBlockJournal& operator=(const ScopedBlockJournal&) = delete;

private:
  BlockJournal* previous_;
};

// One resumable pass over blocks in an order of the stage's own (chamfer's scans, thinning's
// revisits). The rule that makes a resumed stage the bytes of an uninterrupted one: the state the
// blocks carry from one to the next is the stage's scratch volumes (replayed) plus the payloads of
// the committed blocks; every pass that writes or reads the stage's scratch volumes is a resumable
// pass, visits its blocks in an order that depends only on the inputs, the parameters and earlier
// payloads, and a block's index means the same block in every run. Passes that only read the
// stage's inputs (Otsu's histogram, slice statistics) may be plain for_each_block: they run again.
class ResumablePass {
public:
  // Begins a pass of the current journal (none: every block runs, nothing is recorded).
  ResumablePass() : journal_(current_block_journal()), pass_(journal_ ? journal_->begin_pass() : -1) {}
  // The payload block `index` committed in an earlier run (skip the block, apply its payload), or
  // null: run it.
  [[nodiscard]] const std::string* kept(int64_t index) const { return journal_ ? journal_->kept(pass_, index) : nullptr; }
  void commit(int64_t index, std::string_view payload = {}) {
    if (journal_) journal_->commit(pass_, index, payload);
  }

private:
  BlockJournal* journal_;
  int64_t pass_;
};

// The bytes of a trivially copyable value as a payload, and back (Error when the size differs).
template <class T>
std::string payload_of(const T& value) {
  static_assert(std::is_trivially_copyable_v<T>);
  return std::string(reinterpret_cast<const char*>(&value), sizeof value);
}
template <class T>
T payload_as(const std::string& payload) {
  static_assert(std::is_trivially_copyable_v<T>);
  if (payload.size() != sizeof(T))
    throw Error("resume journal: a block's payload has " + std::to_string(payload.size()) + " bytes, expected " +
                std::to_string(sizeof(T)));
  T value;
  std::memcpy(&value, payload.data(), sizeof value);
  return value;
}

// for_each_block for stages whose blocks are independent (see above): blocks committed by an earlier
// run are skipped (counted in the progress), every other block is committed after f(block).
// With `on_kept`: f returns the block's payload (std::string), and on_kept(block, payload) is called
// instead of f for a block committed by an earlier run.
template <class F, class K>
void for_each_block_resumable(const BlockLayout& layout, const Interrupter& interrupter, const std::string& label, F&& f,
                              K&& on_kept) {
  ResumablePass pass;
  const Dims c = layout.count();
  const int64_t total = layout.total();
  int64_t done = 0, index = 0;
  report_blocks(interrupter, label, 0, total);
  for (int64_t bz = 0; bz < c[2]; ++bz)
    for (int64_t by = 0; by < c[1]; ++by)
      for (int64_t bx = 0; bx < c[0]; ++bx, ++index) {
        ++done;
        const Block b = layout.at(bx, by, bz);
        if (const std::string* p = pass.kept(index)) {
          on_kept(b, *p);
          continue;
        }
        const std::string payload = f(b);
        pass.commit(index, payload);
        report_blocks(interrupter, label, done, total);
      }
}
template <class F>
void for_each_block_resumable(const BlockLayout& layout, const Interrupter& interrupter, const std::string& label, F&& f) {
  for_each_block_resumable(
      layout, interrupter, label,
      [&](const Block& b) {
        f(b);
        return std::string();
      },
      [](const Block&, const std::string&) {});
}

// The journal file of one stage (executor side).
class BlockJournalFile final : public BlockJournal {
public:
  // Opens `file` for the stage with cache key `key`. An earlier run's journal of the same key keeps
  // its committed blocks and writes (a torn or unchecked tail is cut off); anything else is replaced
  // by an empty journal. Throws Error when the file cannot be written.
  // The journal is bounded by twice the bytes of the stage's scratch volumes, and at least
  // `min_bytes` (block_journal.cpp, "Size").
  BlockJournalFile(std::filesystem::path file, uint64_t key, uint64_t min_bytes = uint64_t{64} << 20);
  ~BlockJournalFile() override;
  BlockJournalFile(const BlockJournalFile&) = delete;
  BlockJournalFile& operator=(const BlockJournalFile&) = delete;

  int64_t begin_pass() override;
  [[nodiscard]] const std::string* kept(int64_t pass, int64_t index) const override;
  void commit(int64_t pass, int64_t index, std::string_view payload) override;

  // Blocks committed by the earlier run (0 for a new journal).
  [[nodiscard]] int64_t kept_blocks() const;
  // A scratch store of the stage's volume `name` (`dims` voxels of `bytes_per_voxel` bytes): the
  // earlier run's committed writes to `name` are replayed into `inner`, and later writes are
  // journaled once a pass has begun.
  std::shared_ptr<VolumeStore> wrap(const std::string& name, int64_t bytes_per_voxel, const Dims& dims,
                                    std::shared_ptr<VolumeStore> inner);
  // Bytes of the journal file.
  [[nodiscard]] uint64_t size() const;
  [[nodiscard]] const std::filesystem::path& file() const;
  // The store a journaled store wraps (for the format's own operations, e.g. flushing); any other
  // store as it is.
  static const VolumeStore& unwrap(const VolumeStore& store);

  struct State;

private:
  std::unique_ptr<State> s_;
};

}  // namespace skel
