#pragma once
// Names of the geodesic modules: their specs use these constants, and so does code outside the family
// (the GUI, tests) that names a module, so a rename is one edit here and a misspelt name does not compile.
namespace skel::geodesic::names {

inline constexpr const char* boundary_distance = "geodesic.boundary_distance";
inline constexpr const char* thin_surface = "geodesic.thin_surface";
inline constexpr const char* plate_cells = "geodesic.plate_cells";

}  // namespace skel::geodesic::names
