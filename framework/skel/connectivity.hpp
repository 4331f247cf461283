#pragma once
// Voxel adjacency: 6 (faces), 18 (faces and edges) or 26 (faces, edges and corners). The value is the
// number of neighbours, so static_cast<int>(c) is what the algorithms count with.
#include <array>

#include "skel/enum_names.hpp"

namespace skel {

enum class Connectivity : int { c6 = 6, c18 = 18, c26 = 26 };
constexpr auto enum_names(Connectivity) {
  return std::to_array<EnumName<Connectivity>>({{Connectivity::c6, "6"}, {Connectivity::c18, "18"}, {Connectivity::c26, "26"}});
}

}  // namespace skel
