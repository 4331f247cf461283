#pragma once
// The metadata walk of the HDF5 structure probe (hdf5_probe.hpp): what the readers ask of a user's
// .h5 file, everything but H5Dread, calling only libhdf5. Compiled into the probe helper program
// skelflow-hdf5-probe (with AddressSanitizer where the compiler has it) and into skel_io (the
// forked fallback when the helper is not found). Runs only in a process that may die of it.
#include <cstddef>
#include <cstdint>
#include <string>

namespace skel::io::probe {

// Outcomes of one walk (also the helper's exit codes of its one-file mode).
constexpr int kWalkOk = 0;
constexpr int kWalkOutOfMemory = 3;
// The helper's answer when the process walking a file died (hdf5_probe_main.cpp).
constexpr int kWalkDied = 9;
// What the helper's worker sends once it is ready for requests.
constexpr uint32_t kWorkerReady = 0x534b4850;
// Bytes of dataset names reported at most (names beyond are probed again when asked for).
constexpr size_t kMaxNameBytes = size_t{1} << 20;

// Installs the quiet HDF5 error handler of the walk (it notes failed allocations, prints nothing).
void quiet_hdf5_errors();

// Walks `path` and the lookup of `dataset` (when it starts with '/'); fills `names` with the dataset
// names walked, NUL-separated. Returns kWalkOk or kWalkOutOfMemory (libhdf5 failed an allocation, or
// std::bad_alloc).
int walk_file(const char* path, const std::string& dataset, std::string& names);

}  // namespace skel::io::probe
