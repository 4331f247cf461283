// The registered ResumeVolumeIo (skel/resume_io.hpp) and the test hook that slows block-wise stages.
#include "skel/resume_io.hpp"

#include <algorithm>
#include <cstdlib>
#include <mutex>

namespace skel {

namespace {
std::mutex& io_mutex() {
  static std::mutex m;
  return m;
}
std::unique_ptr<ResumeVolumeIo>& io_slot() {
  static std::unique_ptr<ResumeVolumeIo> io;
  return io;
}
}  // namespace

void register_resume_volume_io(ResumeVolumeIo io) {
  std::lock_guard lock(io_mutex());
  io_slot() = std::make_unique<ResumeVolumeIo>(std::move(io));
}

const ResumeVolumeIo* resume_volume_io() {
  std::lock_guard lock(io_mutex());
  return io_slot().get();
}

int64_t test_block_delay_ms() {
  static const int64_t delay = [] {
    const char* v = std::getenv("SKELFLOW_TEST_BLOCK_DELAY_MS");
    return v ? std::max<int64_t>(0, std::atoll(v)) : int64_t{0};
  }();
  return delay;
}

}  // namespace skel
