#pragma once
// Names of the geometry modules: their specs use these constants, and so does code outside the family
// (the GUI, tests) that names a module, so a rename is one edit here and a misspelt name does not compile.
namespace skel::geometry::names {

inline constexpr const char* skeleton_to_graph = "geometry.skeleton_to_graph";
inline constexpr const char* skeleton_to_mesh = "geometry.skeleton_to_mesh";
inline constexpr const char* mesh_smooth = "geometry.mesh_smooth";
inline constexpr const char* mesh_decimate = "geometry.mesh_decimate";
inline constexpr const char* isosurface = "geometry.isosurface";
inline constexpr const char* mesh_labels = "geometry.mesh_labels";  // mesh_labels_modules.cpp

}  // namespace skel::geometry::names

// Grid cell skeleton geometry (cells_to_mesh_modules.cpp).
namespace skel::geometry::names {
inline constexpr const char* cells_to_mesh = "geometry.cells_to_mesh";
inline constexpr const char* cells_to_graph = "geometry.cells_to_graph";
}  // namespace skel::geometry::names
