#pragma once
// Shared helpers of the libFuzzer targets (fuzz/README.md). A target feeds the input to one reader and
// accepts only skel::Error (the reader's documented way to refuse a malformed file); anything else
// (a crash, a sanitizer report, another exception, a leak, a timeout, an allocation over the
// -malloc_limit_mb) is a finding.
#include <unistd.h>

#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <string>

namespace skel::fuzz {

inline std::string as_text(const uint8_t* data, size_t size) {
  return std::string(reinterpret_cast<const char*>(data), size);
}

// A scratch file of this process (the readers that take a path): rewritten for every input, removed
// at exit.
class ScratchFile {
public:
  explicit ScratchFile(const std::string& extension) {
    const char* dir = std::getenv("TMPDIR");
    path_ = std::filesystem::path(dir && *dir ? dir : "/tmp") /
            ("skelflow-fuzz-" + std::to_string(::getpid()) + extension);
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
