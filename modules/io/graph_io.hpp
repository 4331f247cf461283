#pragma once
// SpatialGraph files: Amira SpatialGraph (.am, ASCII), VTK XML PolyData (.vtp), SWC (.swc,
// trees), GraphML (.graphml), CSV (edge points file + nodes file). Written by hand: no VTK or XML
// library in the module library.
//
// Units: every format stores the graph's unit and reads it back (a file without one gives
// kDefaultUnit): .am `Parameters { Units { Coordinates "mm" } }` (Amira's own), .vtp field data
// `unit` (a VTK string array) with `origin` and `direction` when known, .graphml the graph
// attribute `unit`, .swc the comment "# unit: mm", .csv the headers "x [mm]".
//
// Conventions per format:
// - .am: Amira's HxSpatialGraph layout (VertexCoordinates @1, EdgeConnectivity @2, NumEdgePoints
//   @3, EdgePointCoordinates @4, then POINT/VERTEX/EDGE data). The point attribute `radius` is
//   Amira's `thickness`; other attributes keep their names; labels are `int` data. Coordinates are
//   float (as in Amira). The source volume's origin and direction, when known, are the parameters
//   SkelflowOrigin and SkelflowDirection.
// - .vtp (binary appended zlib by default, or ASCII; see VtpEncoding): points = the nodes (one vertex cell each, in id order) followed by every edge's polyline
//   points (each edge owns its points; its first/last point coincide with its node). Line cell data
//   `node0`/`node1` give the node ids; edge attributes are Float32 and edge labels Int32 cell data;
//   point attributes are point data named as in the graph (0 at node points); node attributes and
//   labels are point data named `node.<name>` (0 at polyline points). Coordinates Float64.
// - .swc: one sample per node and per interior polyline point, parents along a breadth-first
//   spanning tree from the lowest node id of each component; radius from `radius` (point / node
//   attribute, else 0), type from node/edge label `swc_type` (else 0). Graphs with loops are
//   rejected. Reading: roots and samples with != 1 child become nodes, chains become edges.
// - .graphml: typed keys that networkx reads as numbers: node keys x, y, z and attributes (double),
//   labels (int); edge keys num_points (int), attributes (double), labels (int), and the polyline as
//   numbers: p<i>_x, p<i>_y, p<i>_z and p<i>_<name> for point attributes (edge keys named p<digits>_
//   are reserved for this). Older files with `points` ("x y z;x y z;...") and `point.<name>`
//   (space-separated values) still read.
// - .csv: `path` holds one row per edge point (edge, node0, node1, point, x, y, z, then
//   `point:<name>`, `edge:<name>`, `edge_label:<name>` columns); `nodes_path` one row per node
//   (node, x, y, z, `node:<name>`, `node_label:<name>`).
#include <filesystem>
#include <string>

#include "skel/enum_names.hpp"
#include "skel/spatial_graph.hpp"

namespace skel::io {

enum class GraphFormat { amira, vtp, swc, graphml, csv };

// Format from the file extension (.am, .vtp, .swc, .graphml, .csv; case-insensitive); throws
// InputError naming `what` for anything else.
GraphFormat graph_format_from_path(const std::filesystem::path& path, const std::string& what = "parameter 'path'");

// How .vtp files are written: binary (appended raw data, zlib-compressed in 32 KiB blocks, UInt64
// headers: what VTK, ParaView and VMTK write by default) or ascii (readable text). Reading takes
// either, and also inline base64, appended base64, UInt32 headers and big-endian files.
enum class VtpEncoding { binary, ascii };
constexpr auto enum_names(VtpEncoding) {
  return std::to_array<EnumName<VtpEncoding>>({{VtpEncoding::binary, "binary"}, {VtpEncoding::ascii, "ascii"}});
}
struct GraphWriteOptions {
  VtpEncoding encoding = VtpEncoding::binary;  // .vtp only; the other formats are text
};

// Writes atomically (temporary file + rename). `nodes_path` is used (and required) for CSV only.
void write_graph(const SpatialGraph& graph, const std::filesystem::path& path, GraphFormat format,
                 const std::filesystem::path& nodes_path = {}, const GraphWriteOptions& options = {});
// Throws InputError naming the file and line/what is wrong for malformed files.
SpatialGraph read_graph(const std::filesystem::path& path, GraphFormat format,
                        const std::filesystem::path& nodes_path = {});

// What io.read_graph does to a graph after reading it: coordinates, radii and other length
// attributes (skel::is_length_attribute) times `scale`; then `unit` (when not empty) replaces the
// file's unit. E.g. a graph in voxel coordinates: scale 0.5, unit "µm".
struct ReadGraphOptions {
  double scale = 1.0;
  std::string unit;
};
void apply_read_options(SpatialGraph& graph, const ReadGraphOptions& options);

// In-memory variants (the CSV nodes table goes to / comes from `nodes_text`).
std::string graph_to_text(const SpatialGraph& graph, GraphFormat format, std::string* nodes_text = nullptr,
                          const GraphWriteOptions& options = {});
SpatialGraph graph_from_text(const std::string& text, GraphFormat format, const std::string& nodes_text = {},
                             const std::string& source = "graph");

}  // namespace skel::io
