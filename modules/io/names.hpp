#pragma once
// Names of the io modules: their specs use these constants, and so does code outside the family
// (the GUI, tests) that names a module, so a rename is one edit here and a misspelt name does not compile.
namespace skel::io::names {

inline constexpr const char* read_graph = "io.read_graph";
inline constexpr const char* write_graph = "io.write_graph";
inline constexpr const char* read_volume = "io.read_volume";
inline constexpr const char* write_volume = "io.write_volume";
inline constexpr const char* write_table = "io.write_table";
inline constexpr const char* read_landmarks = "io.read_landmarks";
inline constexpr const char* write_landmarks = "io.write_landmarks";
inline constexpr const char* read_transform = "io.read_transform";
inline constexpr const char* write_transform = "io.write_transform";
inline constexpr const char* read_mesh = "io.read_mesh";
inline constexpr const char* write_mesh = "io.write_mesh";
inline constexpr const char* read_cells = "io.read_cells";    // grid_cells_io_modules.cpp
inline constexpr const char* write_cells = "io.write_cells";

}  // namespace skel::io::names
