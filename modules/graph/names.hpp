#pragma once
// Names of the graph modules: their specs use these constants, and so does code outside the family
// (the GUI, tests) that names a module, so a rename is one edit here and a misspelt name does not compile.
namespace skel::graph::names {

inline constexpr const char* prune = "graph.prune";
inline constexpr const char* filter = "graph.filter";
inline constexpr const char* apply_edits = "graph.apply_edits";
inline constexpr const char* merge_centerlines = "graph.merge_centerlines";

}  // namespace skel::graph::names
