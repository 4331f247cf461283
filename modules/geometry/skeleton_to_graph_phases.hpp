#pragma once
// The phases of skeleton_to_graph (thesis §3.1), for skeleton_to_graph.cpp and its tests. Not part of
// the module's API: names and signatures follow the implementation.
//
// skeleton_to_graph runs, in order:
//   collect_voxels: the object voxels (ids = raster order) with their 27-neighbourhoods; every later
//      phase reads only these, never the volume, so a skeleton on disk is gathered block by block
//      (collect_voxels_blocks) and the same phases give the same graph;
//   1. classify_voxels: manifold type per voxel (fig. 3.9);
//   2. connect_one_cells: the 1-cells (fig. 3.6), each generated once by the reduced dual cube that
//      contains it (fig. 3.12), as an adjacency between voxel ids;
//   3. collapse_junctions + make_nodes: non-1-manifold voxels joined by 1-cells form one node
//      (§3.1.2); one node per component (at its centroid) and per 1-boundary voxel;
//   4. trace_chains: chains of 1-manifold voxels become edge polylines (fig. 3.13); tunnel_loops:
//      loop edges for the tunnels inside collapsed components; isolated_loops: closed chains without
//      a node.
#include <algorithm>
#include <cstdint>
#include <vector>

#include "geometry/skeleton_to_graph.hpp"
#include "skel/interrupter.hpp"
#include "skel/spatial_graph.hpp"
#include "skel/volume.hpp"

namespace skel::geometry::detail {

// The skeleton's object voxels and what the phases find for them. A voxel's id is its position in
// `vox`.
struct SkeletonVoxels {
  Grid grid;                      // the skeleton's grid (positions, linear indices)
  std::vector<int64_t> vox;       // linear indices, ascending
  std::vector<uint32_t> hood;     // per id: 27-neighbourhood, bit (dx+1) + 3(dy+1) + 9(dz+1) set for
                                  // object voxels inside the grid
  std::vector<uint8_t> cls;       // phase 1: ManifoldType per id
  std::vector<int64_t> off, adj;  // phase 2: the 1-cells, CSR: neighbours of id i are adj[off[i] .. off[i+1])
  std::vector<double> rad;        // radius per id (read_radius; empty without a distance volume)

  [[nodiscard]] int64_t size() const { return static_cast<int64_t>(vox.size()); }
  // Id of object voxel `idx` >= vox[i], by a galloping search forward from i: the corners of a dual
  // cube lie at or after its lowest object corner in x-fastest order, and usually close to it.
  [[nodiscard]] int64_t id_from(int64_t i, int64_t idx) const {
    const int64_t n = size();
    int64_t lo = i, step = 1;
    while (lo + step < n && vox[lo + step] < idx) {
      lo += step;
      step *= 2;
    }
    const int64_t hi = std::min(lo + step + 1, n);
    return static_cast<int64_t>(std::lower_bound(vox.begin() + lo, vox.begin() + hi, idx) - vox.begin());
  }
  // Physical position of voxel id i.
  [[nodiscard]] Vec3 position(int64_t i) const {
    const int64_t idx = vox[i], nx = grid.dims[0], ny = grid.dims[1];
    return grid.position(static_cast<double>(idx % nx), static_cast<double>(idx / nx % ny),
                                     static_cast<double>(idx / (nx * ny)));
  }
  // A chain voxel or a chain's end: never merged into a junction node.
  [[nodiscard]] bool is_line(int64_t i) const {
    return cls[i] == static_cast<uint8_t>(ManifoldType::line) || cls[i] == static_cast<uint8_t>(ManifoldType::line_end);
  }
  // Part of a node (everything but the inside of chains).
  [[nodiscard]] bool is_node_voxel(int64_t i) const { return cls[i] != static_cast<uint8_t>(ManifoldType::line); }
};

// The object voxels of `skeleton` (deterministic for any thread count).
SkeletonVoxels collect_voxels(const VolumeU8& skeleton, int threads, const Interrupter& intr);
// The same from a volume.u8 in memory or on disk (ChunkedVolume), read in blocks of `block` voxels
// with a one-voxel halo: vox and hood equal collect_voxels' for any block shape. With `distance`
// (any volume type on the skeleton's grid, in memory or on disk) also sv.rad as read_radius sets
// it. Memory: two blocks with halo (1 B/voxel + the distance's) plus 20 B per object voxel gathered
// (28 B while sorting).
SkeletonVoxels collect_voxels_blocks(const DataObject& skeleton, const Dims& block, const DataObject* distance,
                                     double scale, const Interrupter& intr);
// Phase 1: sv.cls.
void classify_voxels(SkeletonVoxels& sv, int threads, const Interrupter& intr);
// Phase 2: sv.off, sv.adj (each 1-cell in both directions; order fixed for any thread count).
void connect_one_cells(SkeletonVoxels& sv, int threads, const Interrupter& intr);
// sv.rad: distance value x scale at every voxel (any volume type on the skeleton's grid).
void read_radius(SkeletonVoxels& sv, const DataObject& distance, double scale);

// Phase 3: the node root of every id (flattened union-find: parent[i] is the smallest id of its
// set, parent[root] = root); voxels that are not is_line() and are joined by 1-cells share a root.
std::vector<int64_t> collapse_junctions(const SkeletonVoxels& sv);

// The graph being built, with what the edge phases need besides it.
struct GraphBuild {
  SpatialGraph graph;
  bool with_radius = false;
  std::vector<int64_t> node_of;    // node of each node voxel (and of each component root), else -1
  std::vector<double> node_rad;    // per node: largest radius of its voxels
  std::vector<int32_t> node_kind;  // per node: largest ManifoldType of its voxels
  std::vector<std::vector<float>> point_rad;  // per edge: point radii (with_radius only)
  std::vector<uint8_t> visited;    // chain voxels already on an edge
  // The polyline being emitted and its radii.
  std::vector<Vec3> pts;
  std::vector<float> prad;
  void emit(int64_t n0, int64_t n1) {
    graph.edges.push_back(GraphEdge{n0, n1, pts});
    if (with_radius) point_rad.push_back(prad);
  }
};

// Phase 3: one node per component of `parent` (at the centroid of its voxels), numbered in the order
// of their first voxel; a 1-boundary voxel is a component of its own. `with_radius` needs sv.rad.
GraphBuild make_nodes(const SkeletonVoxels& sv, std::vector<int64_t>& parent, bool with_radius);
// Phase 4: an edge per 1-cell between two nodes and per chain of 1-manifold voxels between nodes.
void trace_chains(const SkeletonVoxels& sv, GraphBuild& b);
// Phase 4: tunnels inside collapsed components (e.g. a ring of junction voxels around a hole): each
// independent cycle of the component's cell complex that does not bound its 2-cells becomes a loop
// edge on the component's node, drawn along the cycle's voxels.
void tunnel_loops(const SkeletonVoxels& sv, GraphBuild& b);
// Phase 4: closed chains of 1-manifold voxels (no node on them): a loop edge on a new node at the
// loop's first voxel.
void isolated_loops(const SkeletonVoxels& sv, GraphBuild& b);

}  // namespace skel::geometry::detail
