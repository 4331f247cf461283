#pragma once
// Binary masks from volumes: the one place that applies the mask rule "voxel > 0 is object" (any
// integer volume; a float volume is an error, it needs a threshold first). Masks are uint8 0/1.
#include <memory>
#include <string>

#include "skel/data.hpp"
#include "skel/volume.hpp"

namespace skel {

// A new uint8 0/1 mask of `data`, 1 where voxel > 0 (a VolumeU8 is copied and made 0/1 as well).
// Throws InputError naming `what` (e.g. "input 'mask'") for floating-point volumes and non-volumes.
// With `warning`, sets it to a message naming `what` when the volume holds values other than 0 and
// 1 (a grey or label image wired into a mask: all of it > 0 is object), else leaves it empty; the
// check rides on the conversion pass (a uint8 volume costs one extra read-only pass).
VolumeU8 to_mask(const DataObject& data, const std::string& what, std::string* warning = nullptr);

// `data` as a mask without a copy when it already is a VolumeU8 (shared as it is: non-zero is
// object); other integer volumes go through to_mask (1 byte per voxel). Same errors and warning.
std::shared_ptr<const VolumeU8> shared_mask(const DataPtr& data, const std::string& what,
                                            std::string* warning = nullptr);

// The box [begin, begin + size) of a volume in memory or on disk (skel/out_of_core.hpp) as a
// 0/1 mask (the rule and errors of to_mask), for block-wise stages.
VolumeU8 read_mask_block(const DataObject& data, const Dims& begin, const Dims& size, const std::string& what);

}  // namespace skel
