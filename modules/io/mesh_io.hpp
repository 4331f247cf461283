#pragma once
// Mesh files (io.read_mesh / io.write_mesh): .vtp VTK XML PolyData (binary, zlib-compressed appended
// data, through VTK's XML writer and reader), .ply (binary little endian; reads ASCII and both binary
// byte orders), .stl (binary; reads ASCII too), .obj (Wavefront, ASCII), .surf (Amira HxSurface,
// ASCII). What each format carries:
//   .vtp   points, triangles, polylines, every attribute, the unit
//   .ply   points, triangles, polylines (element "line"), every attribute (int/float properties), the unit
//          (comment "unit")
//   .obj   points, triangles, polylines (comment "unit")
//   .stl   triangles only (vertices are merged by equal coordinates, in order of first use)
//   .surf  points and triangles (one patch)
// Readers check counts against the file before allocating and throw InputError naming the file (and
// the line, for text formats); writers write through write_file_atomically / write_atomically.
#include <filesystem>
#include <string>

#include "skel/mesh.hpp"

namespace skel::io {

enum class MeshFormat { vtp, ply, stl, obj, surf };

// Format from the extension (.vtp, .ply, .stl, .obj, .surf; case-insensitive); throws InputError
// naming `what` for anything else.
MeshFormat mesh_format_from_path(const std::filesystem::path& path, const std::string& what = "parameter 'path'");

void write_mesh(const Mesh& mesh, const std::filesystem::path& path, MeshFormat format);
Mesh read_mesh(const std::filesystem::path& path, MeshFormat format);

}  // namespace skel::io
