// Modules of grid cell skeleton geometry: geometry.cells_to_mesh and geometry.cells_to_graph (thesis §3.2).
// Kept apart from geometry_modules.cpp (the voxel skeleton modules).
#include "geometry/cells_to_mesh.hpp"
#include "geometry/names.hpp"
#include "skel/module.hpp"

namespace skel::geometry {
namespace {

class CellsToMeshModule final : public Module {
public:
  static ModuleSpec spec() {
    return ModuleSpec(names::cells_to_mesh, "Grid cell skeleton to a triangle mesh and line segments (simple or detailed geometry)")
        .input<GridCells>("cells", "grid cell skeleton (e.g. from thinning.grid_cell)")
        .output<Mesh>("mesh", "quads of 2-cells as triangles, bare 1-cells as segments, in physical units, with cell classes")
        .param("geometry", &CellsToMeshOptions::geometry,
               "simple: a 2-cell is one quad, a 1-cell one segment; detailed: the 3x3x3 subdivision of fig. 3.20 (9 tiles per 2-cell, 3 segments per 1-cell)")
        .details(R"(Thesis §3.2 "Geometry of Grid Cell Skeletons" (figs. 3.19-3.22). Cells are classified by
their cofaces: a 0-cell by the rules of fig. 3.9 (codes of `manifold`: 1 0-manifold, 2 1-manifold,
3 1-boundary, 4 2-manifold, 5 2-boundary, 6 junction, 7 1-x-junction: a junction with a 1-cell that
bounds no 2-cell); a 1-cell is 1-manifold (2) without 2-cells, 2-manifold (4) with two 2-cells and no
3-cell, 2-boundary (5) with one, else a junction (6); a 2-cell is 2-manifold (4) without 3-cell, else a
junction (6).

simple: every 2-cell becomes a quad through its four 0-cells (two triangles), every 1-manifold 1-cell a
segment between its two 0-cells; a triangle is all-manifold (`manifold` 1) when its 2-cell is 2-manifold
and its 0-cells are 2-manifold or 2-boundary, a segment when both 0-cells are 1-manifold or 1-boundary.
detailed: vertices on the 3x3x3 subdivided grid of the 0-cells (one third and two thirds along every
cell); a 2-cell is nine tiles (corner tiles represent its 0-cells, side tiles its 1-cells, the centre
tile the 2-cell), a 1-cell three segments (its two ends represent its 0-cells); a tile or segment is
all-manifold when the cell it represents is. Triangle and line attribute `cell_class`: the class code of
that cell. Vertex attributes `manifold` (class of the cell the vertex lies in) and `fixed` (1 at
1-x-junction 0-cells, for mesh_smooth and mesh_decimate). Vertices are shared through their subdivided
grid position, so every 2-cell is made once and neighbouring quads share their edges; positions are the
voxel corners, origin + (p - 0.5)·spacing.

Memory: the input complex (1 byte per voxel corner) and the mesh: ~30 B per triangle (simple: 2
triangles per 2-cell; detailed: 18) and 12 B + 8 B of attributes per vertex, plus a hash of 24 B per
vertex while building.)");
  }
  void run(RunContext& ctx) override {
    auto cells = ctx.input<GridCells>("cells");
    ctx.output("mesh", cells_to_mesh(*cells, ctx.options<CellsToMeshOptions>()));
  }
};
SKEL_REGISTER_MODULE(CellsToMeshModule);

class CellsToGraphModule final : public Module {
public:
  static ModuleSpec spec() {
    return ModuleSpec(names::cells_to_graph, "Grid cell skeleton to a spatial graph (1-cells to edges, junction 0-cells to nodes)")
        .input<GridCells>("cells", "grid cell skeleton (e.g. from thinning.grid_cell)")
        .output<SpatialGraph>("graph", "nodes at end points and junctions, edges with polylines through the voxel corners")
        .details(R"(The one-dimensional part of a grid cell skeleton as a graph (thesis §3.2 with §3.1.2): the
1-cells that bound no 2-cell are chained; nodes are the 0-cells on such 1-cells that do not have exactly
two of them (end points, junctions) or that also touch a 2-cell or 3-cell (where lines attach to
surfaces); edges run between nodes through the 0-cells of the chain (positions: voxel corners,
origin + (p - 0.5)·spacing). A closed chain without a node gets one node at its first 0-cell (raster
order) and a loop edge (degree 2). Node label `manifold`: the 0-cell class (codes as in
geometry.cells_to_mesh); edge attribute `length` in the grid's unit. Unit, origin and direction come from
the complex's grid, so the graph overlays the image. Memory: the input complex, 1 byte per voxel corner
of visited flags, ~40 B per graph point.)");
  }
  void run(RunContext& ctx) override {
    auto cells = ctx.input<GridCells>("cells");
    ctx.output("graph", cells_to_graph(*cells, ctx.progress()));
  }
};
SKEL_REGISTER_MODULE(CellsToGraphModule);

}  // namespace
}  // namespace skel::geometry
