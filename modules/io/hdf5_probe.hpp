#pragma once
// The HDF5 structure probe. Debian's libhdf5 1.10.8 crashes, reads out of bounds or allocates
// gigabytes on some corrupt or hostile .h5 files while it decodes their metadata (object headers,
// attribute messages, local heaps, B-trees), before Skelflow sees any of it (fuzz target `hdf5`,
// docs/reliability.md). Before a user's HDF5 file is opened for reading, the metadata walk the
// readers make (open, group visit, path lookups, every object's attributes including `spacing`,
// `origin`, `unit`, `element_size_um` and `encoding`, dataset open, type, space, layout, chunking,
// filters, stored size, the chunk index) runs first in a forked child process that calls only
// libhdf5, with an address-space limit (1 GiB above what the process has mapped), no core dump and
// a wall timeout. If the child dies by a signal, fails, runs out of its memory or time, the file is
// refused with an InputError naming it; otherwise the caller reads it in-process. The verdict is
// cached per file (path, device, inode, size, modification and change time), so a file is probed
// once per process while it does not change.
//
// Environment: SKEL_HDF5_PROBE=0 turns the probe off (trusted data, no fork per file);
// SKEL_HDF5_PROBE_TIMEOUT=S sets the timeout in seconds (default 60).
// Limits: a libhdf5 bug that corrupts memory without crashing the child (a heap overflow that hits
// nothing vital) is not seen without AddressSanitizer, and the file is then read in-process as
// before. Files Skelflow writes and reads itself (out-of-core scratch stores) are not probed.
#include <cstdint>
#include <filesystem>
#include <string>

namespace skel::io {

// Probes `file` (and the lookup of `dataset`, when not empty) as described above unless the cached
// verdict covers it. Throws InputError when the file is refused, Error when the probe process cannot
// be started. The caller holds the process-wide HDF5 mutex (no other thread is inside libhdf5 when
// the process forks).
void probe_hdf5_file(const std::filesystem::path& file, const std::string& dataset);

namespace detail {
// Number of probe processes this process has started (tests: a file is probed once).
int64_t hdf5_probes_started();
// Forgets every cached verdict (the fuzz harness rewrites one scratch file with new bytes that may
// have the same size within the same clock tick).
void forget_hdf5_probes();
}  // namespace detail

}  // namespace skel::io
