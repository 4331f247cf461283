#pragma once
// Names of the distance modules: their specs use these constants, and so does code outside the family
// (the GUI, tests) that names a module, so a rename is one edit here and a misspelt name does not compile.
namespace skel::distance::names {

inline constexpr const char* chamfer = "distance.chamfer";
inline constexpr const char* euclidean = "distance.euclidean";
inline constexpr const char* feature_transform = "distance.feature_transform";
inline constexpr const char* seeded = "distance.seeded";

}  // namespace skel::distance::names
