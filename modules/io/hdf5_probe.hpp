#pragma once
// The HDF5 structure probe. Debian's libhdf5 1.10.8 crashes, reads out of bounds or allocates
// gigabytes on some corrupt or hostile .h5 files while it decodes their metadata (object headers,
// attribute messages, local heaps, B-trees), before Skelflow sees any of it (fuzz target `hdf5`,
// docs/reliability.md). Before a user's HDF5 file is opened for reading, the metadata walk the
// readers make (hdf5_probe_walk.hpp: open, group visit, path lookups, every object's attributes
// including `spacing`, `origin`, `unit`, `element_size_um` and `encoding`, dataset open, type, space,
// layout, chunking, filters, stored size, the chunk index) runs first in the helper program
// skelflow-hdf5-probe, built with AddressSanitizer where the compiler has it (so a heap overflow
// inside libhdf5 stops it even when it would not crash), with an address-space limit (1 GiB above
// its start-up mapping), no core dump and a wall timeout. The helper is a persistent worker: started
// once (posix_spawn, not a fork of this process's page tables), it answers one request per file on
// a socket. It walks in a child it forks from its own initialised state; after a crash or a
// sanitizer report there the file is refused and the worker forks a new child; after a timeout the
// worker is killed and the next request starts a new one. It ends when this process closes the
// socket or dies (EOF, PR_SET_PDEATHSIG).
// If the helper fails, runs out of its memory or time, the file is refused with an InputError naming
// it; otherwise the helper reads it too (hdf5_reads_in_helper, ask_hdf5_helper below; the readers'
// requests of hdf5_read.hpp, voxels through a shared memory window), so that libhdf5 decodes nothing
// of a user's file in the caller's process. With the forked fallback the caller reads it in-process,
// taking the readers' attributes from the walk's answer (probed_attribute below). The verdict is cached per file (path, device, inode,
// size, modification and change time), so a file is probed once per process while it does not change.
//
// Environment: SKEL_HDF5_PROBE=0 turns the probe off (trusted data); SKEL_HDF5_PROBE=fork runs the
// walk in a forked child of this process instead of the helper (also what happens when no helper is
// found); SKEL_HDF5_PROBE_TIMEOUT=S sets the timeout in seconds (default 60);
// SKEL_HDF5_PROBE_MEMORY_MB=M the memory a walk may add (MiB, default 1024; limited as address space
// and as private writable memory, since AddressSanitizer reserves its allocator's range at start-up);
// SKEL_HDF5_PROBE_HELPER names the helper program (default: skelflow-hdf5-probe beside this program, else the build tree's).
// Limits: a memory error of libhdf5 that does not crash the walk is not seen in the forked child of a
// build without AddressSanitizer (the helper has it unless SKEL_HDF5_PROBE_ASAN=OFF or the compiler
// lacks it). Files Skelflow writes and reads itself (out-of-core scratch stores) are not probed.
#include <cstdint>
#include <filesystem>
#include <functional>
#include <string>

#include "io/hdf5_probe_walk.hpp"

namespace skel::io {

// Probes `file` (and the lookup of `dataset`, when not empty) as described above unless the cached
// verdict covers it. Throws InputError when the file is refused, Error when the probe process cannot
// be started. Thread-safe (one request at a time). The caller holds the process-wide HDF5 mutex (no
// other thread is inside libhdf5 when the forked fallback forks).
void probe_hdf5_file(const std::filesystem::path& file, const std::string& dataset);

// The attribute probe::kAttributeNames[index] of the object `object` (a dataset or group path) of
// `file` as the probe's walk read it, probing the file first unless the cache covers the object: the
// readers take these values instead of decoding attribute messages in their own process (libhdf5
// 1.10.8 reads out of bounds in H5Aexists on some damaged object headers, depending on the heap's
// history: docs/reliability.md). An object the walk could not open has every attribute absent.
// Returns false when the probe is off (SKEL_HDF5_PROBE=0) or the file is not a regular file or changed
// between the probe and this call: the caller then reads the attribute in-process. Throws as
// probe_hdf5_file. The caller holds the process-wide HDF5 mutex.
bool probed_attribute(const std::filesystem::path& file, const std::string& object, size_t index, probe::Attribute& out);

// True when users' HDF5 files are opened and read in the helper (SKEL_HDF5_PROBE unset or 1 and the
// helper found): the readers (hdf5_volume.cpp) then ask it with ask_hdf5_helper and make no libhdf5
// call on a user's file themselves (hdf5_read.hpp says why).
bool hdf5_reads_in_helper();

// Request `kind` (h5::Request, not the walk) about `dataset` of `file` to the helper, after the walk
// (probe_hdf5_file); `extra` is the kind's fixed part; a read needs the shared window to hold
// `window_bytes`. On success calls take(payload, window) while no other request can use the window.
// Throws InputError for what the helper refused (its message, naming the file) and for a file that
// crashed, outran or outgrew it (then refused from now on, as the walk's refusals are), Error for other
// failures. Thread-safe (one request at a time).
void ask_hdf5_helper(const std::filesystem::path& file, const std::string& dataset, uint32_t kind, const std::string& extra,
                     uint64_t window_bytes, const std::function<void(const std::string& payload, const void* window)>& take);

namespace detail {
// Number of walks this process has asked for (tests: a file is probed once).
int64_t hdf5_probes_started();
// Number of helper worker processes this process has started (tests: one for many files).
int64_t hdf5_probe_workers_started();
// The running worker's process id, -1 when none runs.
int hdf5_probe_worker_pid();
// The helper program the probe uses now; "" when it forks (SKEL_HDF5_PROBE=fork, none found) or is off.
std::string hdf5_probe_helper();
// Ends the worker and reaps it (tests: no process left behind; the next probe starts a new one).
void stop_hdf5_probe_worker();
// The bytes one read request of the readers may fill in the shared window (default h5::kWindowBytes,
// 64 MiB; tests make it small to read a volume in many boxes). 0 restores the default.
void set_hdf5_read_window(uint64_t bytes);
uint64_t hdf5_read_window();
// Forgets every cached verdict (the fuzz harness rewrites one scratch file with new bytes that may
// have the same size within the same clock tick).
void forget_hdf5_probes();
}  // namespace detail

}  // namespace skel::io
