#pragma once
// Shared helpers of the libFuzzer targets (fuzz/README.md). A target feeds the input to one reader and
// accepts only skel::Error (the reader's documented way to refuse a malformed file); anything else
// (a crash, a sanitizer report, another exception, a leak, a timeout, an allocation over the
// -malloc_limit_mb) is a finding.
#include <unistd.h>

#include <array>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <string>

namespace skel::fuzz {

inline std::string as_text(const uint8_t* data, size_t size) {
  return std::string(reinterpret_cast<const char*>(data), size);
}

// The volume targets read the voxels of declared volumes of at most this many voxels (after the
// header, which is always read). Header parsing, the declared-size checks against the file, strip,
// tile, chunk and decompression handling are the same for 64³ as for 256³ voxels; a larger volume
// only adds allocation, copy and conversion time per input (up to 64 MiB of floats allocated and
// poisoned by ASan per input at the former limit of 2^24 voxels). Allocations beyond what a file can
// hold are still caught: every reader checks declared
// sizes against the file before allocating, and -malloc_limit_mb (scripts/fuzz.sh) stops any
// allocation over 1 GB, whatever the declared size.
constexpr double kMaxReadVoxels = double(1 << 18);

inline bool small_enough_to_read(const std::array<int64_t, 3>& dims) {
  return static_cast<double>(dims[0]) * static_cast<double>(dims[1]) * static_cast<double>(dims[2]) <= kMaxReadVoxels;
}

// A scratch file of this process (the readers that take a path): rewritten for every input, removed
// at exit. In $TMPDIR when set, else in /dev/shm (memory: no disk write per input) when it is a
// writable folder, else in /tmp.
class ScratchFile {
public:
  explicit ScratchFile(const std::string& extension) {
    const char* env = std::getenv("TMPDIR");
    std::filesystem::path dir = "/tmp";
    if (env && *env) dir = env;
    else if (std::error_code ec; std::filesystem::is_directory("/dev/shm", ec) && ::access("/dev/shm", W_OK) == 0)
      dir = "/dev/shm";
    path_ = dir / ("skelflow-fuzz-" + std::to_string(::getpid()) + extension);
  }
  ~ScratchFile() {
    std::error_code ec;
    std::filesystem::remove(path_, ec);
  }
  ScratchFile(const ScratchFile&) = delete;
  ScratchFile& operator=(const ScratchFile&) = delete;
  const std::filesystem::path& write(const uint8_t* data, size_t size) {
    std::FILE* f = std::fopen(path_.c_str(), "wb");
    if (!f) std::abort();
    if (size && std::fwrite(data, 1, size, f) != size) std::abort();
    std::fclose(f);
    return path_;
  }

private:
  std::filesystem::path path_;
};

}  // namespace skel::fuzz
