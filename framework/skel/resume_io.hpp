#pragma once
// Resumable out-of-core runs (`skelflow run --memory-budget ... --resume`, docs/architecture.md
// "Out-of-core execution"): how the executor keeps the volumes of finished stages on disk and opens
// them again in a later process. io registers the HDF5 implementation, so framework names no format.
#include <filesystem>
#include <functional>
#include <memory>

#include "skel/out_of_core.hpp"

namespace skel {

struct ResumeVolumeIo {
  // Writes an in-memory volume (any Volume<T>) to `file`, complete on disk when it returns.
  std::function<void(const std::filesystem::path& file, const DataObject& volume)> save;
  // Makes a scratch store's file complete on disk (its data and metadata flushed), so that a later
  // kill -9 of the process leaves it readable.
  std::function<void(const VolumeStore& store)> flush;
  // Opens a file made by `save` or a flushed scratch store as an on-disk volume of `type_id` and
  // `grid` (as recorded when it was saved; checked against the file); the file is removed when the
  // volume's last user drops it (as a scratch store's).
  std::function<std::shared_ptr<ChunkedVolume>(const std::filesystem::path& file, const std::string& type_id,
                                               const Grid& grid)> open;
};

void register_resume_volume_io(ResumeVolumeIo io);
// The registered implementation; null when no io family is linked.
const ResumeVolumeIo* resume_volume_io();

// Test hook: SKELFLOW_TEST_BLOCK_DELAY_MS=N makes every block-wise stage sleep N ms after each block
// (report_blocks), so that tests can kill a run in the middle of a stage. 0 when unset.
int64_t test_block_delay_ms();

}  // namespace skel
