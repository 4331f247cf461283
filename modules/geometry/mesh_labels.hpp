#pragma once
// Labels from a voxel volume onto a skeleton mesh (thesis fig. 6.14: rods and plates coloured per
// element): every triangle and line of a mesh made by skeleton_to_mesh gets the label of its voxels.
#include <string>

#include "skel/mesh.hpp"
#include "skel/volume.hpp"

namespace skel::geometry {

// Adds the int attribute `name` to the vertices, triangles and lines of `mesh` from `labels` (any
// volume type; values converted to int32). A vertex that sits on a voxel centre of the labels' grid
// (within a quarter voxel per axis) takes that voxel's value; a triangle or line takes the most
// frequent non-zero value of its voxel vertices (ties: the smallest; 0 when none is labelled); other
// vertices (face centres, centroids) take the value of their first triangle (0 if only on lines).
// Throws InputError when the mesh and the labels are in different units or `name` exists.
void label_mesh(Mesh& mesh, const DataObject& labels, const std::string& name);

}  // namespace skel::geometry
