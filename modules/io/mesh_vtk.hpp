#pragma once
// Mesh <-> vtkPolyData, the only conversion between skelflow's VTK-free Mesh and VTK (used by the .vtp
// format, the VTK mesh filters of the geometry family and the GUI's view).
//
// Layout in vtkPolyData: points as float; lines (polylines) first, then triangles as polys, so the
// cell data holds the line values first. Vertex attributes become point data, triangle and line
// attributes cell data (int32 -> vtkIntArray, float -> vtkFloatArray). An attribute that only one
// kind of primitive has is padded with 0 on the other; field-data string arrays
// "skelflow_triangle_attributes" / "skelflow_line_attributes" list which names belong to which, and
// "unit" holds the length unit, so a round trip restores the Mesh exactly.
#include <string>

#include <vtkPolyData.h>
#include <vtkSmartPointer.h>

#include "skel/mesh.hpp"

namespace skel::io {

vtkSmartPointer<vtkPolyData> mesh_to_vtk(const Mesh& mesh);

// Converts polydata back. Polygons of more than 3 vertices are split into triangle fans (their cell
// values repeated); vertex cells are ignored; triangle strips are split into triangles. Point and
// cell arrays of one component become attributes (integer types -> int32, others -> float); without
// the skelflow field data every cell array becomes a triangle attribute when there are triangles and
// a line attribute when there are lines. `what` names the source in messages (a file).
Mesh mesh_from_vtk(vtkPolyData& poly, const std::string& what);

}  // namespace skel::io
