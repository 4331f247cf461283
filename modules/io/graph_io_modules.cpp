// Graph file modules: io.read_graph and io.write_graph (with the `skelflow info` inspector).
#include "io/graph_io.hpp"
#include "io/mesh_io.hpp"
#include "io/names.hpp"
#include "skel/module.hpp"

namespace skel::io {
namespace {

constexpr const char* kGraphFormats =
    "By extension: .am Amira SpatialGraph (ASCII; radius = thickness), .vtp VTK XML PolyData (read: ASCII, inline "
    "binary, appended raw or base64, zlib, UInt32/UInt64 headers; written binary appended zlib or ASCII; nodes as vertex cells, edges as polylines, attributes as point/cell data), .swc (trees only), "
    ".graphml, .csv (edge points; the nodes table goes to nodes_path). Attributes and labels are kept in "
    "every format except SWC (radius and swc_type only). The unit is stored in every format (.am Units, .vtp "
    "field data, GraphML graph attribute, SWC '# unit:' comment, CSV headers 'x [mm]').";

// The extensions the reader and the writer take (their path parameters, the GUI's file dialogs).
const std::vector<std::string> kGraphExtensions = {".am", ".vtp", ".swc", ".graphml", ".csv"};

class ReadGraphModule final : public Module {
public:
  static ModuleSpec spec() {
    return ModuleSpec(names::read_graph, "Read a spatial graph file (.am, .vtp, .swc, .graphml, .csv)")
        .output<SpatialGraph>("graph", "the graph")
        .path("path", "", PathRole::Input, "graph file")
        .extensions(kGraphExtensions)
        .path("nodes_path", "", PathRole::Input, "CSV only: nodes table (default: <stem>_nodes.csv)")
        .optional_value()
        .param("scale", &ReadGraphOptions::scale, "multiplies coordinates, radii and every length attribute (e.g. the voxel size of a graph in voxel coordinates)")
        .min(1e-30)
        .param("unit", &ReadGraphOptions::unit, "physical unit of the (scaled) coordinates; empty: the file's (Amira Units, .vtp field data, GraphML graph attribute, SWC/CSV header), else " + std::string(kDefaultUnit))
        .optional_value()
        .details(std::string(kGraphFormats) +
                 " Polyline end points are set to their nodes' positions. Length attributes are those whose name "
                 "contains radius, thickness, diameter or length. Malformed files are input errors naming the file "
                 "and what is wrong. Memory: the file text plus the graph.");
  }
  void run(RunContext& ctx) override {
    const auto p = ctx.input_path("path");
    const std::string np = ctx.param<std::string>("nodes_path");
    SpatialGraph g = read_graph(p, graph_format_from_path(p), np.empty() ? std::filesystem::path() : ctx.input_path("nodes_path"));
    apply_read_options(g, ctx.options<ReadGraphOptions>());
    ctx.output("graph", std::move(g));
  }
};
SKEL_REGISTER_MODULE(ReadGraphModule);

class WriteGraphModule final : public Module {
public:
  static ModuleSpec spec() {
    return ModuleSpec(names::write_graph, "Write a spatial graph file (.am, .vtp, .swc, .graphml, .csv)")
        .input<SpatialGraph>("graph", "the graph")
        .path("path", "", PathRole::Output, "graph file; the format follows the extension")
        .extensions(kGraphExtensions)
        .path("nodes_path", "", PathRole::Output, "CSV only (required there): nodes table file")
        .optional_value()
        .extensions({".csv"})
        .param("encoding", &GraphWriteOptions::encoding, ".vtp only: binary = appended raw data, zlib-compressed (VTK's and ParaView's default, small and exact); ascii = readable text")
        .details(std::string(kGraphFormats) +
                 " Files appear only when the whole run succeeds (temporary file + rename). Coordinates: "
                 "float in .am (Amira's layout), 17 significant digits elsewhere.");
  }
  void run(RunContext& ctx) override {
    auto g = ctx.input<SpatialGraph>("graph");
    const auto fin = ctx.final_output_path("path");
    const auto f = graph_format_from_path(fin);
    std::filesystem::path np;
    if (f == GraphFormat::csv) {
      if (ctx.param<std::string>("nodes_path").empty())
        throw InputError("parameter 'nodes_path': required when writing a .csv graph");
      np = ctx.output_path("nodes_path");
    }
    write_graph(*g, ctx.output_path("path"), f, np, ctx.options<GraphWriteOptions>());
  }
};
SKEL_REGISTER_MODULE(WriteGraphModule);

SKEL_REGISTER_INSPECTOR("spatial graph", {".am", ".vtp", ".swc", ".graphml"}, [](const std::filesystem::path& p) {
  try {
    return read_graph(p, graph_format_from_path(p)).describe() + "\n";
  } catch (const InputError&) {
    if (graph_format_from_path(p) != GraphFormat::vtp) throw;
    // A .vtp written by io.write_mesh (binary, triangles) is a mesh, not a graph.
    try {
      return "not a spatial graph but a " + read_mesh(p, MeshFormat::vtp).describe() + "\n";
    } catch (const InputError&) {
    }
    throw;
  }
});

}  // namespace
}  // namespace skel::io
