#pragma once
// Post-processing of skeleton meshes through VTK's filters (thesis §3.1.3: smoothing and triangle
// decimation with 1-x-junction vertices kept fixed) and VTK's flying edges iso-surface for comparison.
// The Mesh is converted to vtkPolyData here and back (io/mesh_vtk.hpp); the Mesh API stays VTK-free.
#include <string>

#include "skel/data.hpp"
#include "skel/mesh.hpp"

namespace skel::geometry {

struct MeshSmoothOptions {
  int iterations = 20;             // windowed sinc iterations
  double pass_band = 0.1;          // in (0, 2]; smaller smooths more
  bool boundary_smoothing = true;  // also smooth surface boundaries
  std::string fixed = "fixed";     // int vertex attribute: vertices with a non-zero value stay in place
};

// vtkWindowedSincPolyDataFilter over triangles and lines (coordinates normalised, non-manifold
// vertices smoothed too); vertices marked in `fixed` get their positions back afterwards, so lines
// stay attached where they were. Topology and attributes are unchanged. A missing `fixed` attribute
// fixes nothing; one that is not int32 is an InputError.
Mesh mesh_smooth(const Mesh& mesh, const MeshSmoothOptions& options = {});

struct MeshDecimateOptions {
  double keep = 0.02;           // fraction of triangles to keep, in (0, 1]
  std::string fixed = "fixed";  // int vertex attribute: vertices with a non-zero value stay in place
};

// vtkQuadricDecimation of the triangles (topology may change; lines are kept as they are). Afterwards
// the output vertex nearest to each fixed surface vertex is put back at the fixed vertex's exact
// position and the lines ending there are attached to it. Vertex and triangle attributes come from the nearest input
// vertex / triangle (by centroid).
Mesh mesh_decimate(const Mesh& mesh, const MeshDecimateOptions& options = {});

struct IsosurfaceOptions {
  double value = 0.5;  // iso-value (0.5 for a mask)
};

// vtkFlyingEdges3D of any volume at `value`, in physical units. The volume is padded with one voxel of
// its minimum value so the surface is closed where the object touches the border. Memory: a float copy
// of the padded volume (4 B/voxel) plus the surface.
Mesh isosurface(const DataObject& volume, const IsosurfaceOptions& options = {});

}  // namespace skel::geometry
