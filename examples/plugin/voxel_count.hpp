#pragma once
// The algorithm of example.voxel_count as a plain function (tested without the module).
#include <cstdint>
#include <string>

#include "skel/data.hpp"

namespace example {

struct VoxelCountOptions {
  double min_value = 1.0;  // a voxel belongs to the object when its value is >= min_value
};

struct VoxelCount {
  int64_t voxels = 0;         // all voxels
  int64_t object = 0;         // voxels >= min_value
  double object_volume = 0;   // object * voxel volume, in unit³
  std::string unit;           // the input grid's unit
};

VoxelCount count_voxels(const skel::DataObject& volume, const VoxelCountOptions& options = {});

}  // namespace example
