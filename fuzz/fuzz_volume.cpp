// The volume formats of the registry that are one file (NRRD, MetaImage, NIfTI-1, VTK image data,
// Amira lattice; SKEL_FUZZ_VOLUME_EXT names the extension): the input is written to a scratch file
// with that extension, then read_volume_header and (when the declared volume is small) read_any_volume
// read it, as io.read_volume does. Detached data files (.nhdr, .mhd) and Zarr folders are not fuzzed
// (more than one file). Every reader checks declared sizes against the file before allocating, so
// the volume limit (kMaxReadVoxels, fuzz_common.hpp) only bounds the fuzzer's time, not its memory.
#include "fuzz_common.hpp"
#include "io/volume_format.hpp"
#include "skel/error.hpp"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  static skel::fuzz::ScratchFile file(SKEL_FUZZ_VOLUME_EXT);
  const auto& path = file.write(data, size);
  try {
    const skel::io::VolumeHeader h = skel::io::read_volume_header(path);
    if (skel::fuzz::small_enough_to_read(h.grid.dims)) (void)skel::io::read_any_volume(path);
  } catch (const skel::Error&) {
  }
  return 0;
}
