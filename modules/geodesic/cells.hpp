#pragma once
// The geodesic plate skeleton in the grid cell model (thesis §2.3.2, "A value is associated with every
// 2-cell of the object's grid cell complex", fig. 4.5): the 2-cell c{p,q} between a voxel p and its
// 6-neighbour q gets the importance g(b(p), b(q)) (b: nearest background point, g: shortest 6-path in
// the background layer L, as geodesic.hpp); the 2-cells with importance >= t together with their faces
// form the skeleton Y_t. Y_t is a sub-complex of the object's grid cell complex X(P); unlike thinning it
// does not keep the object's homotopy (cavities are kept: their inner boundary cannot reach the outer
// one through L). Lock it in thinning.grid_cell (input `locked_cells`) for a homotopic plate skeleton.
#include <cstdint>

#include "skel/grid_cells.hpp"
#include "skel/interrupter.hpp"
#include "skel/volume.hpp"

namespace skel::geodesic {

struct PlateCellsOptions {
  int64_t threshold = 20;  // t, in 6-steps of the boundary layer (as geodesic.boundary_distance)
  int threads = 0;
  Interrupter interrupter;
};

struct PlateCellsStatistics {
  int64_t object_voxels = 0;
  int64_t layer_voxels = 0;    // |L|
  int64_t searches = 0;        // breadth-first searches (one per base point with targets)
  int64_t visited = 0;         // layer voxels visited over all searches
  int64_t selected_faces = 0;  // 2-cells with importance >= t
  uint64_t bytes = 0;          // peak working memory (without input and output)
};

struct PlateCellsResult {
  GridCells cells;  // Y_t
  // Per object voxel, which of its considered 2-cells have importance >= t: bit 2a = the lower face
  // along axis a (x, y, z), bit 2a+1 = the upper face along axis a (only where that neighbour is
  // background). Every 2-cell of X(P) is considered by exactly one object voxel (the upper one of two
  // object voxels, else the object voxel), so a voxel's importance in geodesic.boundary_distance is
  // >= t exactly when it has a bit set here.
  VolumeU8 faces;
  PlateCellsStatistics stats;
};

// Y_t of `mask` (voxel > 0 is object). Threshold in [1, 10^6]; InputError otherwise.
PlateCellsResult plate_cells(const VolumeU8& mask, const PlateCellsOptions& options = {});

}  // namespace skel::geodesic
