#pragma once
// The read side of HDF5 volumes: opening a user's file and dataset, the checks made before reading
// (rank, type, damaged type fields, declared and stored sizes), spacing/origin/unit, and the voxels of a
// box (our own chunk decoding, hdf5_chunks.hpp, else H5Dread). Compiled twice:
//   - into skel_io, where hdf5_volume.cpp uses it for trusted files (SKEL_HDF5_PROBE=0), for the
//     forked fallback of the probe (SKEL_HDF5_PROBE=fork, or no helper found) and for its own files;
//   - into the probe helper skelflow-hdf5-probe (hdf5_probe_main.cpp), built with AddressSanitizer,
//     which answers the readers' requests (serve_request below) for users' files in its own process.
// With the helper (the default), no libhdf5 call on a user's file is made in the reader's process:
// libhdf5 1.10.8 reads freed or out-of-bounds memory while it decodes some damaged object headers,
// depending on the heap's history (H5Aexists, H5Dopen2's layout message: docs/reliability.md), so a
// walk in a fresh process cannot vouch for a later open in a long-running one. The helper writes the
// voxels into a shared memory window (a memfd the reader created and mapped) box by box; the reader
// copies them into its volume.
// Every function here assumes the caller holds the process-wide HDF5 mutex (in the helper there is
// one thread calling libhdf5, apart from the chunk decoder's own locked calls).
#include <hdf5.h>

#include <cstdint>
#include <filesystem>
#include <functional>
#include <string>
#include <vector>

#include "io/hdf5_probe_walk.hpp"
#include "io/hdf5_volume.hpp"

