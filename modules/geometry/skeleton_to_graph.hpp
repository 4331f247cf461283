#pragma once
// Voxel skeleton → SpatialGraph by the dual-cube cell complex of Prohaska's thesis §3.1:
// 1-cells by the rules of fig. 3.6, 2-cells on the shortest independent cycles of each dual cube,
// a 3-cell when χ = 2 (§3.1.1), voxel manifold types of fig. 3.9, edges generated once per reduced
// dual cube from a 2^8 lookup table, junction collapse and chain simplification (§3.1.2), Gaussian
// smoothing of edge points, radius from a distance volume (§6.1). Beyond the thesis, a tunnel inside
// a collapsed component is kept as a loop edge on its node, so the graph's cyclomatic number equals
// the skeleton's tunnel count (unless a component encloses a cavity or has > 4096 internal 1-cells).
#include <array>
#include <cstdint>
#include <vector>

#include "skel/interrupter.hpp"
#include "skel/out_of_core.hpp"
#include "skel/spatial_graph.hpp"
#include "skel/volume.hpp"

namespace skel::geometry {

// Manifold type of a skeleton voxel (values of the `manifold` output volume; 0 = background).
enum class ManifoldType : uint8_t {
  background = 0,
  point = 1,          // 0-manifold: no incident 1-cell (isolated voxel)
  line = 2,           // 1-manifold: exactly two incident 1-cells, no 2-cell
  line_end = 3,       // 1-boundary: exactly one incident 1-cell, no 2-cell
  surface = 4,        // 2-manifold: every incident 1-cell bounds exactly two 2-cells
  surface_edge = 5,   // 2-boundary: two incident 1-cells bound one 2-cell, the rest two
  junction = 6,       // anything else (incl. 3-cells), every incident 1-cell bounds a 2-cell
  line_junction = 7,  // 1-x-junction: a junction with at least one bare incident 1-cell
};

// One entry of the 2^8 dual-cube table. Corner k of a dual cube sits at (k&1, k>>1&1, k>>2&1);
// pair p in [0, 28) is the corner pair dual_cube_pair(p).
struct DualCubeCell2 {
  uint8_t vertices = 0;  // corner mask
  uint32_t edges = 0;    // pair mask of its boundary cycle
  int8_t face = -1;      // 2*axis + side when all corners lie on one face of the cube, else -1
};
struct DualCubeEntry {
  uint32_t edges = 0;          // all 1-cells (pair mask), rules of fig. 3.6
  uint32_t reduced_edges = 0;  // 1-cells inside the reduced dual cube (fig. 3.12)
  std::vector<DualCubeCell2> cells2;
  bool cell3 = false;
  int euler = 0;  // χ of the complex before the 3-cell: 1 or 2
};
// Corner pair (a < b) of pair index p.
std::array<int, 2> dual_cube_pair(int p);
// The lookup table, built once on first use.
const std::vector<DualCubeEntry>& dual_cube_table();

// Manifold type of every object voxel (fig. 3.9), 0 outside the object.
VolumeU8 classify_manifold(const VolumeU8& skeleton, int threads = 0, const Interrupter& interrupter = {});

struct SkeletonToGraphOptions {
  int smooth_passes = 0;         // Gaussian smoothing passes over edge points (0 = off)
  int smooth_kernel = 5;         // window size in points (odd, >= 3)
  double radius_scale = 1.0;     // radius = distance value × radius_scale
  bool want_manifold = false;    // also return the manifold type volume
  int threads = 0;
  Interrupter interrupter;
};

struct SkeletonGraphResult {
  SpatialGraph graph;
  VolumeU8 manifold;  // empty unless want_manifold
};

// `distance` may be null; otherwise any volume on the skeleton's grid whose value at a skeleton
// voxel gives the point attribute `radius` (× radius_scale). Throws InputError on a grid mismatch.
SkeletonGraphResult skeleton_to_graph(const VolumeU8& skeleton, const DataObject* distance,
                                      const SkeletonToGraphOptions& options = {});

// Block-wise (out-of-core, thesis ch. 5): the same graph as skeleton_to_graph, bit for bit, for a
// volume.u8 skeleton in memory or on disk read in blocks of `block` voxels with a one-voxel halo.
// Each object voxel is gathered with its 27-neighbourhood (all the dual cubes around it), so the
// 1-cells, junctions, chains and loops that cross block faces, edges and corners are those of the
// whole volume; the phases then run on the gathered voxels. `distance` (may be null) is read block
// by block too. When `manifold` is given (volume.u8 on the skeleton's grid) the manifold types are
// written to it block by block. Memory: one block with halo (1 B/voxel + the distance's bytes), plus
// ~65 B per skeleton voxel while the graph is built (as in core, without the volume).
SpatialGraph skeleton_to_graph_blocks(const DataObject& skeleton, const DataObject* distance, const Dims& block,
                                      const SkeletonToGraphOptions& options, const ChunkedVolume* manifold = nullptr);

// Gaussian smoothing of the interior points of every edge (end points fixed), window `kernel`
// points (truncated symmetrically near the ends), sigma = kernel / 4.
void smooth_edges(SpatialGraph& graph, int passes, int kernel);

}  // namespace skel::geometry
