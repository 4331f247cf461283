// Mesh file modules: io.read_mesh and io.write_mesh (with the `skelflow info` inspector).
#include "io/mesh_io.hpp"
#include "io/names.hpp"
#include "skel/module.hpp"

namespace skel::io {
namespace {

constexpr const char* kMeshFormats =
    "By extension: .vtp VTK XML PolyData (binary, zlib-compressed appended data; points, triangles, "
    "polylines, every attribute, the unit), .ply (binary little endian; points, triangles, polylines as "
    "element 'line', every attribute as an int or float property, the unit as a comment; ASCII and big "
    "endian files are read too), .obj (Wavefront; points, triangles, polylines), .stl (binary; triangles "
    "only, vertices merged by equal coordinates; ASCII files are read too), .surf (Amira HxSurface, "
    "ASCII; points and triangles in one patch). Polygons of more than 3 vertices are read as triangle "
    "fans.";

// The extensions the reader and the writer take (their path parameters, the GUI's file dialogs).
const std::vector<std::string> kMeshExtensions = {".vtp", ".ply", ".stl", ".obj", ".surf"};

class ReadMeshModule final : public Module {
public:
  static ModuleSpec spec() {
    return ModuleSpec(names::read_mesh, "Read a mesh file (.vtp, .ply, .stl, .obj, .surf)")
        .output<Mesh>("mesh", "the mesh")
        .path("path", "", PathRole::Input, "mesh file")
        .extensions(kMeshExtensions)
        .details(std::string(kMeshFormats) +
                 " Malformed files are input errors naming the file (and line, for text formats). Memory: "
                 "the file plus the mesh (~30 B per triangle, 4 B per attribute value).");
  }
  void run(RunContext& ctx) override {
    const auto p = ctx.input_path("path");
    ctx.output("mesh", read_mesh(p, mesh_format_from_path(p)));
  }
};
SKEL_REGISTER_MODULE(ReadMeshModule);

class WriteMeshModule final : public Module {
public:
  static ModuleSpec spec() {
    return ModuleSpec(names::write_mesh, "Write a mesh file (.vtp, .ply, .stl, .obj, .surf)")
        .input<Mesh>("mesh", "the mesh")
        .path("path", "", PathRole::Output, "mesh file; the format follows the extension")
        .extensions(kMeshExtensions)
        .details(std::string(kMeshFormats) +
                 " Files appear only when the whole run succeeds (temporary file + rename). Coordinates are "
                 "float (shortest round-trip text in .obj and .surf), so every format reads back the points "
                 "it wrote exactly. Memory: the file's bytes (~50 B per triangle for .stl).");
  }
  void run(RunContext& ctx) override {
    auto m = ctx.input<Mesh>("mesh");
    const auto f = mesh_format_from_path(ctx.final_output_path("path"));
    write_mesh(*m, ctx.output_path("path"), f);
  }
};
SKEL_REGISTER_MODULE(WriteMeshModule);

// .vtp is described by the graph inspector (registered first); the mesh formats of their own here.
SKEL_REGISTER_INSPECTOR("mesh", {".ply", ".stl", ".obj", ".surf"}, [](const std::filesystem::path& p) {
  return read_mesh(p, mesh_format_from_path(p)).describe() + "\n";
});

}  // namespace
}  // namespace skel::io
