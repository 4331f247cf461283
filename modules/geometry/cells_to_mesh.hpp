#pragma once
// Grid cell skeleton -> piecewise linear geometry and graphs (thesis §3.2 "Geometry of Grid Cell
// Skeletons", figs. 3.19-3.22). The complex is already a cell complex: cells are classified by their
// cofaces (0-cells by the rules of fig. 3.9, 1- and 2-cells by §3.2), 1-cells without a 2-cell become
// line segments, 2-cells become quads (two triangles).
#include <cstdint>

#include "geometry/skeleton_to_graph.hpp"
#include "skel/enum_names.hpp"
#include "skel/grid_cells.hpp"
#include "skel/interrupter.hpp"
#include "skel/mesh.hpp"
#include "skel/spatial_graph.hpp"

namespace skel::geometry {

// Class of a cell of a complex without... (codes of ManifoldType; 0-cells use all of them):
//   0-cell: point, line, line_end, surface, surface_edge, junction, line_junction (fig. 3.9);
//   1-cell: line (no 2-cell: 1-manifold), surface (two 2-cells, no 3-cell), surface_edge (one 2-cell,
//           no 3-cell), junction (otherwise);
//   2-cell: surface (no 3-cell), junction (a 3-cell).
ManifoldType classify_cell(const GridCells& cells, int64_t kx, int64_t ky, int64_t kz);

enum class CellGeometry {
  simple,   // 1-cell = one segment between its 0-cells, 2-cell = one quad (two triangles)
  detailed  // 3x3x3 subdivision (fig. 3.20): 1-cell = 3 segments, 2-cell = 9 tiles (18 triangles)
};
constexpr auto enum_names(CellGeometry) {
  return std::to_array<EnumName<CellGeometry>>({{CellGeometry::simple, "simple"}, {CellGeometry::detailed, "detailed"}});
}

struct CellsToMeshOptions {
  CellGeometry geometry = CellGeometry::simple;
  Interrupter interrupter;
};

// Attributes (as geometry.skeleton_to_mesh): vertex `manifold` (the class of the 0-cell at the vertex;
// subdivision vertices: the class of the 1- or 2-cell they lie in) and `fixed` (1 at 1-x-junction
// 0-cells); triangle and line `manifold` (1 all-manifold, 0 not-all-manifold) and `cell_class` (the class
// code of the cell the primitive represents: in detailed geometry, a tile at a corner represents the
// 0-cell, at a side the 1-cell, in the centre the 2-cell, and a segment's ends their 0-cells).
// all-manifold: a 1-manifold 1-cell whose 0-cells are line or line_end; a 2-cell without 3-cell whose
// 0-cells are surface or surface_edge; detailed tiles and segments: the cell they represent is manifold
// (0-cell line/line_end/surface/surface_edge, 1-cell line/surface/surface_edge, 2-cell surface).
// Vertices: physical positions of the voxel corners (origin + (p - 0.5)·spacing), in raster order of
// the cells that make them. Every 2-cell gives its triangles once; isolated 0-cells give no geometry.
Mesh cells_to_mesh(const GridCells& cells, const CellsToMeshOptions& options = {});

// Graph of the one-dimensional part (1-cells without a 2-cell): nodes are the 0-cells that do not have
// exactly two such 1-cells or that touch a 2-cell (end points, junctions, attachments to surfaces), edges
// the chains of 1-cells between them (polylines through the voxel corners); a closed chain without a
// node gets one node at its first 0-cell (raster order) and a loop edge. Node label `manifold` (class
// of the 0-cell), edge attribute `length`. Unit, origin and direction from the complex's grid.
SpatialGraph cells_to_graph(const GridCells& cells, const Interrupter& interrupter = {});

}  // namespace skel::geometry
