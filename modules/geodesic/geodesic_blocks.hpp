#pragma once
// Geodesic boundary distance block by block (out-of-core, thesis ch. 5, §5.3): each block is
// computed by the in-core boundary_distance on the block with a margin of d_max + t/2 around it, and
// only its interior is kept. See boundary_distance_blocks.
#include <cstdint>

#include "geodesic/geodesic.hpp"
#include "skel/out_of_core.hpp"

namespace skel::geodesic {

struct BlockStatistics {
  int64_t blocks = 0;
  int64_t object_voxels = 0;   // of the whole mask (block interiors)
  int64_t max_ring = 0;        // d_max: largest chessboard distance of an object voxel to the background
  int64_t largest_margin = 0;  // voxels
  int64_t retries = 0;         // blocks read again with a larger margin
  uint64_t largest_block_bytes = 0;  // working memory of the largest block with margin
  Statistics summed;           // in-core statistics summed over the blocks with their margins
};

// Bytes per voxel of a block with margin: mask (1) + rings (2) + boundary_distance's working memory
// and outputs over the block (<= 20 for an all-object block) + the interior's outputs (5).
constexpr int64_t kBlockBytesPerVoxel = 28;

// The margin that makes a block exact: d_max + t/2 plus three voxels (the 6-neighbour q of an
// interior voxel, rounding of t/2, the layer voxel next to the margin's edge).
int64_t exact_margin(int64_t max_ring, int64_t threshold);

// Threshold mode only (full mode has no finite margin: throws InputError naming parameter 'mode').
// `mask` (volume.u8, voxel > 0 is object, in memory or on disk) is cut into blocks of `block`
// voxels; each block is read with a margin m, the chessboard distance of its voxels to the
// background (the ring of the nearest-point propagation) is computed in the block, and when the
// largest ring r of the interior gives exact_margin(r, t) > m, the block is read again with that
// margin (a ring computed in a block is exact where it is below the margin). With the margin, every
// nearest point b(p) of an interior voxel and every 6-path in the boundary layer shorter than t
// between b(p) and b(q) lie inside the block, and every path through the block's (artificial) outside
// is at least t long, so importance (saturated at t) and surface_skeleton equal the in-core result
// voxel for voxel. Writes `importance` (volume.f32) and `surface_skeleton` (volume.u8) on the mask's
// grid. Throws InputError naming parameter 'threshold' when a block with its margin needs more than
// `memory_budget` bytes (0: no limit).
BlockStatistics boundary_distance_blocks(const DataObject& mask, const ChunkedVolume& importance,
                                         const ChunkedVolume& surface_skeleton, const Options& options,
                                         const Dims& block, uint64_t memory_budget);

}  // namespace skel::geodesic
