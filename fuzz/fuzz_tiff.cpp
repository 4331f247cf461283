// The TIFF path: the input is written to a scratch .tif file, then the registry reads its header (as
// validate does) and, when the declared volume is small, its voxels (as io.read_volume does), the
// first channel of multi-channel files.
#include "fuzz_common.hpp"
#include "io/volume_format.hpp"
#include "skel/error.hpp"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  static skel::fuzz::ScratchFile file(".tif");
  const auto& path = file.write(data, size);
  try {
    skel::io::VolumeReadOptions o;
    o.channel = 0;
    const skel::io::VolumeHeader h = skel::io::read_volume_header(path, o);
    if (skel::fuzz::small_enough_to_read(h.grid.dims)) (void)skel::io::read_any_volume(path, o);
  } catch (const skel::Error&) {
  }
  return 0;
}
