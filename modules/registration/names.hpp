#pragma once
// Names of the registration modules: their specs use these constants, and so does code outside the family
// (the GUI, tests) that names a module, so a rename is one edit here and a misspelt name does not compile.
namespace skel::registration::names {

inline constexpr const char* landmarks = "registration.landmarks";
inline constexpr const char* refine = "registration.refine";
inline constexpr const char* apply_transform = "registration.apply_transform";
inline constexpr const char* stitch_tiles = "registration.stitch_tiles";

}  // namespace skel::registration::names
