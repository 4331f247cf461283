#pragma once
// SpatialGraph files: Amira SpatialGraph (.am, ASCII), VTK XML PolyData (.vtp, ASCII), SWC (.swc,
// trees), GraphML (.graphml), CSV (edge points file + nodes file). Written by hand: no VTK or XML
// library in the module library.
//
// Conventions per format:
// - .am: Amira's HxSpatialGraph layout (VertexCoordinates @1, EdgeConnectivity @2, NumEdgePoints
//   @3, EdgePointCoordinates @4, then POINT/VERTEX/EDGE data). The point attribute `radius` is
//   Amira's `thickness`; other attributes keep their names; labels are `int` data. Coordinates are
//   float (as in Amira).
// - .vtp: points = the nodes (one vertex cell each, in id order) followed by every edge's polyline
//   points (each edge owns its points; its first/last point coincide with its node). Line cell data
//   `node0`/`node1` give the node ids; edge attributes are Float32 and edge labels Int32 cell data;
//   point attributes are point data named as in the graph (0 at node points); node attributes and
//   labels are point data named `node.<name>` (0 at polyline points). Coordinates Float64.
// - .swc: one sample per node and per interior polyline point, parents along a breadth-first
//   spanning tree from the lowest node id of each component; radius from `radius` (point / node
//   attribute, else 0), type from node/edge label `swc_type` (else 0). Graphs with loops are
//   rejected. Reading: roots and samples with != 1 child become nodes, chains become edges.
// - .graphml: node keys x, y, z (double) and attributes (float) / labels (int); edge keys for
//   attributes/labels, `points` ("x y z;x y z;...") and `point.<name>` (space-separated values).
// - .csv: `path` holds one row per edge point (edge, node0, node1, point, x, y, z, then
//   `point:<name>`, `edge:<name>`, `edge_label:<name>` columns); `nodes_path` one row per node
//   (node, x, y, z, `node:<name>`, `node_label:<name>`).
#include <filesystem>
#include <string>

#include "skel/spatial_graph.hpp"

namespace skel::io {

enum class GraphFormat { amira, vtp, swc, graphml, csv };

// Format from the file extension (.am, .vtp, .swc, .graphml, .csv; case-insensitive); throws
// InputError naming `what` for anything else.
GraphFormat graph_format_from_path(const std::filesystem::path& path, const std::string& what = "parameter 'path'");

// Writes atomically (temporary file + rename). `nodes_path` is used (and required) for CSV only.
void write_graph(const SpatialGraph& graph, const std::filesystem::path& path, GraphFormat format,
                 const std::filesystem::path& nodes_path = {});
// Throws InputError naming the file and line/what is wrong for malformed files.
SpatialGraph read_graph(const std::filesystem::path& path, GraphFormat format,
                        const std::filesystem::path& nodes_path = {});

// In-memory variants (the CSV nodes table goes to / comes from `nodes_text`).
std::string graph_to_text(const SpatialGraph& graph, GraphFormat format, std::string* nodes_text = nullptr);
SpatialGraph graph_from_text(const std::string& text, GraphFormat format, const std::string& nodes_text = {},
                             const std::string& source = "graph");

}  // namespace skel::io
