#pragma once
// Per-block resume of out-of-core stages (`skelflow run --resume`, docs/architecture.md
// "Out-of-core execution"). A stage whose blocks are independent — each block reads only the
// stage's inputs and writes only its own part of the outputs, and nothing is carried in memory from
// one block to the next — walks its blocks with for_each_block_resumable instead of for_each_block.
// In a resumable run the executor gives such a stage a journal: every write to its scratch
// volumes is recorded, and after each block the block's writes and a commit record are appended to
// `<node>.blocks` in the resume folder and synced to disk. A run killed with kill -9 and started
// again with --resume replays the committed writes into the new scratch volumes and skips the
// committed blocks, so the stage's outputs are the bytes of an uninterrupted run.
#include <cstdint>
#include <filesystem>
#include <memory>
#include <string>

#include "skel/out_of_core.hpp"

namespace skel {

class BlockJournal {
public:
  virtual ~BlockJournal() = default;
  // Starts the next for_each_block_resumable of the stage; returns its number (0, 1, ...).
  virtual int64_t begin_pass() = 0;
  // True when block `index` of pass `pass` was committed by an earlier run.
  [[nodiscard]] virtual bool finished(int64_t pass, int64_t index) const = 0;
  // Makes the writes since the last commit durable together with the record that block `index` of
  // pass `pass` is finished.
  virtual void commit(int64_t pass, int64_t index) = 0;
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

// for_each_block for stages whose blocks are independent (see above): blocks committed by an earlier
// run are skipped (counted in the progress), every other block is committed after f(block).
template <class F>
void for_each_block_resumable(const BlockLayout& layout, const Interrupter& interrupter, const std::string& label, F&& f) {
  BlockJournal* journal = current_block_journal();
  if (journal == nullptr) {
    for_each_block(layout, interrupter, label, std::forward<F>(f));
    return;
  }
  const int64_t pass = journal->begin_pass();
  const Dims c = layout.count();
  const int64_t total = layout.total();
  int64_t done = 0, index = 0;
  report_blocks(interrupter, label, 0, total);
  for (int64_t bz = 0; bz < c[2]; ++bz)
    for (int64_t by = 0; by < c[1]; ++by)
      for (int64_t bx = 0; bx < c[0]; ++bx, ++index) {
        ++done;
        if (journal->finished(pass, index)) continue;
        f(layout.at(bx, by, bz));
        journal->commit(pass, index);
        report_blocks(interrupter, label, done, total);
      }
}

// The journal file of one stage (executor side).
class BlockJournalFile final : public BlockJournal {
public:
  // Opens `file` for the stage with cache key `key`. An earlier run's journal of the same key keeps
  // its committed blocks and writes (a torn or unchecked tail is cut off); anything else is replaced
  // by an empty journal. Throws Error when the file cannot be written.
  BlockJournalFile(std::filesystem::path file, uint64_t key);
  ~BlockJournalFile() override;
  BlockJournalFile(const BlockJournalFile&) = delete;
  BlockJournalFile& operator=(const BlockJournalFile&) = delete;

  int64_t begin_pass() override;
  [[nodiscard]] bool finished(int64_t pass, int64_t index) const override;
  void commit(int64_t pass, int64_t index) override;

  // Blocks committed by the earlier run (0 for a new journal).
  [[nodiscard]] int64_t kept_blocks() const;
  // A scratch store of the stage's volume `name` (voxels of `bytes_per_voxel` bytes): the earlier
  // run's committed writes to `name` are replayed into `inner`, and later writes are journaled once
  // a pass has begun.
  std::shared_ptr<VolumeStore> wrap(const std::string& name, int64_t bytes_per_voxel, std::shared_ptr<VolumeStore> inner);
  [[nodiscard]] const std::filesystem::path& file() const;
  // The store a journaled store wraps (for the format's own operations, e.g. flushing); any other
  // store as it is.
  static const VolumeStore& unwrap(const VolumeStore& store);

  struct State;

private:
  std::unique_ptr<State> s_;
};

}  // namespace skel
