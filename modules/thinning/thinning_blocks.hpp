#pragma once
// Block-wise distance ordered homotopic thinning (out-of-core, thesis ch. 5.2, Algorithm 5): the
// mask is thinned in sub-blocks (a block plus a halo of H voxels on each side, so neighbouring
// sub-blocks overlap by 2·H >= 2·d_max), each by thin_doht with the voxels nearer the sub-block
// border than the object border locked; see thin_doht_blocks.
#include <cstdint>

#include "skel/data.hpp"
#include "skel/out_of_core.hpp"
#include "thinning/thinning.hpp"

namespace skel::thinning {

struct BlockThinningOptions : ThinningOptions {
  using OptionsBase = ThinningOptions;
  // Halo H in voxels around each block (overlap 2·H between neighbouring sub-blocks). 0: derived
  // from the priority's maximum over the object (block_thinning_halo).
  int halo = 0;
};

// d_max in voxels read from the priority: float priorities are taken as Euclidean distances in
// physical units (distance.euclidean: maximum / smallest spacing), integer ones as chamfer
// distances with a face weight of 3 (distance.chamfer: maximum / 3). One scan over the priority's
// object voxels, block by block.
double priority_max_distance(const DataObject& mask, const DataObject& priority, const Dims& block);
// The halo for a largest distance d_max (voxels): floor(1.11·d_max) + 1. The lock test uses the
// (3, 4, 5) chamfer distance, which exceeds the Euclidean one by at most sqrt(11)/3 < 1.11 times;
// every voxel of a block interior is then nearer its object border than the sub-block border.
int64_t halo_for_distance(double d_max);

struct BlockThinningResult {
  ThinningStatistics stats;  // object_voxels, skeleton_voxels; tests, removed, sub_iterations summed
                             // over the block runs; bytes: the largest block run's working memory
  int64_t halo = 0;          // H used
  Dims block{0, 0, 0};       // interior block shape used
  int64_t blocks = 0;        // blocks of the layout
  int64_t passes = 0;        // passes over (changed) blocks until nothing changed
  int64_t block_runs = 0;    // thin_doht calls
  int64_t bytes_per_voxel = 0;  // memory per voxel of a sub-block
};

// Memory per voxel of a sub-block: mask and state (1 + 1), priority (its voxel size), lock and user
// lock (1 + 1), padded mask and uint32 chamfer of the lock test (1 + 4), skeleton (1), thinning's
// priority levels (up to 2) and queue (8 per queued voxel; budgeted as 4 per voxel).
int64_t block_thinning_bytes_per_voxel(int64_t priority_voxel_bytes);

// Thins `mask` (any integer volume, > 0 is object; in memory or on disk) by `priority` (any volume
// on the same grid) block by block into `skeleton` (volume.u8 on disk, the mask's grid; 0/1).
// The mask is first copied into `skeleton` (the state); then each block's sub-block (block ± H,
// clipped to the grid) is read from the state, its voxels are locked where the (3, 4, 5) chamfer
// distance to the object border inside the sub-block (computed on the original mask; outside the
// grid is background, beyond an inner sub-block face unknown) is at least 3·(distance to that face
// − 1) — so the outermost layer at inner faces is always locked — or where `locked` (optional) is
// set, thin_doht runs on it and the sub-block is written back. Every removal is of a voxel simple
// in a sub-block whose border layer is fixed, hence simple in the whole volume: the skeleton is
// homotopic to the mask for any halo. Blocks whose sub-blocks saw a later block change voxels are
// run again in a further pass, until a pass changes nothing.
// Block shape: plan.block when given by the user, else the largest cube whose sub-block takes at
// most a quarter of the budget. Throws InputError naming param 'halo' when a sub-block of at least
// 16³ interior voxels does not fit the budget, or when a block interior holds object voxels farther
// from the object border than the halo (the halo given, or derived from a priority that is no
// distance). Progress "thinning k/n blocks" (pass p: "thinning pass p k/n blocks"), cancellation
// between blocks.
BlockThinningResult thin_doht_blocks(const DataObject& mask, const DataObject& priority, const DataObject* locked,
                                     const ChunkedVolume& skeleton, const BlockThinningOptions& options,
                                     const BlockPlan& plan);

}  // namespace skel::thinning
