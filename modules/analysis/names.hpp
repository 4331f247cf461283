#pragma once
// Names of the analysis modules: their specs use these constants, and so does code outside the family
// (the GUI, tests) that names a module, so a rename is one edit here and a misspelt name does not compile.
namespace skel::analysis::names {

inline constexpr const char* topology = "analysis.topology";
inline constexpr const char* network_statistics = "analysis.network_statistics";
inline constexpr const char* trees = "analysis.trees";
inline constexpr const char* label_propagation = "analysis.label_propagation";
inline constexpr const char* report = "analysis.report";
inline constexpr const char* dangling_ends = "analysis.dangling_ends";
inline constexpr const char* tubularity = "analysis.tubularity";  // rods_plates_modules.cpp (algorithm: geodesic/surface.hpp)
inline constexpr const char* rods_plates = "analysis.rods_plates";  // rods_plates_modules.cpp (algorithm: geodesic/surface.hpp)
inline constexpr const char* rods_plates_elements = "analysis.rods_plates_elements";

}  // namespace skel::analysis::names
