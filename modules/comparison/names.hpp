#pragma once
// Names of the comparison modules: their specs use these constants, and so does code outside the family
// (the GUI, tests) that names a module, so a rename is one edit here and a misspelt name does not compile.
namespace skel::comparison::names {

inline constexpr const char* skeleton_distance = "comparison.skeleton_distance";
inline constexpr const char* graph_match = "comparison.graph_match";

}  // namespace skel::comparison::names
