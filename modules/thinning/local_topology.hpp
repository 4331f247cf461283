#pragma once
// Local digital topology in the grid point model with (26, 6) adjacency (thesis §2.3): the
// simple-voxel test (Characterization 2 of Bertrand and Malandain). Global topology numbers are in
// analysis/topology.hpp.
//
// Neighbourhood encoding used by every local test here: bit k (0 <= k < 26) of a 26-bit word is the
// k-th voxel of the 3x3x3 cube around the centre in x-fastest order with the centre skipped, i.e. the
// cube position c = x + 3*y + 9*z (x, y, z in {0, 1, 2}, centre c = 13) maps to bit c for c < 13 and
// to bit c - 1 for c > 13. A set bit means "object voxel".
#include <cstdint>

#include "skel/interrupter.hpp"
#include "skel/volume.hpp"

namespace skel::thinning {

// Bit index of neighbour offset (dx, dy, dz) in {-1, 0, 1}^3 \ {0}.
constexpr int neighbour_bit(int dx, int dy, int dz) {
  const int c = (dx + 1) + 3 * (dy + 1) + 9 * (dz + 1);
  return c < 13 ? c : c - 1;
}

// Exact simple-voxel test for (26, 6) topology: the centre is simple iff the object voxels of its
// 26-neighbourhood form exactly one 26-component and the background voxels of its 18-neighbourhood
// form exactly one 6-component that contains a 6-neighbour of the centre (Characterization 2).
// Answers from a lazily filled, thread-safe 2^26-entry table (16 MiB, 2 bits per configuration);
// each configuration is computed once by is_simple_direct.
bool is_simple(uint32_t neighbourhood26);

// The same test computed directly, no table: bit-parallel component growth on the 27-bit cube word
// (a 26- or 6-dilation is a few masked shifts), about 30 ns on random configurations. Thinning uses
// this one.
bool is_simple_direct(uint32_t neighbourhood26);

// Number of 26-components of the object voxels in the 26-neighbourhood (centre excluded), and
// number of 6-components of background voxels of the 18-neighbourhood that contain a 6-neighbour
// of the centre. Simple iff both are 1.
int object_components26(uint32_t neighbourhood26);
int background_components6(uint32_t neighbourhood26);

// The 26-bit neighbourhood word of voxel (x, y, z) in `mask` (outside the array = background).
uint32_t neighbourhood_at(const VolumeU8& mask, int64_t x, int64_t y, int64_t z);

}  // namespace skel::thinning
