#pragma once
// The metadata walk of the HDF5 structure probe (hdf5_probe.hpp): what the readers ask of a user's
// .h5 file, calling only libhdf5, and the values of the attributes the readers use, which the
// readers then take from the probe's answer instead of decoding them in their own process. Compiled into the probe helper program
// skelflow-hdf5-probe (with AddressSanitizer where the compiler has it) and into skel_io (the
// forked fallback when the helper is not found). Runs only in a process that may die of it.
#include <array>
#include <cstddef>
#include <cstdint>
#include <map>
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
// Bytes of attribute records reported at most (objects beyond are probed again when asked for), and
// of one string attribute (a longer one is reported as too long).
constexpr size_t kMaxRecordBytes = size_t{2} << 20;
constexpr size_t kMaxStringBytes = size_t{64} << 10;
// Bytes of a whole answer at most: names, records and their two lengths.
constexpr size_t kMaxPayloadBytes = kMaxNameBytes + kMaxRecordBytes + 8;

// The attributes the readers read (hdf5_volume.cpp: read_geometry, read_string_attribute), in the
// order of a record.
constexpr const char* kAttributeNames[] = {"spacing", "origin", "element_size_um", "unit", "encoding"};
constexpr size_t kAttributeCount = 5;
constexpr bool is_string_attribute(size_t i) { return i >= 3; }

// One of those attributes of one object as the walk read it (H5Aexists, H5Aopen, H5Aread with the
// readers' memory types).
struct Attribute {
  enum class Kind : uint8_t {
    absent = 0,      // H5Aexists said no (or failed)
    numbers = 1,     // three numbers, read as doubles
    text = 2,        // a string, read as stored (fixed or variable length)
    wrong_count = 3, // a number attribute that does not hold 3 values (`count` says how many)
    not_string = 4,  // a string attribute of another class
    unreadable = 5,  // H5Aopen or H5Aread failed
    too_long = 6,    // a string longer than kMaxStringBytes
  };
  Kind kind = Kind::absent;
  int64_t count = 0;
  std::array<double, 3> numbers{0, 0, 0};
  std::string text;
};
using ObjectAttributes = std::array<Attribute, kAttributeCount>;

// A walk's answer: the dataset names walked and the readers' attributes of the objects walked (the
// requested dataset and its group first, so they are there even when the answer is full).
struct WalkResult {
  std::string names;  // NUL-separated
  std::map<std::string, ObjectAttributes> attributes;
};

// The attribute kAttributeNames[index] of the open object `obj` (an hid_t), read as the walk reads it:
// in the walk, and in-process when the probe is off.
Attribute read_attribute(int64_t obj, size_t index);

// The answer as bytes (what the helper sends) and back; decode returns false on malformed bytes.
std::string encode(const WalkResult& r, const std::string& first, const std::string& second);
bool decode(const std::string& bytes, WalkResult& r);

// Memory a walk may add to its process: SKEL_HDF5_PROBE_MEMORY_MB (MiB, 64 to 1048576), default 1024.
// Throws std::invalid_argument naming the variable on another value.
constexpr uint64_t kDefaultMemoryMiB = 1024;
uint64_t memory_limit_bytes();

// What this process has mapped (/proc/self/status): all of it (VmSize) and its private writable
// part (VmData), in bytes.
struct MemoryUse {
  uint64_t size = 0, data = 0;
};
MemoryUse memory_use();
// Lets this process map at most `bytes` more than `base`: RLIMIT_AS on the address space and
// RLIMIT_DATA on the private writable memory. Both are needed: under AddressSanitizer the allocator
// reserves its whole range at start-up, so the address space does not grow when libhdf5 allocates
// (RLIMIT_AS alone let a walk grow by ~350 MB/s until the timeout); its writable mappings do.
void limit_memory(const MemoryUse& base, uint64_t bytes);
// After limit_memory: a SIGSEGV or SIGBUS while the process is within 64 MiB of a limit ends it with
// kWalkOutOfMemory instead (the sanitizer runtime's strdup interceptor writes through the NULL its
// allocator returns at the limit, where libhdf5 reports the failed allocation); any other keeps
// the signal's default action.
void exit_on_fault_at_the_limit();

// Installs the quiet HDF5 error handler of the walk (it notes failed allocations, prints nothing).
void quiet_hdf5_errors();

// Whether libhdf5 failed an allocation since the last walk_file or forget_out_of_memory (the quiet
// handler notes it): the helper's readers' requests (hdf5_read.hpp) report that as out of memory.
bool out_of_memory_noted();
void forget_out_of_memory();

// Walks `path` and the lookup of `dataset` (when it starts with '/'); fills `payload` with the
// encoded WalkResult. Returns kWalkOk or kWalkOutOfMemory (libhdf5 failed an allocation, or
// std::bad_alloc).
int walk_file(const char* path, const std::string& dataset, std::string& payload);

}  // namespace skel::io::probe
