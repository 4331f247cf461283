// Module of the geodesic plate skeleton in the grid cell model: geodesic.plate_cells (thesis §2.3.2, fig. 4.5).
#include <vector>

#include "geodesic/cells.hpp"
#include "geodesic/names.hpp"
#include "skel/grid_cells.hpp"
#include "skel/module.hpp"
#include "skel/table.hpp"

namespace skel::geodesic {
namespace {

class PlateCells final : public Module {
public:
  static ModuleSpec spec() {
    return ModuleSpec(names::plate_cells,
                      "Geodesic plate skeleton of 2-cells: grid cells whose geodesic boundary distance reaches a threshold")
        .input<VolumeU8>("mask", "binary object (voxel > 0 is object)")
        .output<GridCells>("cells", "Y_t: the 2-cells with importance >= threshold and their faces (a sub-complex of the object's grid cell complex)")
        .output<Table>("table", "statistics: object and boundary-layer voxels, searches, visited layer voxels, selected 2-cells, cells per dimension, memory")
        .param("threshold", &PlateCellsOptions::threshold,
               "t: a 2-cell belongs to the skeleton when the geodesic distance of the nearest background points of its two voxels is >= t")
        .range(1, 1000000)
        .unit("voxel steps")
        .details(R"(Thesis §2.3.2 ("a value is associated with every 2-cell of the object's grid cell complex")
and fig. 4.5. The 2-cell c{p,q} between an object voxel p and its 6-neighbour q (object or background)
gets the importance g(b(p), b(q)): b is the nearest background point (as geodesic.boundary_distance),
g the length of the shortest 6-path in the background layer L (background voxels 26-adjacent to the
object), infinite where none exists. The 2-cells with g >= t and all their faces form the skeleton
Y_t: in a plate, the 2-cells between voxels whose nearest background points lie on the two sides -
one sheet of 2-cells in the middle of the plate, without a voxel staircase. The voxels that consider
a selected 2-cell (the upper of two object voxels, or the object voxel at the boundary) are exactly the
voxels of geodesic.boundary_distance's surface skeleton with the same threshold.

The thesis uses t = 100 and 200 on the chamfer-(3,4,5) distance along the boundary, i.e. about 33 and
67 voxel steps here. Y_t does not keep the object's homotopy (rods vanish, narrow parts of plates
open holes; cavities are kept: their inside cannot reach the outside in L); lock it in
thinning.grid_cell (input locked_cells) for a homotopic plate or mixed skeleton (§2.3.3, fig. 4.7).
Make geometry with geometry.cells_to_mesh (2-cells as quads), then geometry.mesh_smooth and
geometry.mesh_decimate (fig. 4.5 rows 4-5).

Implementation: the phases of geodesic.boundary_distance (nearest points, voxels grouped by base
point) and one breadth-first search per base point to t, stopping when all targets of its voxels are
reached; the distances are kept per 2-cell (no pivots, since no voxel is settled by a single
saturated target). Results do not depend on the thread count.

Memory (beyond the mask): the output complex (1 byte per voxel corner) and the face bits (1 byte per
voxel), and the phases of geodesic.boundary_distance: 4 bits per voxel of the padded grid, 4 (b(p)) + 4
(bucket position) bytes per object voxel, 6 + 4 + 4 bytes per boundary-layer voxel plus 1 per
boundary-layer voxel and worker thread.)");
  }
  void run(RunContext& ctx) override {
    auto mask = ctx.input<VolumeU8>("mask");
    PlateCellsResult r = plate_cells(*mask, ctx.options<PlateCellsOptions>());
    const auto& s = r.stats;
    if (s.object_voxels == 0) ctx.warn("the mask is empty: the skeleton is empty");
    else if (s.selected_faces == 0) ctx.warn("no 2-cell reaches the threshold: the skeleton is empty (lower threshold?)");
    const auto c = r.cells.counts();
    Table t;
    t.add("object_voxels", std::vector<int64_t>{s.object_voxels});
    t.add("layer_voxels", std::vector<int64_t>{s.layer_voxels});
    t.add("searches", std::vector<int64_t>{s.searches});
    t.add("visited", std::vector<int64_t>{s.visited});
    t.add("selected_2cells", std::vector<int64_t>{s.selected_faces});
    t.add("cells0", std::vector<int64_t>{c[0]});
    t.add("cells1", std::vector<int64_t>{c[1]});
    t.add("cells2", std::vector<int64_t>{c[2]});
    t.add("euler", std::vector<int64_t>{c[0] - c[1] + c[2] - c[3]});
    t.add("working_bytes", std::vector<int64_t>{static_cast<int64_t>(s.bytes)}, "bytes");
    ctx.output("cells", std::move(r.cells));
    ctx.output("table", std::move(t));
  }
};
SKEL_REGISTER_MODULE(PlateCells);

}  // namespace
}  // namespace skel::geodesic
