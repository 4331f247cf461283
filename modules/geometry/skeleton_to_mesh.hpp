#pragma once
// Voxel skeleton -> triangle mesh + polylines (thesis §3.1.3). Each dual cube's cell complex (the 2^8
// table of skeleton_to_graph.hpp: 1-cells of fig. 3.6, 2-cells on the shortest cycles) is triangulated:
// a 2-cell of 3 voxels is one triangle, a longer one a fan around the centroid of its voxels
// (fig. 3.14). Only 2-cells inside the reduced dual cube (corner 0, its edges and faces, the interior)
// are made, so every triangle is made exactly once (fig. 3.15). A triangle is all-manifold when all its
// voxels are 2-manifold or 2-boundary, else not-all-manifold; the lookup table over the 3^8 states of a
// dual cube's voxels (background; 2-manifold or 2-boundary; other) holds the triangles of each state
// with their class. Optionally (on by default) the cases 13, 14 and 18 of fig. 3.7, which enclose a
// volume, are triangulated without it (fig. 3.16; see MeshCubeTemplate). 1-cells that bound no 2-cell
// become polylines. Vertices of 1-x-junction voxels are marked fixed for smoothing and decimation.
#include <array>
#include <cstdint>
#include <vector>

#include "skel/interrupter.hpp"
#include "skel/mesh.hpp"
#include "skel/volume.hpp"

namespace skel::geometry {

// The triangles of one dual cube configuration. Vertex codes: 0-7 the corners (voxels), 8 + f the
// centre of face f = 2*axis + side (shared with the neighbouring cube: identified through a 2x2x2
// subdivided grid, where voxels sit at even and face centres at two odd coordinates), 14 + j the
// centroid of interior[j] (a corner mask; made per cube).
struct MeshTriangleTemplate {
  std::array<uint8_t, 3> v{};
  uint8_t voxels = 0;    // corner mask deciding the manifold class (the voxels of its 2-cell)
  bool reduced = false;  // made by this cube (not on a face another cube makes)
};
struct MeshCubeTemplate {
  std::vector<MeshTriangleTemplate> triangles;
  std::vector<uint8_t> interior;  // corner masks whose centroids are interior vertices
  uint32_t bounded_edges = 0;     // 1-cells (pair mask) bounding a 2-cell of this cube
};
inline constexpr int kFaceCentre = 8;
inline constexpr int kInterior = 14;

// Triangulation of configuration `config` (corner k at (k&1, k>>1&1, k>>2&1)). `improved`: cases 13
// (4 voxels pairwise face-diagonal: a cone from the cube centre over the 6 diagonals), 14 (5 voxels:
// three triangles around the body diagonal between the two voxels of degree 3) and 18 (6 voxels: the
// full face as usual plus a fin from its centre to the opposite diagonal edge) have no enclosed
// volume; otherwise every 2-cell is triangulated as it is (case 21, the full cube, always keeps its
// volume: no face of it meets the background).
const MeshCubeTemplate& mesh_cube_template(int config, bool improved);

struct SkeletonToMeshOptions {
  bool improved = true;  // improved triangulations of cases 13, 14, 18
  int threads = 0;
  Interrupter interrupter;
};

// Vertex attributes: `manifold` (ManifoldType code of the voxel; a centre vertex 4 when all its
// triangles are all-manifold, else 6) and `fixed` (1 at 1-x-junction voxels). Triangle attribute
// `manifold` (1 all-manifold, 0 not-all-manifold); line attribute `manifold` (1 when every voxel is
// 1-manifold or 1-boundary). Vertices: the voxels used by a triangle or line (ascending voxel index),
// then face centres (ascending subdivided index), then interior centroids. Isolated voxels give no
// geometry. Deterministic for any thread count.
Mesh skeleton_to_mesh(const VolumeU8& skeleton, const SkeletonToMeshOptions& options = {});

}  // namespace skel::geometry
