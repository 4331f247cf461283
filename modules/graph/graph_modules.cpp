// Modules of the graph family: graph-to-graph operations (graph.prune, graph.filter) and replaying
// manual edits (graph.apply_edits).
#include "graph/centerlines.hpp"
#include "graph/editor.hpp"
#include "graph/graph_ops.hpp"
#include "graph/names.hpp"
#include "skel/module.hpp"
#include "skel/units.hpp"
#include "skel/table.hpp"

namespace skel::graph {
namespace {

class PruneModule final : public Module {
public:
  static ModuleSpec spec() {
    return ModuleSpec(names::prune, "Remove short terminal branches, merging edges at degree-2 nodes")
        .input<SpatialGraph>("graph", "spatial graph")
        .output<SpatialGraph>("graph", "pruned graph")
        .output<Table>("report", "one row: removed_edges, merged_nodes, iterations")
        .param("min_length", &PruneOptions::min_length, "terminal branches shorter than this are removed")
        .default_value(5.0)
        .min(0)
        .unit(units::length)
        .param("max_iterations", &PruneOptions::max_iterations, "rounds of pruning (0 = until nothing changes)")
        .min(0)
        .param("radius_factor", &PruneOptions::radius_factor,
                       "also remove terminal branches shorter than this times the radius at their junction (0 = off)")
        .min(0)
        .param("radius", &PruneOptions::radius, "point attribute holding the radius (for radius_factor)")
        .details(
            "A terminal branch is an edge with one end of degree 1 and the other of degree >= 3. Per round, "
            "at every junction the short terminal branches are removed shortest first, never leaving the "
            "junction with fewer than two edges; then the two edges at every node left with degree 2 are "
            "merged (polylines and point attributes concatenated, edge attributes length-weighted). Rounds "
            "repeat until nothing changes, so branches that become terminal are pruned too. Isolated edges "
            "are kept. With radius_factor f > 0 the limit of a branch is max(min_length, f * r), r = the `radius` "
            "point attribute at its junction end (the local thickness from skeleton_to_graph's distance input): "
            "a spur from a surface bump of a vessel of radius r is about r long, so f = 2 removes such spurs on "
            "thick and thin vessels alike while real ends, many radii long, stay. Lengths are polyline lengths in physical units. Memory: a copy of the graph.");
  }
  void run(RunContext& ctx) override {
    SpatialGraph g = *ctx.input<SpatialGraph>("graph");
    auto s = prune(g, ctx.options<PruneOptions>());
    Table t;
    t.add("removed_edges", std::vector<int64_t>{s.removed_edges})
        .add("merged_nodes", std::vector<int64_t>{s.merged_nodes})
        .add("iterations", std::vector<int64_t>{s.iterations});
    ctx.output("graph", std::move(g));
    ctx.output("report", std::move(t));
  }
};
SKEL_REGISTER_MODULE(PruneModule);

class FilterModule final : public Module {
public:
  static ModuleSpec spec() {
    return ModuleSpec(names::filter, "Keep edges whose attribute lies in a range")
        .input<SpatialGraph>("graph", "spatial graph")
        .output<SpatialGraph>("graph", "graph with the kept edges")
        .param("attribute", &FilterOptions::attribute,
                            "length, an edge attribute or label, or a point attribute (length-weighted mean)")
        .param("min", &FilterOptions::min, "lowest kept value (inclusive)")
        .default_value(0.0)
        .param("max", &FilterOptions::max, "highest kept value (inclusive; 1e30 = no limit)")
        .default_value(1e30)
        .param("remove_isolated_nodes", &FilterOptions::remove_isolated_nodes, "remove nodes left without edges")
        .param("merge", &FilterOptions::merge, "merge the two edges at nodes left with degree 2")
        .details(
            "Thesis §6.2 (fig. 6.9 filtering by local thickness). The value of an edge is its polyline length "
            "(`length`), its edge attribute or label of that name, or the length-weighted mean of the point "
            "attribute of that name (e.g. `radius`). Edges with a value outside [min, max] (or NaN) are "
            "removed; ids are compacted keeping order. Memory: a copy of the graph.");
  }
  void run(RunContext& ctx) override {
    SpatialGraph g = *ctx.input<SpatialGraph>("graph");
    filter_edges(g, ctx.options<FilterOptions>());
    ctx.output("graph", std::move(g));
  }
};
SKEL_REGISTER_MODULE(FilterModule);

class ApplyEdits final : public Module {
public:
  static ModuleSpec spec() {
    return ModuleSpec(names::apply_edits, "Replays a manual edit journal on a graph (keeps manual work across re-runs)")
        .input<SpatialGraph>("graph", "graph to edit (e.g. from geometry.skeleton_to_graph)")
        .optional_input<VolumeU8>("mask", "object mask, for connections routed through the mask")
        .optional_input<VolumeF32>("distance", "distance map (physical units), for the radius of new points")
        .output<SpatialGraph>("graph", "edited graph")
        .output<Table>("table", "one row per journal entry: index, op, status (applied | not matched | failed), message")
        .path("journal", "", PathRole::Input, "edit journal (YAML) written by skelflow-gui or by hand")
        .param<double>("tolerance", 0.0, "match distance for addressing elements by position; 0 = the journal's own")
        .min(0).unit(units::length)
        .param<bool>("strict", false, "fail when an entry no longer matches (default: report it in the table)")
        .details(R"(The journal (docs/editing.md) lists operations that address nodes and edges by
physical position ("node at [x, y, z]", "edge through [x, y, z]") within a tolerance, not by internal
ids, so that a journal recorded on one reconstruction can be replayed on a graph recomputed by the
upstream pipeline (with a slightly different parameter, say). Every entry is tried in order; one whose
target no longer exists is reported in the table as "not matched" and never silently skipped. `undo`
and `redo` entries undo/redo the previous steps exactly as in the editor. Memory: one copy of the graph
plus the undo records of the journal's steps.)");
  }
  void run(RunContext& ctx) override {
    auto in = ctx.input<SpatialGraph>("graph");
    graph::Journal j = graph::read_journal(ctx.input_path("journal"));
    if (!j.dropped.empty()) ctx.warn(j.dropped);
    double tol = ctx.param<double>("tolerance");
    if (tol <= 0) tol = j.tolerance;
    graph::EditContext ec;
    ec.mask = ctx.optional_input<VolumeU8>("mask");
    ec.distance = ctx.optional_input<VolumeF32>("distance");
    graph::GraphEditor ed(*in, ec);
    std::vector<int64_t> index;
    std::vector<std::string> ops, status, message;
    int64_t missed = 0;
    for (size_t i = 0; i < j.ops.size(); ++i) {
      ctx.progress().check(static_cast<double>(i) / static_cast<double>(std::max<size_t>(1, j.ops.size())));
      const auto r = ed.apply(j.ops[i], tol);
      index.push_back(static_cast<int64_t>(i));
      ops.emplace_back(enum_name(j.ops[i].op));
      status.push_back(r.applied ? "applied" : (r.message.rfind("no ", 0) == 0 || r.message.rfind("nothing", 0) == 0 ? "not matched" : "failed"));
      message.push_back(r.message);
      if (!r.applied) {
        ++missed;
        if (ctx.param<bool>("strict"))
          throw InputError("journal entry " + std::to_string(i) + " (" + j.ops[i].to_yaml() + "): " + r.message);
      }
    }
    if (missed) ctx.warn(std::to_string(missed) + " of " + std::to_string(j.ops.size()) + " journal entries were not applied (see the table)");
    Table t;
    t.add("index", index);
    t.add("op", ops);
    t.add("status", status);
    t.add("message", message);
    ctx.output("graph", SpatialGraph(ed.graph()));
    ctx.output("table", std::move(t));
  }
};
SKEL_REGISTER_MODULE(ApplyEdits);

class MergeCenterlines final : public Module {
public:
  static ModuleSpec spec() {
    return ModuleSpec(names::merge_centerlines, "Merge overlapping centerlines (VMTK: one polyline per inlet–outlet path) into a branch graph")
        .input<SpatialGraph>("centerlines", "one edge per path, e.g. a VMTK centerlines .vtp read by io.read_graph")
        .output<SpatialGraph>("graph", "branch graph: nodes at inlets, outlets and bifurcations, one edge per branch, point attribute radius")
        .param("tolerance", &MergeCenterlinesOptions::tolerance,
               "a point this close to a point of an earlier path lies on it (0 = radius_factor × its radius)")
        .min(0)
        .unit(units::length)
        .param("radius_factor", &MergeCenterlinesOptions::radius_factor, "with tolerance 0: the tolerance in radii of the point")
        .min(1e-6)
        .param("radius", &MergeCenterlinesOptions::radius, "point attribute with the radius (VMTK: MaximumInscribedSphereRadius); copied as `radius`")
        .details(
            "VMTK's vmtkcenterlines writes one polyline per inlet–outlet path; the paths overlap along the vessels "
            "they share, so as a graph they count the trunk once per outlet. Paths are taken in order: a point "
            "within the tolerance of a point of an earlier path (by default its maximum inscribed sphere radius, "
            "the vessel's own radius, as vmtkbranchextractor decides) is that point; the stretches on new points "
            "are added, joined to the shared points where the path leaves (a bifurcation) or rejoins the earlier "
            "ones. The point graph is then split at every point where paths part (degree != 2): one edge per "
            "branch. Shared stretches keep the first path's points. A uniform hash of cell = the largest "
            "tolerance finds neighbours in O(1) per point. Memory: about 64 bytes per input point.");
  }
  void run(RunContext& ctx) override {
    ctx.output("graph", merge_centerlines(*ctx.input<SpatialGraph>("centerlines"), ctx.options<MergeCenterlinesOptions>()));
  }
};
SKEL_REGISTER_MODULE(MergeCenterlines);

}  // namespace
}  // namespace skel::graph
