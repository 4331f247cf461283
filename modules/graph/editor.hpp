#pragma once
// Manual editing of SpatialGraphs (thesis §6.1: connect unconnected segment ends, delete or move
// segments, correct radii, label vessels). Every operation is one undoable step; the editor records
// each step in an edit journal that addresses elements by physical position, so the journal can be
// replayed on a graph recomputed by the upstream pipeline (graph.apply_edits).
#include <cstdint>
#include <filesystem>
#include <functional>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "skel/enum_names.hpp"
#include "skel/spatial_graph.hpp"
#include "skel/volume.hpp"

namespace skel::graph {

// One journal entry. Positions are physical (the graph's units). Ops:
//   delete_edge {at | at_list}      delete_node {at}          split {at}           merge {at}
//   connect {from, to, route}       move_node {from, to}      set {at, level, attribute, value}
//   prune {max_length, radius_factor}   delete_components {max_length}   bridge_gaps {max_distance, route}
//   undo                            redo
enum class EditKind { delete_edge, delete_node, connect, split, merge, move_node, set, prune, delete_components,
                      bridge_gaps, undo, redo };
constexpr auto enum_names(EditKind) {
  return std::to_array<EnumName<EditKind>>(
      {{EditKind::delete_edge, "delete_edge"}, {EditKind::delete_node, "delete_node"}, {EditKind::connect, "connect"},
       {EditKind::split, "split"}, {EditKind::merge, "merge"}, {EditKind::move_node, "move_node"},
       {EditKind::set, "set"}, {EditKind::prune, "prune"}, {EditKind::delete_components, "delete_components"},
       {EditKind::bridge_gaps, "bridge_gaps"}, {EditKind::undo, "undo"}, {EditKind::redo, "redo"}});
}
// How a new connection runs: a straight segment, or the shortest 26-path through the mask.
enum class Route { straight, mask };
constexpr auto enum_names(Route) {
  return std::to_array<EnumName<Route>>({{Route::straight, "straight"}, {Route::mask, "mask"}});
}
// What `set` changes: a node's or an edge's value.
enum class Level { node, edge };
constexpr auto enum_names(Level) { return std::to_array<EnumName<Level>>({{Level::node, "node"}, {Level::edge, "edge"}}); }

struct EditOp {
  EditOp() = default;
  explicit EditOp(EditKind kind) : op(kind) {}
  EditKind op = EditKind::delete_edge;
  std::vector<Vec3> at;             // delete_edge may name several edges (one undo step)
  std::optional<Vec3> from, to;     // connect, move_node
  Route route = Route::straight;    // connect, bridge_gaps
  Level level = Level::edge;        // set
  std::string attribute;            // set
  double value = 0.0;               // set
  double length = 0.0;              // prune / delete_components: max_length; bridge_gaps: max_distance
  double radius_factor = 0.0;       // prune: also spurs shorter than this x the radius at their junction
  // One line of YAML flow style, e.g. `{op: delete_edge, at: [1.5, 2, 3]}`.
  [[nodiscard]] std::string to_yaml() const;
};

// Reads a journal file (YAML: `skelflow_edits: 1`, optional `tolerance`, `ops:` list). Throws
// InputError naming the file, line and column of a malformed entry.
struct Journal {
  double tolerance = 1.0;  // default match distance for addressing by position (physical units)
  std::vector<EditOp> ops;
  // Set when the last line had no newline and did not parse (an append cut short by a kill): that
  // line was left out; the message names the file and line.
  std::string dropped;
};
Journal read_journal(const std::filesystem::path& path);
Journal parse_journal(const std::string& text, const std::string& name = "<journal>");

// Optional image data for routed connections and radii.
struct EditContext {
  std::shared_ptr<const VolumeU8> mask;       // route: mask follows object voxels
  std::shared_ptr<const VolumeF32> distance;  // radius of new points = distance value (physical)
};

struct ApplyResult {
  bool applied = false;
  std::string message;  // what was done, or why not (no element within the tolerance, ...)
};

// What a dangling end's best partner is.
struct DanglingEnd {
  int64_t node = -1;        // the end node (degree 1)
  Vec3 position{};
  Vec3 direction{};         // unit vector pointing out of the segment
  bool has_partner = false;
  bool partner_is_node = false;
  int64_t partner_node = -1;    // if partner_is_node
  int64_t partner_edge = -1;    // otherwise: edge and point index
  int64_t partner_point = -1;
  Vec3 partner_position{};
  double distance = 0, angle_deg = 0, score = 0;  // lower score = better
};
struct DanglingOptions {
  double max_distance = 20.0;       // physical units
  double max_angle_deg = 60.0;      // between the segment's direction and the gap
  double direction_length = 5.0;    // how far back along the segment the direction is measured
};
// Every end point (degree-1 node) with its best partner: another end node or a point on another
// edge, within max_distance and max_angle of the direction the segment points to. Score = distance ×
// (1 + (1 − cos angle)). Sorted by score (ends without partner last).
std::vector<DanglingEnd> find_dangling_ends(const SpatialGraph& g, const DanglingOptions& o = {});

class GraphEditor {
public:
  explicit GraphEditor(SpatialGraph graph, EditContext context = {});
  ~GraphEditor();
  GraphEditor(const GraphEditor&) = delete;
  GraphEditor& operator=(const GraphEditor&) = delete;