namespace skel::io::h5 {

// libhdf5's innermost error message as " (HDF5: ...)", "" when none; clears the stack.
std::string hdf5_reason();
// InputError "FILE: what (HDF5: ...)".
[[noreturn]] void fail(const std::filesystem::path& file, const std::string& what);

// RAII handle of an hid_t with its close function.
struct Handle {
  hid_t id = -1;
  herr_t (*close)(hid_t) = nullptr;
  Handle() = default;
  Handle(hid_t i, herr_t (*c)(hid_t)) : id(i), close(c) {}
  Handle(const Handle&) = delete;
  Handle& operator=(const Handle&) = delete;
  Handle(Handle&& o) noexcept : id(o.id), close(o.close) { o.id = -1; }
  Handle& operator=(Handle&& o) noexcept {
    if (this != &o) {
      if (id >= 0 && close) close(id);
      id = o.id;
      close = o.close;
      o.id = -1;
    }
    return *this;
  }
  ~Handle() {
    if (id >= 0 && close) close(id);
  }
  explicit operator bool() const { return id >= 0; }
  // Closes now and reports whether that worked (the destructor cannot).
  bool close_now() {
    const hid_t i = id;
    id = -1;
    return i < 0 || !close || close(i) >= 0;
  }
};

// Opens `file` read-only (or read-write: Skelflow's own outputs, write_string_attribute) after
// checking that it exists, is not a folder and is HDF5. `fapl` is the file access list (-1: default).
Handle open_file(const std::filesystem::path& file, bool write, hid_t fapl = -1);
// The dataset names of an open file ("/a/b"), in libhdf5's visit order.
std::vector<std::string> list_datasets(hid_t file);
// Opens `dataset` (each path component checked, so a missing group is a clear message that lists the
// file's datasets) with a 256 MiB chunk cache.
Handle open_dataset(hid_t f, const std::filesystem::path& file, const std::string& dataset);

struct Opened {
  Handle file, dset, space;
  Dims dims{0, 0, 0};  // (x, y, z)
  std::string dtype;   // uint8 ... float64
};
// open_file + open_dataset + rank 3 + a supported number type whose bit fields lie inside its bytes.
Opened open_volume(const std::filesystem::path& file, const std::string& dataset, bool write = false, hid_t fapl = -1);

// Where the readers' attributes come from: by default libhdf5 in this process (probe::read_attribute);
// the reader's process installs the structure probe's cache (probed_attribute, hdf5_probe.hpp) for the
// forked fallback, so that it decodes no attribute message itself. A source returns false when it has
// no value (the attribute is then read in this process).
using AttributeSource = bool (*)(const std::filesystem::path& file, const std::string& object, size_t index,
                                 probe::Attribute& out);
void set_attribute_source(AttributeSource source);

// Dims, type, chunks, filters, spacing, origin and unit of an open dataset (VolumeInfo).
VolumeInfo volume_info(const Opened& o, const std::filesystem::path& file, const std::string& dataset);
// The checks before a whole dataset is read: at least one voxel on every axis; the declared size
// against the data the file holds (deflate at most ~1100:1), undecodable filters, the stored size
// against the file size.
void check_whole_read(const Opened& o, const std::filesystem::path& file, const std::string& dataset);
// The voxels of the box [begin, begin + size) (x, y, z; inside the dataset) into `out` (x fastest),
// converted to T as H5Dread does; our chunk decoding on `threads` threads where it applies.
template <class T>
void read_voxels(const Opened& o, const std::filesystem::path& file, const std::string& dataset, const Dims& begin,
                 const Dims& size, T* out, int threads);
// The string attribute `name` (one of probe::kAttributeNames' strings) of `dataset`, "" when absent.
std::string string_attribute(const Opened& o, const std::filesystem::path& file, const std::string& dataset,
                             const std::string& name);
// describe_file's text (hdf5_volume.hpp). `before_open(name)` runs before each dataset is opened
// (the in-process reader probes the lookup of that name first).
std::string describe(const std::filesystem::path& file, const std::function<void(const std::string&)>& before_open);

// ------------------------------------------------------------------ requests to the probe helper
// Request kinds (the walk of hdf5_probe_walk.hpp is kind 0).
enum class Request : uint32_t { walk = 0, info = 1, read = 2, describe = 3, string_attribute = 4 };
constexpr uint32_t kRequestKinds = 5;
// Outcomes beside probe::kWalkOk / kWalkOutOfMemory / kWalkDied: the request was refused with an
// InputError (payload: its message), or failed otherwise (payload: the message, an Error).
constexpr int kRefused = 10;
constexpr int kFailed = 11;
// The shared memory window is the helper's descriptor 3 (the reader's memfd); by default at most this
// many bytes are read per request (the reader splits larger boxes, aligned to chunks where a chunk
// fits: detail::set_hdf5_read_window, hdf5_probe.hpp).
constexpr int kWindowFd = 3;
constexpr uint64_t kWindowBytes = uint64_t{64} << 20;

// Element types of a read request (VoxelTraits order of the readers).
enum class MemoryType : uint32_t { u8 = 0, u16 = 1, u32 = 2, u64 = 3, i32 = 4, f32 = 5, f64 = 6 };
template <class T> constexpr MemoryType memory_type_of();
template <> constexpr MemoryType memory_type_of<uint8_t>() { return MemoryType::u8; }
template <> constexpr MemoryType memory_type_of<uint16_t>() { return MemoryType::u16; }
template <> constexpr MemoryType memory_type_of<uint32_t>() { return MemoryType::u32; }
template <> constexpr MemoryType memory_type_of<uint64_t>() { return MemoryType::u64; }
template <> constexpr MemoryType memory_type_of<int32_t>() { return MemoryType::i32; }
template <> constexpr MemoryType memory_type_of<float>() { return MemoryType::f32; }
template <> constexpr MemoryType memory_type_of<double>() { return MemoryType::f64; }
size_t memory_type_bytes(MemoryType t);

// The fixed part of a read request (after path and dataset), native byte order.
struct ReadRequest {
  uint32_t memory_type = 0;  // MemoryType
  int32_t threads = 0;       // chunk decoding threads (<= 0: all)
  uint32_t own_chunks = 1;   // 0: SKEL_HDF5_OWN_CHUNKS=0 in the reader's process
  uint32_t reserved = 0;
  int64_t begin[3] = {0, 0, 0}, size[3] = {0, 0, 0};  // (x, y, z)
};
// The answer to a read: chunks our decoder decoded, reads it declined (the reader adds them to its own
// counters, hdf5_chunks.hpp, so that tests see which path a read took).
struct ReadAnswer {
  int64_t decoded = 0, declined = 0;
};

// The answer to an info request: encode_info's bytes, then (put by serve_request) why a whole read
// would be refused, "" when it would not (check_whole_read's message).
std::string encode_info(const VolumeInfo& info);
bool decode_info(const std::string& bytes, VolumeInfo& info, std::string* whole_read_refusal = nullptr);

// Serves one request in the helper: `extra` holds the kind's fixed part (ReadRequest, or the attribute
// name). Fills `payload` and returns probe::kWalkOk, kRefused (an InputError: its message),
// kFailed (another error) or probe::kWalkOutOfMemory. A read writes the box into the window
// (descriptor `window_fd`, at least size[0]*size[1]*size[2] elements long).
int serve_request(Request kind, const std::string& path, const std::string& dataset, const std::string& extra,
                  int window_fd, std::string& payload);

}  // namespace skel::io::h5
