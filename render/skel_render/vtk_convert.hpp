#pragma once
// Adapters from Skelflow data objects to VTK data sets for the GUI's 3D view and `skelflow render`.
// Volumes are wrapped without copying (the caller keeps the DataPtr alive as long as the VTK
// object); graphs become poly lines with every point and edge attribute as VTK arrays.
#include <vtkImageData.h>
#include <vtkPolyData.h>
#include <vtkSmartPointer.h>

#include <string>
#include <vector>

#include "skel/data.hpp"
#include "skel/spatial_graph.hpp"

namespace skel::render {

// Voxel values as point scalars ("voxels") of an image with the volume's spacing and origin.
// Throws InputError if `volume` is not a volume.
vtkSmartPointer<vtkImageData> volume_to_image(const DataObject& volume);
// Voxel values as *cell* scalars of an image one larger per axis, shifted by half a voxel: each
// voxel is a cube, so thresholding cells and taking the outer faces draws voxel surfaces.
vtkSmartPointer<vtkImageData> volume_to_cell_image(const DataObject& volume);
// True for uint8 volumes that hold only 0 and 1 (masks and skeletons).
bool is_binary_volume(const DataObject& data);

// One poly line per edge. Point arrays: every point attribute, and edge attributes/labels repeated
// on their points (so tubes and colours can use them); cell arrays: edge attributes and labels.
vtkSmartPointer<vtkPolyData> graph_to_polydata(const SpatialGraph& graph);
// Names of the point arrays graph_to_polydata creates, for the colour-by list.
std::vector<std::string> graph_attribute_names(const SpatialGraph& graph);

}  // namespace skel::render
