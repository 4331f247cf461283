#pragma once
// Names of the volume modules: their specs use these constants, and so does code outside the family
// (the GUI, tests) that names a module, so a rename is one edit here and a misspelt name does not compile.
namespace skel::volume::names {

inline constexpr const char* convert = "volume.convert";
inline constexpr const char* crop = "volume.crop";

}  // namespace skel::volume::names
