#pragma once
// SpatialGraph: nodes with positions, edges with polylines, named attributes (type id "graph").
//
// Storage (structure of arrays, plain value semantics like Volume):
//   - nodes: `positions[n]` in the physical unit `unit` (the source volume's, or the file's).
//   - edges: `edges[e] = {node0, node1, points}`; `points` is the polyline *including* both end node
//     positions, so points.front() == positions[node0] and points.back() == positions[node1].
//     A loop edge has node0 == node1 (a closed ring hangs on one node of degree 2).
//   - attributes: float per node / edge / point (`radius`, `thickness`, `length` ...) and int32
//     labels per node / edge (`tree`, `kind`, `branch_order` ...). Point attributes are stored per
//     edge (values[e][i] belongs to edges[e].points[i]).
//
// Ids are dense (0..count-1). Single removals are O(1) (edges) by moving the *last* element into the
// hole ("swap and pop"); they return the old id of the moved element so an editing layer can keep
// its bookkeeping and undo exactly (re-insert = push_back + swap back). Batch removals
// (remove_edges / remove_nodes) compact in one O(N + E) pass and keep the relative order.
// Published graphs are shared as std::shared_ptr<const SpatialGraph> (cheap to share); an editor
// copies once and then edits its own copy in place (copy-on-write at the object level).
#include <cstdint>
#include <map>
#include <string>
#include <vector>

#include "skel/data.hpp"
#include "skel/volume.hpp"

namespace skel {

struct GraphEdge {
  int64_t node0 = -1;
  int64_t node1 = -1;
  std::vector<Vec3> points;  // polyline incl. both end node positions (>= 2 points)
};

// Compressed adjacency: the edges incident to node n are edge_ids[offsets[n] .. offsets[n+1]);
// a loop edge appears twice at its node (it adds 2 to the degree).
struct GraphAdjacency {
  std::vector<int64_t> offsets;
  std::vector<int64_t> edge_ids;
  [[nodiscard]] int64_t degree(int64_t n) const { return offsets[n + 1] - offsets[n]; }
};

class SpatialGraph final : public DataObject {
public:
  template <class T>
  using Attributes = std::map<std::string, std::vector<T>, std::less<>>;
  using PointAttributes = std::map<std::string, std::vector<std::vector<float>>, std::less<>>;

  // ---- data (public: algorithms fill them directly; check_invariants() says what is off) ----
  std::vector<Vec3> positions;  // node positions
  std::vector<GraphEdge> edges;
  Attributes<float> node_attributes;    // values[n]
  Attributes<int32_t> node_labels;      // values[n]
  Attributes<float> edge_attributes;    // values[e]
  Attributes<int32_t> edge_labels;      // values[e]
  PointAttributes point_attributes;     // values[e][i]
  // Physical unit of positions, polylines, lengths and radii: the source volume's grid unit, or what
  // the graph file says (kDefaultUnit when it says nothing).
  std::string unit{kDefaultUnit};
  // Grid of the volume the graph came from (dims 0 when unknown): bounding box for densities,
  // target grid for label propagation; its origin and direction go to the graph files so that the
  // graph overlays the image. Its unit equals `unit` when known.
  Grid source_grid;

  [[nodiscard]] int64_t node_count() const { return static_cast<int64_t>(positions.size()); }
  [[nodiscard]] int64_t edge_count() const { return static_cast<int64_t>(edges.size()); }
  [[nodiscard]] int64_t point_count() const;  // sum of polyline sizes

  // ---- construction (keeps every attribute array sized; new entries get 0) ----
  int64_t add_node(const Vec3& position);
  // Adds an edge; empty `points` means the straight segment {positions[n0], positions[n1]}.
  // Throws Error on invalid node ids or a polyline of < 2 points.
  int64_t add_edge(int64_t node0, int64_t node1, std::vector<Vec3> points = {});
  // Removes edge e; the last edge takes id e. Returns the old id of the moved edge, or -1 if e was
  // the last one. O(1) plus the attributes.
  int64_t remove_edge(int64_t e);
  // Removes node n and its incident edges (each by remove_edge); the last node takes id n and the
  // edges that referenced it are renumbered. Returns the old id of the moved node or -1. O(E).
  int64_t remove_node(int64_t n);
  // Batch removal keeping order; returns old→new id (-1 for removed). O(N + E).
  std::vector<int64_t> remove_edges(const std::vector<int64_t>& ids);
  // Removes the nodes and their incident edges, keeping order; returns old→new node id. O(N + E).
  std::vector<int64_t> remove_nodes(const std::vector<int64_t>& ids);

  // Creates (or resizes) the attribute with `fill` for every entry and returns it.
  std::vector<float>& ensure_node_attribute(const std::string& name, float fill = 0.0f);
  std::vector<int32_t>& ensure_node_label(const std::string& name, int32_t fill = 0);
  std::vector<float>& ensure_edge_attribute(const std::string& name, float fill = 0.0f);
  std::vector<int32_t>& ensure_edge_label(const std::string& name, int32_t fill = 0);
  std::vector<std::vector<float>>& ensure_point_attribute(const std::string& name, float fill = 0.0f);

  // ---- queries ----
  [[nodiscard]] std::vector<int64_t> degrees() const;  // loop edges count twice
  [[nodiscard]] GraphAdjacency adjacency() const;
  [[nodiscard]] double edge_length(int64_t e) const;   // polyline length, physical units
  [[nodiscard]] double total_length() const;
  [[nodiscard]] int64_t connected_components() const;
  // Cyclomatic number E - N + C: the number of independent loops.
  [[nodiscard]] int64_t cyclomatic_number() const;
  // Problems found (empty = consistent): edge node ids valid, polylines >= 2 points, end points
  // equal the node positions (exactly), every attribute array sized to its level.
  [[nodiscard]] std::vector<std::string> check_invariants() const;

  // DataObject
  [[nodiscard]] std::string type_id() const override { return type_ids::graph; }
  [[nodiscard]] uint64_t bytes() const override;
  [[nodiscard]] std::string describe() const override;
  [[nodiscard]] std::string physical_unit() const override { return unit; }
};

// Whether an attribute named `name` holds lengths (its name contains radius, thickness, diameter or
// length): those scale with the coordinates.
bool is_length_attribute(const std::string& name);

// Multiplies every position, polyline point, length attribute (is_length_attribute) and the source
// grid's spacing and origin by `factor` (> 0): a change of unit (1e-3: µm -> mm numbers).
void scale_graph(SpatialGraph& graph, double factor);

}  // namespace skel
