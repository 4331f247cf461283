#pragma once
// Names of the segmentation modules: their specs use these constants, and so does code outside the family
// (the GUI, tests) that names a module, so a rename is one edit here and a misspelt name does not compile.
namespace skel::segmentation::names {

inline constexpr const char* threshold = "segmentation.threshold";
inline constexpr const char* gaussian = "segmentation.gaussian";
inline constexpr const char* connected_components = "segmentation.connected_components";
inline constexpr const char* median = "segmentation.median";
inline constexpr const char* illumination_z = "segmentation.illumination_z";
inline constexpr const char* morphology = "segmentation.morphology";
inline constexpr const char* fill_cavities = "segmentation.fill_cavities";

}  // namespace skel::segmentation::names
