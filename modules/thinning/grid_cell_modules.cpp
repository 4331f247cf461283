// Module of grid cell thinning: thinning.grid_cell (SMOOTHDOGTT, thesis Algorithm 3).
#include <string>
#include <vector>

#include "skel/grid_cells.hpp"
#include "skel/module.hpp"
#include "skel/table.hpp"
#include "thinning/grid_cell.hpp"
#include "thinning/names.hpp"

namespace skel::thinning {
namespace {

class GridCellModule final : public Module {
public:
  static ModuleSpec spec() {
    return ModuleSpec(names::grid_cell,
                      "Grid cell thinning (SMOOTHDOGTT): homotopic grid cell skeleton of a binary object")
        .input<VolumeU8>("mask", "binary object (voxel > 0 is object)")
        .input<AnyVolume>("priority",
                          "removal order, same dims as mask: lower values are removed first (usually a distance transform)")
        .optional_input<VolumeU8>("locked", "voxels (> 0) whose closed cubes (all their cells) are never removed")
        .optional_input<GridCells>("locked_cells", "cells never removed, same voxel dims as mask (e.g. geodesic.plate_cells: a homotopic plate or mixed skeleton, thesis §2.3.3)")
        .output<GridCells>("skeleton", "the grid cell skeleton: a sub-complex of the object's grid cell complex")
        .output<Table>("table", "one row: voxels, cells per dimension before and after, tests, removed pairs, kept end points")
        .param("end_point_length", &GridCellThinningOptions::end_point_length,
               "l as a (0,1)-cell path length: 0 keeps no end points; l > 0 keeps end 0-cells whose path of end points in turn is longer than l 1-cells (thesis fig. 4.2: 2 keeps noise spurs, 4-6 are robust)")
        .range(0, 1000000)
        .unit("1-cells")
        .details(R"(Thesis §2.3.1 "Thinning grid cell complexes" (Proposition 1, Algorithm 3 SMOOTHDOGTT,
(0,1)-cell paths and the importance of cell end points). The object is converted to its grid cell
complex X(P): every object voxel is a closed unit cube - a 3-cell with its six 2-cells, twelve 1-cells
and eight 0-cells, shared with its neighbours (the complex of the (26, 6) voxel object: same
components, cavities, tunnels and Euler characteristic c0 - c1 + c2 - c3).

Simple pairs {c^d, c^(d+1)} are removed: c^d is incident with c^(d+1) and no other cell (Proposition 1),
so every step leaves a sub-complex that is a deformation retract. Cells are queued per (priority level,
dimension of the lower cell); a cell's priority is the voxel priority interpolated at the cell's centre:
the mean over the 2^(3-d) voxels sharing the cell (a cell sits at their mean position), background
voxels counting as one below the lowest object priority - so boundary cells go before interior cells of
the same distance, and the cells shared by most object voxels (junction centres) stay longest. Initially every 2-cell incident with a
background 3-cell is queued. The lowest non-empty (level, dimension) bucket is taken as a whole: all its
cells are checked on the unchanged complex (in parallel), then the candidates are rechecked and removed
one by one (sequential rechecking); each removal queues the unqueued faces (all lower dimensions) of both
cells, and processing restarts at the lowest bucket - so low-dimensional pairs near the boundary go
first and no directional sub-iterations are needed. A 0-cell with exactly one 1-cell is a local cell end
point; its importance is the number of 0-cells along its (0,1)-cell path that are end points in turn
(each after removing the pairs before it); with end_point_length l > 0 an end point of importance > l
is kept. With l = 0 a tree retracts to one 0-cell.

With `locked_cells` (e.g. the geodesic plate skeleton Y_t of geodesic.plate_cells) those cells are kept
as well: the result is Y_t (within the object) plus what the object's homotopy needs - the plate
skeleton of fig. 4.5 made homotopic, or with rods the mixed skeleton of fig. 4.7 (thesis §2.3.3: "its
elements are locked during a subsequent thinning step").

The result contains no 3-cell unless locked: one-dimensional parts are 0- and 1-cells, closed surfaces
around cavities stay as 2-cells. The junction of fig. 2.21 (two rings meeting), which leaves a
cluster of voxels in voxel thinning, retracts to one 0-cell of degree 4. The towers of fig. 2.23 (a
voxel Bing's house) do not retract to a point: removing cells in distance order leaves the medial
surface, the two-dimensional Bing's house, in which every 1-cell bounds two or three 2-cells - no cell
has exactly one coface, so no simple pair exists (it is contractible but not collapsible). A collapse
of the object's complex to a point would have to break out of the medial surface before reaching it
(e.g. collapse a wall from an edge while the voxels beside it still exist); removal in distance order
reaches the medial surface first (tested with walls 1 and 2 voxels thick: one component, no free
face left, no 3-cell). Results are deterministic and identical for any thread count.

Memory: the skeleton (grid cells: 1 byte per voxel corner, (X+1)(Y+1)(Z+1) bytes, eight cells per
byte), the queued flags (1 byte per voxel corner), 4 bytes per queued cell (8 where the Khalimsky box
has 2^32 cells or more, beyond about 810³ voxels) - on thin structures nearly every cell of the object
is queued at some time, up to about one per voxel at once on plates - the buckets (about 72 bytes
each), and with `locked` or `locked_cells` the locked cells (1 byte per voxel corner): 2 bytes per voxel
plus the queue - measured 3.6 (rods) and 5.9 (plates) bytes per voxel in all at 256³, against 1.7-3
for thinning.doht (bench/RESULTS.md). Priorities are read from the input (no copy); the inputs are
read only.)");
  }
  void run(RunContext& ctx) override {
    auto mask = ctx.input<VolumeU8>("mask");
    DataPtr priority = ctx.input_data("priority");
    auto locked = ctx.optional_input<VolumeU8>("locked");
    auto locked_cells = ctx.optional_input<GridCells>("locked_cells");
    GridCellThinningResult r =
        thin_grid_cells(*mask, *priority, locked.get(), ctx.options<GridCellThinningOptions>(), locked_cells.get());
    const auto& s = r.stats;
    if (s.object_voxels == 0) ctx.warn("the mask is empty: the skeleton is empty");
    Table t;
    t.add("object_voxels", std::vector<int64_t>{s.object_voxels});
    const char* names[4] = {"0", "1", "2", "3"};
    for (size_t d = 0; d < 4; ++d) t.add(std::string("cells") + names[d] + "_before", std::vector<int64_t>{s.cells_before[d]});
    for (size_t d = 0; d < 4; ++d) t.add(std::string("cells") + names[d] + "_after", std::vector<int64_t>{s.cells_after[d]});
    t.add("euler", std::vector<int64_t>{s.cells_after[0] - s.cells_after[1] + s.cells_after[2] - s.cells_after[3]});
    t.add("buckets", std::vector<int64_t>{s.buckets});
    t.add("tests", std::vector<int64_t>{s.tests});
    t.add("removed_pairs", std::vector<int64_t>{s.removed_pairs});
    t.add("kept_end_points", std::vector<int64_t>{s.kept_end_points});
    t.add("locked_cells", std::vector<int64_t>{s.locked_cells});
    t.add("working_bytes", std::vector<int64_t>{static_cast<int64_t>(s.bytes)}, "bytes");
    ctx.output("skeleton", std::move(r.skeleton));
    ctx.output("table", std::move(t));
  }
};
SKEL_REGISTER_MODULE(GridCellModule);

}  // namespace
}  // namespace skel::thinning
