#pragma once
// Graph-to-graph operations on SpatialGraph: merging chains at degree-2 nodes, pruning short
// terminal branches, filtering edges by an attribute (thesis §3.1.2 simplification, §6.1).
#include <cstdint>
#include <limits>
#include <string>

#include "skel/interrupter.hpp"
#include "skel/spatial_graph.hpp"

namespace skel::graph {

// Joins the two edges at every node of degree 2 (two distinct edges) into one edge and removes the
// node; polylines and point attributes are concatenated, edge attributes become the length-weighted
// mean, edge labels are taken from the lower edge id. Isolated loops keep their single node.
// Returns the number of nodes removed.
int64_t merge_degree_two(SpatialGraph& graph);

struct PruneOptions {
  double min_length = 0.0;  // physical units; terminal branches shorter than this are removed
  int max_iterations = 0;   // 0 = until nothing changes
  Interrupter interrupter;
  // Thickness-relative threshold: a terminal branch is also removed when it is shorter than
  // radius_factor times the radius at its junction end (point attribute `radius`). A spur grown from
  // a bump on the surface of a vessel of radius r is about r long, whatever r is, so one absolute
  // length cannot remove spurs on thick vessels without removing real ends of thin ones. 0 = off.
  double radius_factor = 0.0;
  std::string radius = "radius";
};
struct PruneStats {
  int64_t removed_edges = 0;
  int64_t merged_nodes = 0;
  int iterations = 0;
};
// A terminal branch: an edge from a `tip` of degree 1 to a `junction` of degree >= 3.
struct Spur {
  int64_t edge = -1, tip = -1, junction = -1;
  double length = 0.0;  // polyline length
};
// The prune rule, shared by graph.prune and the graph editor's prune operation: the terminal
// branches (loops excluded) shorter than max(min_length, radius_factor × the point attribute
// `radius` at their junction end; radius_factor 0 = the absolute length only), in edge order.
// `degrees` = graph.degrees(). No parameter checks (the callers report them in their own terms).
std::vector<Spur> find_spurs(const SpatialGraph& graph, const std::vector<int64_t>& degrees,
                             const PruneOptions& options);

// Iteratively removes terminal edges (one end of degree 1, the other of degree >= 3) shorter than
// max(min_length, radius_factor * radius at the junction end), shortest first per junction and never leaving a junction with fewer than two edges,
// then merges the edges at nodes left with degree 2. Isolated edges (both ends free) are kept.
PruneStats prune(SpatialGraph& graph, const PruneOptions& options);

// Per-edge value used by filters and statistics: "length" (polyline length), an edge attribute,
// an edge label, or a point attribute (length-weighted mean along the edge). Throws InputError
// naming `what` when the name is none of these.
std::vector<double> edge_values(const SpatialGraph& graph, const std::string& name, const std::string& what);

struct FilterOptions {
  std::string attribute = "length";
  double min = -std::numeric_limits<double>::infinity();
  double max = std::numeric_limits<double>::infinity();
  bool remove_isolated_nodes = true;  // nodes left without edges
  bool merge = false;                 // merge degree-2 nodes afterwards
};
// Keeps the edges whose value lies in [min, max]; returns the number of edges removed.
int64_t filter_edges(SpatialGraph& graph, const FilterOptions& options);

}  // namespace skel::graph
