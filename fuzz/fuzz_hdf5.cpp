// The HDF5 header path: the input is written to a scratch .h5 file, then read_volume_info and (when
// the declared volume is small) read_volume open it as `/volume`, as io.read_volume does.
#include "fuzz_common.hpp"
#include "io/hdf5_volume.hpp"
#include "skel/error.hpp"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  static skel::fuzz::ScratchFile file(".h5");
  const auto& path = file.write(data, size);
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
