#pragma once
// Names of the synthetic modules: their specs use these constants, and so does code outside the family
// (the GUI, tests) that names a module, so a rename is one edit here and a misspelt name does not compile.
namespace skel::synthetic::names {

inline constexpr const char* altered_network = "synthetic.altered_network";
inline constexpr const char* network = "synthetic.network";
inline constexpr const char* vessel_tree = "synthetic.vessel_tree";

}  // namespace skel::synthetic::names
