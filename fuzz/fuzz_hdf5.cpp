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
    // A declared size is not checked against the file here: a compressed or unwritten dataset may
    // rightly be far larger than its file. Reading it needs that much memory, which is the user's
    // machine's question, not the parser's: the fuzzer reads volumes of up to 2^24 voxels.
    const double voxels = static_cast<double>(info.dims[0]) * static_cast<double>(info.dims[1]) *
                          static_cast<double>(info.dims[2]);
    if (voxels <= double(1 << 24)) (void)skel::io::read_volume(path);
  } catch (const skel::Error&) {
  }
  return 0;
}
