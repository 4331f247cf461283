#pragma once
// Thinning in the grid cell model (thesis §2.3.1 "Thinning grid cell complexes", Proposition 1,
// Algorithm 3 SMOOTHDOGTT, (0,1)-cell paths and cell end-point importance).
//
// The object's grid cell complex X(P) (skel::GridCells) is shrunk by removing simple pairs of cells
// {c^d, c^(d+1)}: c^d is incident with c^(d+1) and with no other cell of the complex (Proposition 1),
// so what remains is a sub-complex and a deformation retract. Components, cavities, tunnels and the
// Euler characteristic are kept exactly; the junction that locks thinning in the grid point model
// (fig. 2.21) retracts to one 0-cell; the towers of fig. 2.23 end as the 2-D Bing's house, which has no
// simple pair (contractible, not collapsible).
#include <cstdint>

#include "skel/data.hpp"
#include "skel/grid_cells.hpp"
#include "skel/interrupter.hpp"
#include "skel/volume.hpp"

namespace skel::thinning {

struct GridCellThinningOptions {
  // End-point importance as a (0,1)-cell path length l: 0 keeps no end points; l > 0 keeps a local cell
  // end point (a 0-cell with exactly one 1-cell) whose importance - the number of 0-cells c_0, c_1, ...
  // of its (0,1)-cell path that are local end points in turn, each after removing the pairs before it -
  // exceeds l. The thesis (fig. 4.2) uses 0, 2, 4, 6; 2 keeps noise spurs, 4-6 are robust.
  int end_point_length = 6;
  int threads = 0;  // parallel candidate checks and the conversion; results do not depend on it
  Interrupter interrupter;
};

struct GridCellThinningStatistics {
  int64_t object_voxels = 0;
  std::array<int64_t, 4> cells_before{};  // c0..c3 of X(P)
  std::array<int64_t, 4> cells_after{};   // c0..c3 of the skeleton
  int64_t buckets = 0;          // (priority, dimension) buckets taken from the queue
  int64_t tests = 0;            // deletability tests (parallel checks and sequential rechecks)
  int64_t removed_pairs = 0;
  int64_t kept_end_points = 0;  // 0-cells of the skeleton kept as end points (free pair refused)
  int64_t locked_cells = 0;     // cells of the skeleton that are locked (closure of a locked voxel or in locked_cells)
  uint64_t bytes = 0;           // peak working memory (without input and output)
};

struct GridCellThinningResult {
  GridCells skeleton;
  GridCellThinningStatistics stats;
};

// Thins the grid cell complex of `mask` (non-zero = object). `priority`: any volume on the same dims
// (lower = removed first); a cell's priority is the mean over the 2^(3-d) voxels sharing it, background
// voxels counting as one below the lowest object priority. `locked` (optional, same dims): the cells of the closed cubes of its non-zero voxels
// are never removed. `locked_cells` (optional, same voxel dims): its cells are never removed (e.g. the
// geodesic plate skeleton Y_t, geodesic/cells.hpp; cells outside the object are ignored). Throws
// InputError on mismatched dims or a NaN priority, Cancelled when asked.
GridCellThinningResult thin_grid_cells(const VolumeU8& mask, const DataObject& priority, const VolumeU8* locked = nullptr,
                                       const GridCellThinningOptions& options = {}, const GridCells* locked_cells = nullptr);

// Topology of a cell complex: components (cells joined by incidence), cavities (bounded components of
// the complement in R³), Euler characteristic (c0 - c1 + c2 - c3), tunnels = components + cavities -
// euler. For tests and small complexes: 8 bytes per Khalimsky cell (64 bytes per voxel).
struct CellTopology {
  int64_t components = 0, cavities = 0, euler = 0, tunnels = 0;
  bool operator==(const CellTopology&) const = default;
};
CellTopology cell_topology(const GridCells& cells);

// Local tests, shared with tests and geometry code.
// Number of cofaces of dimension dim(k) + 1 of cell k in `cells` (0 for a 3-cell).
int coface_count(const GridCells& cells, int64_t kx, int64_t ky, int64_t kz);
// Whether cell k (present) is the lower cell of a simple pair (Proposition 1): exactly one coface.
inline bool has_free_pair(const GridCells& cells, int64_t kx, int64_t ky, int64_t kz) {
  return cells.has(kx, ky, kz) && coface_count(cells, kx, ky, kz) == 1;
}
// Importance of a local cell end point (0-cell k with exactly one 1-cell), counted up to `cap`.
int end_point_importance(const GridCells& cells, int64_t kx, int64_t ky, int64_t kz, int cap);

}  // namespace skel::thinning
