#pragma once
// Voxel type conversion and cropping of volumes.
#include <string>

#include "skel/data.hpp"
#include "skel/enum_names.hpp"
#include "skel/interrupter.hpp"
#include "skel/volume.hpp"

namespace skel::volume {

enum class ConvertMode {
  Clamp,    // value cast to the target type, clamped to its range (NaN → 0)
  Rescale,  // input [min, max] mapped linearly onto the target range (float targets: onto [0, 1])
};
constexpr auto enum_names(ConvertMode) {
  return std::to_array<EnumName<ConvertMode>>({{ConvertMode::Clamp, "clamp"}, {ConvertMode::Rescale, "rescale"}});
}

struct ConvertOptions {
  std::string dtype = "uint8";  // uint8 | uint16 | uint32 | int32 | float32 | float64
  ConvertMode mode = ConvertMode::Clamp;
  int threads = 0;
  Interrupter interrupter{};
};

// Converts any volume to the voxel type named by options.dtype; same grid. Throws InputError on an
// unknown dtype.
DataPtr convert_volume_type(const DataObject& input, const ConvertOptions& options);

// Copies the box [begin, begin + size) of `input` (voxel indices, clipped to the volume) into a new
// volume whose origin keeps the physical position of the voxels. Throws InputError if the box is
// empty after clipping.
DataPtr crop_volume(const DataObject& input, const Dims& begin, const Dims& size);

}  // namespace skel::volume
