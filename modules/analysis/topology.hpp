#pragma once
// Global topology numbers of a binary volume in the grid point model with (26, 6) adjacency (thesis
// §2.3): components, cavities, Euler characteristic, tunnels.
#include <cstdint>

#include "skel/interrupter.hpp"
#include "skel/volume.hpp"

namespace skel::analysis {

struct TopologyNumbers {
  int64_t object_voxels = 0;
  int64_t components = 0;  // 26-components of the object
  int64_t cavities = 0;    // bounded 6-components of the background (the outside, i.e. everything
                           // connected to the region beyond the array, is not a cavity)
  int64_t euler = 0;       // Euler characteristic of the (26, 6) object (cell complex X(P))
  int64_t tunnels = 0;     // first Betti number: components + cavities - euler
  bool operator==(const TopologyNumbers&) const = default;
};

struct TopologyOptions {
  int threads = 0;  // 0 = all hardware threads; results do not depend on it
  Interrupter interrupter;
};

// Topology numbers of `mask` (voxel != 0 is object). Voxels outside the array are background.
// The Euler characteristic is counted over 2x2x2 cells: chi = V - E + F - C of the grid cell complex
// X(P) (thesis §2.3, grid cell model), which is the Euler characteristic of the 26-connected object.
// Components and cavities: union-find over x-runs (segmentation::count_components). Memory: 1 byte
// per voxel of the padded grid (Euler count, freed afterwards), then ~24 bytes per run.
TopologyNumbers topology(const VolumeU8& mask, const TopologyOptions& options = {});

}  // namespace skel::analysis
