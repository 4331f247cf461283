#pragma once
// Names of the thinning modules: their specs use these constants, and so does code outside the family
// (the GUI, tests) that names a module, so a rename is one edit here and a misspelt name does not compile.
namespace skel::thinning::names {

inline constexpr const char* doht = "thinning.doht";
inline constexpr const char* lee94 = "thinning.lee94";
inline constexpr const char* grid_cell = "thinning.grid_cell";

}  // namespace skel::thinning::names
