// The HDF5 header path: the input is written to a scratch .h5 file, then read_volume_info and (when
// the declared volume is small) read_volume open it as `/volume`, as io.read_volume does. Both go
// through the structure probe (io/hdf5_probe.hpp), as a user's file does: libhdf5's metadata walk
// runs first in the helper skelflow-hdf5-probe (a persistent, limited ASan worker process), and a
// file that crashes it or makes a memory error there is refused (an InputError, no finding). The
// probe's verdict cache is cleared for every input: the scratch file is rewritten in place, often
// with the same size in the same clock tick.
#include <cstdio>
#include <cstdlib>

#include "fuzz_common.hpp"
#include "io/hdf5_probe.hpp"
#include "io/hdf5_volume.hpp"
#include "skel/error.hpp"

// A probe that hangs must be refused within libFuzzer's 10 s per input (-timeout=10, scripts/fuzz.sh).
extern "C" int LLVMFuzzerInitialize(int*, char***) {
  setenv("SKEL_HDF5_PROBE_TIMEOUT", "5", 0);
  // Files on which libhdf5 allocates without end are refused at the memory limit: 96 MiB (~0.5 s on
  // this VM, where a page fault costs ~20 µs) instead of the default 1 GiB (~5 s) keeps the inputs
  // per second up once the fuzzer found them (256 MiB: 1.3-1.6 s each, 6 of the 61 corpus inputs of
  // session 11, and the fuzz run's rate fell to 34/s). The walker's AddressSanitizer quarantine
  // (64 MiB) fits under it.
  setenv("SKEL_HDF5_PROBE_MEMORY_MB", "96", 0);
  // The users' path: the helper program, not the forked fallback.
  if (skel::io::detail::hdf5_probe_helper().empty()) {
    std::fprintf(stderr, "fuzz_hdf5: skelflow-hdf5-probe not found (build it: ninja skelflow-hdf5-probe)\n");
    std::abort();
  }
  return 0;
}

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  static skel::fuzz::ScratchFile file(".h5");
  const auto& path = file.write(data, size);
  skel::io::detail::forget_hdf5_probes();
  try {
    const skel::io::VolumeInfo info = skel::io::read_volume_info(path);
    // read_volume checks the declared size against the data the file holds before allocating (a
    // compressed dataset may rightly be ~1000 times larger than its file); the fuzzer reads the
    // voxels of volumes of up to kMaxReadVoxels (fuzz_common.hpp: the same parsing paths, less
    // copying per input).
    if (skel::fuzz::small_enough_to_read(info.dims)) (void)skel::io::read_volume(path);
  } catch (const skel::Error&) {
  }
  return 0;
}