  [[nodiscard]] const SpatialGraph& graph() const { return graph_; }

  // Journal: each applied step, undo and redo is appended and flushed (fsync) at once. The header is
  // written when the file is new or empty.
  void set_journal(const std::filesystem::path& path, double tolerance = 1.0);
  [[nodiscard]] const std::filesystem::path& journal() const { return journal_; }

  // ---- operations by id (GUI); each is one undo step and returns the journal entry it wrote.
  // Throw Error on invalid ids or impossible operations (the graph is unchanged then).
  EditOp delete_edges(std::vector<int64_t> edges);
  EditOp delete_node(int64_t node);
  // Connects node `from` to node `to_node`, or (to_node < 0) to point `to_point` of edge `to_edge`
  // (the edge is split there). route "mask" follows the mask's object voxels (shortest 26-path).
  EditOp connect(int64_t from, int64_t to_node, int64_t to_edge = -1, int64_t to_point = -1,
                 Route route = Route::straight);
  EditOp split(int64_t edge, int64_t point);  // point: interior polyline index
  EditOp merge(int64_t node);                 // node of degree 2 with two different edges
  EditOp move_node(int64_t node, const Vec3& to);  // incident polylines follow (fading to their far end)
  // level "edge": sets a point attribute of that name on all points if it exists (e.g. radius),
  // else an edge label if one exists, else a float edge attribute. level "node": label or attribute.
  EditOp set_attribute(Level level, const std::vector<int64_t>& ids, const std::string& name,
                       double value);
  // Terminal branches shorter than max(max_length, radius_factor x the point attribute `radius` at
  // their junction end), iterated (the rule of graph.prune; radius_factor > 0 needs `radius`).
  EditOp prune(double max_length, double radius_factor = 0.0);
  EditOp delete_components(double max_length);  // components with total length < max_length
  EditOp bridge_gaps(double max_distance, Route route = Route::straight);

  // ---- journal entries (replay): resolves positions within `tolerance`, applies, records.
  ApplyResult apply(const EditOp& op, double tolerance);

  bool undo();
  bool redo();
  [[nodiscard]] bool can_undo() const { return !undo_.empty(); }
  [[nodiscard]] bool can_redo() const { return !redo_.empty(); }
  [[nodiscard]] size_t undo_count() const { return undo_.size(); }
  [[nodiscard]] std::string undo_text() const;  // description of the step undo() would revert

  // ---- lookups by position (physical units); -1 if nothing within `tolerance`.
  [[nodiscard]] int64_t node_at(const Vec3& p, double tolerance) const;
  // Edge whose polyline passes nearest to p; also the nearest polyline vertex index.
  [[nodiscard]] int64_t edge_at(const Vec3& p, double tolerance, int64_t* point = nullptr) const;

private:
  struct Step;
  using Undo = std::function<void(SpatialGraph&)>;
  void begin();
  void commit(EditOp op, std::function<void()> redo);
  void rollback();
  EditOp perform(EditOp op, std::function<void()> run);
  void record(Undo u) { log_.push_back(std::move(u)); }
  // Primitives (each records its inverse).
  int64_t p_add_node(const Vec3& p);
  int64_t p_add_edge(int64_t n0, int64_t n1, std::vector<Vec3> pts, int64_t copy_attrs_from = -1);
  void p_remove_edge(int64_t e);
  void p_remove_node(int64_t n);  // must be isolated
  void p_set_node_position(int64_t n, const Vec3& p);
  void p_set_polyline(int64_t e, std::vector<Vec3> pts, std::map<std::string, std::vector<float>, std::less<>> point_values);
  void p_set_value(Level level, const std::string& name, int64_t id, double value);
  void write_journal(const EditOp& op);
  std::vector<Vec3> route_path(const Vec3& a, const Vec3& b, Route route) const;
  void fill_new_point_radius(int64_t e);
  // Implementation of each op without begin/commit (bridge_gaps reuses connect).
  void do_connect(int64_t from, int64_t to_node, int64_t to_edge, int64_t to_point, Route route);
  int64_t do_split(int64_t edge, int64_t point);
  void do_merge(int64_t node);
  void do_delete_edges(std::vector<int64_t> edges);
  Vec3 edge_probe(int64_t e) const;  // a point on edge e that identifies it (middle of the polyline)

  SpatialGraph graph_;
  EditContext context_;
  std::vector<Undo> log_;  // inverses of the step being built
  bool in_step_ = false;
  std::vector<std::unique_ptr<Step>> undo_, redo_;
  std::filesystem::path journal_;
  double journal_tolerance_ = 1.0;
};

// Exact equality of two graphs (positions, polylines, all attributes and labels).
bool same_graph(const SpatialGraph& a, const SpatialGraph& b);

}  // namespace skel::graph
