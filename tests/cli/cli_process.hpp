#pragma once
// Running the skelflow binary from CLI tests (SKELFLOW_BIN, set per test target by CMake): start it
// in the background with its output in a file, find the resume folder of a run, read a file whole.
#include <sys/types.h>
#include <unistd.h>

#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <string>
#include <system_error>
#include <vector>

namespace skel::test_cli {

// Starts skelflow with `args`, stdout and stderr into `log`; delay_ms > 0 sets
// SKELFLOW_TEST_BLOCK_DELAY_MS (every block-wise stage sleeps that long after each block). Returns
// the child's pid.
inline pid_t start_skelflow(const std::vector<std::string>& args, const std::filesystem::path& log, int delay_ms) {
  const std::string bin = SKELFLOW_BIN;
  const pid_t pid = fork();
  if (pid == 0) {
    FILE* f = std::freopen(log.c_str(), "w", stdout);
    (void)f;
    dup2(fileno(stdout), fileno(stderr));
    if (delay_ms > 0) setenv("SKELFLOW_TEST_BLOCK_DELAY_MS", std::to_string(delay_ms).c_str(), 1);
    std::vector<char*> argv{const_cast<char*>(bin.c_str())};
    for (const auto& a : args) argv.push_back(const_cast<char*>(a.c_str()));
    argv.push_back(nullptr);
    execv(bin.c_str(), argv.data());
    _exit(127);
  }
  return pid;
}

// The resume folder of pipeline file `p.yaml` in `scratch` (empty path when there is none).
inline std::filesystem::path resume_dir(const std::filesystem::path& scratch) {
  std::error_code ec;
  for (const auto& e : std::filesystem::directory_iterator(scratch, ec))
    if (e.path().filename().string().rfind(".skelflow-resume-p-", 0) == 0) return e.path();
  return {};
}

inline std::string text_of(const std::filesystem::path& f) {
  std::ifstream in(f, std::ios::binary);
  return std::string(std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>());
}

}  // namespace skel::test_cli
