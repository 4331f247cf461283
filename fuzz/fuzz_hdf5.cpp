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
    (void)skel::io::read_volume(path);
    (void)info;
  } catch (const skel::Error&) {
  }
  return 0;
}
