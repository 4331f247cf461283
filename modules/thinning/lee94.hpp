#pragma once
// Lee, Kashyap & Chu (1994) 3D medial surface/axis thinning exactly as scikit-image's
// skeletonize_3d (skimage/morphology/_skeletonize_3d_cy.pyx, scikit-image 0.19) and Fiji's
// Skeletonize3D compute it, voxel for voxel, so that users can reproduce published
// Fiji/AnalyzeSkeleton numbers. Unlike thin_doht this is NOT homotopic in every case: the
// sequential re-check only tests the object connectivity of the 26-neighbourhood, so it deletes a
// voxel that has become isolated, and small components (e.g. two or three voxels) can vanish.
//
// The algorithm (one "pass" = six sub-iterations; repeated until a whole pass deletes nothing):
//   for each border direction in the order of skimage/Fiji: y-1, y+1, x+1, x-1, z+1, z-1
//   (skimage's W, E, S, N, U, B for an array indexed [z][y][x]; only the first four when nz == 1):
//     1. candidates, collected on the unchanged image in raster order (x fastest): object voxels
//        whose neighbour in that direction is background, that are not end points (exactly one
//        26-neighbour), that are Euler invariant (Lee's table 2, delta G_26, summed over the eight
//        octants) and whose 26-neighbour object voxels form at most one 26-component;
//     2. sequential re-check in candidate order: delete a candidate if its 26-neighbour object
//        voxels (in the image as modified so far) form at most one 26-component.
// Voxels outside the array are background (skimage pads by one voxel).
//
// Implementation (results identical for any thread count): the padded object packed as bits (1/8
// byte per voxel, so it stays in cache); border voxels found 64 at a time; the 3x3x3 word of a voxel
// from nine 3-bit row reads; the Euler test as two table look-ups (the four octants of the lower and
// of the upper half of the cube, 2 x 128 KiB, built once); the 26-component test as bit-parallel
// dilations of the 27-bit word; candidates collected on row chunks in parallel and concatenated in
// chunk order (= raster order); the re-check skips the component test when a candidate's word is
// unchanged since it was collected. After the first pass only voxels near a deletion are examined:
// a voxel's candidate status depends on its 3x3x3 neighbourhood only, so per direction a flag per row
// and per group of eight voxels says where a deletion happened since that direction last looked;
// every other voxel keeps its previous status ("not a candidate").
#include <cstdint>

#include "skel/interrupter.hpp"
#include "skel/volume.hpp"

namespace skel::thinning {

struct Lee94Options {
  int threads = 0;  // 0 = all hardware threads (candidate collection)
  Interrupter interrupter;
};

struct Lee94Statistics {
  int64_t object_voxels = 0;     // non-zero voxels of the mask
  int64_t skeleton_voxels = 0;   // voxels left
  int64_t passes = 0;            // passes of six (four when nz == 1) sub-iterations, the last one deleting nothing
  int64_t candidates = 0;        // candidates collected over all sub-iterations
  int64_t removed = 0;           // candidates deleted by the sequential re-check
  int64_t rejected = 0;          // candidates kept by the re-check (their neighbourhood changed)
  int64_t vanished_components = 0;  // deletions of a voxel without object neighbours: each removes the
                                    // last voxel of a component (Lee94's known loss of small components)
  int64_t scanned_rows = 0;      // rows (y, z) scanned for candidates over all sub-iterations
  uint64_t bytes = 0;            // working memory (packed image, dirty flags, row flags, candidate lists)
};

struct Lee94Result {
  VolumeU8 skeleton;  // 0/1, same grid as the mask
  Lee94Statistics stats;
};

// Thins `mask` (non-zero = object). Throws Cancelled when the interrupter says so.
Lee94Result thin_lee94(const VolumeU8& mask, const Lee94Options& options = {});

namespace lee94_detail {
// The local tests on the 27-bit cube word (bit (dx+1) + 3 (dy+1) + 9 (dz+1); the centre bit 13 is
// ignored), exposed for tests against a literal port of the scikit-image code.
bool euler_invariant(uint32_t cube);
bool at_most_one_component(uint32_t cube);  // skimage's is_simple_point (0 or 1 components)
}  // namespace lee94_detail

}  // namespace skel::thinning
