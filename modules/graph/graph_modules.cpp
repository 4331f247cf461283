// Modules of the graph family: skeleton → graph (geometry.*), graph operations (graph.*), network
// analysis (analysis.*) and graph files (io.read_graph / io.write_graph).
#include "graph/graph_io.hpp"
#include "graph/graph_ops.hpp"
#include "graph/network_analysis.hpp"
#include "graph/skeleton_to_graph.hpp"
#include "skel/module.hpp"

namespace skel {
namespace {

class SkeletonToGraphModule final : public Module {
public:
  static ModuleSpec spec() {
    return ModuleSpec("geometry.skeleton_to_graph", "Voxel skeleton to a spatial graph by dual cubes")
        .input<VolumeU8>("skeleton", "voxel skeleton (non-zero = skeleton voxel)")
        .optional_input<AnyVolume>("distance", "distance volume on the same grid; gives the point attribute radius")
        .output<SpatialGraph>("graph", "nodes at junctions/ends, edges with polylines (µm), radius per point")
        .output<VolumeU8>("manifold", "manifold type per voxel (only when with_manifold is true)")
        .param<int64_t>("smooth_passes", 0, "Gaussian smoothing passes over edge points (0 = off)")
        .min(0)
        .param<int64_t>("smooth_kernel", 5, "smoothing window in points (>= 3)")
        .min(3)
        .param<double>("radius_scale", 1.0, "radius = distance value × radius_scale (1 for distances in µm)")
        .min(0)
        .param<bool>("with_manifold", false, "also output the manifold type volume")
        .details(
            "Thesis §3.1. Each object voxel is a 0-cell; 1-cells join 6-adjacent voxels always, 18-adjacent "
            "voxels when the other two voxels of their face are background, 26-adjacent voxels when they are "
            "the only two object voxels of their dual cube (fig. 3.6). In each dual cube, 2-cells fill the "
            "shortest cycles (all independent cycles of one length at once) until the cycle space is spanned; "
            "a 3-cell is added when χ = 2. Voxels are classified by their incident cells (fig. 3.9); codes of "
            "`manifold`: 0 background, 1 0-manifold (isolated voxel), 2 1-manifold, 3 1-boundary, 4 2-manifold, "
            "5 2-boundary, 6 junction, 7 1-x-junction (junction with a bare 1-cell). §3.1.2: a 2^8 table gives "
            "the 1-cells of each reduced dual cube, so every edge is generated once; connected voxels that "
            "are not 1-manifold/1-boundary collapse to one node at their centroid (node label `kind` = highest "
            "manifold code of its voxels); a tunnel inside such a component (a cycle of its 1-cells that does "
            "not bound its 2-cells, e.g. junction voxels around a hole) is kept as a loop edge on its node "
            "drawn along the cycle (the thesis collapses it; components with > 4096 internal 1-cells are "
            "collapsed as in the thesis); chains of 1-manifold voxels become edge polylines that start and end "
            "at their nodes; an isolated ring becomes one loop edge on a node (degree 2) at its first voxel "
            "(x-fastest order). Smoothing: Gaussian weights, sigma = kernel/4, end points fixed. Radius "
            "(§6.1 local thickness): point attribute `radius` = distance × radius_scale at each voxel; at a "
            "node the maximum over its voxels (also node attribute `radius`). Memory: the skeleton (1 B/voxel), "
            "~60 B per skeleton voxel, plus 1 B/voxel for `manifold`. Deterministic for any thread count.");
  }
  void run(RunContext& ctx) override {
    auto skel_in = ctx.input<VolumeU8>("skeleton");
    DataPtr dist = ctx.input_data("distance");
    SkeletonToGraphOptions o;
    o.smooth_passes = static_cast<int>(ctx.param<int64_t>("smooth_passes"));
    o.smooth_kernel = static_cast<int>(ctx.param<int64_t>("smooth_kernel"));
    o.radius_scale = ctx.param<double>("radius_scale");
    o.want_manifold = ctx.param<bool>("with_manifold");
    o.threads = ctx.threads();
    o.interrupter = ctx.progress();
    auto r = skeleton_to_graph(*skel_in, dist.get(), o);
    ctx.output("graph", std::move(r.graph));
    if (o.want_manifold) ctx.output("manifold", std::move(r.manifold));
  }
};
SKEL_REGISTER_MODULE(SkeletonToGraphModule);

class PruneModule final : public Module {
public:
  static ModuleSpec spec() {
    return ModuleSpec("graph.prune", "Remove short terminal branches, merging edges at degree-2 nodes")
        .input<SpatialGraph>("graph", "spatial graph")
        .output<SpatialGraph>("graph", "pruned graph")
        .output<Table>("report", "one row: removed_edges, merged_nodes, iterations")
        .param<double>("min_length", 5.0, "terminal branches shorter than this are removed")
        .min(0)
        .unit("µm")
        .param<int64_t>("max_iterations", 0, "rounds of pruning (0 = until nothing changes)")
        .min(0)
        .param<double>("radius_factor", 0.0,
                       "also remove terminal branches shorter than this times the radius at their junction (0 = off)")
        .min(0)
        .param<std::string>("radius", std::string("radius"), "point attribute holding the radius (for radius_factor)")
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
    PruneOptions o;
    o.min_length = ctx.param<double>("min_length");
    o.max_iterations = static_cast<int>(ctx.param<int64_t>("max_iterations"));
    o.radius_factor = ctx.param<double>("radius_factor");
    o.radius = ctx.param<std::string>("radius");
    o.interrupter = ctx.progress();
    auto s = prune(g, o);
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
    return ModuleSpec("graph.filter", "Keep edges whose attribute lies in a range")
        .input<SpatialGraph>("graph", "spatial graph")
        .output<SpatialGraph>("graph", "graph with the kept edges")
        .param<std::string>("attribute", std::string("length"),
                            "length, an edge attribute or label, or a point attribute (length-weighted mean)")
        .param<double>("min", 0.0, "lowest kept value (inclusive)")
        .param<double>("max", 1e30, "highest kept value (inclusive; 1e30 = no limit)")
        .param<bool>("remove_isolated_nodes", true, "remove nodes left without edges")
        .param<bool>("merge", false, "merge the two edges at nodes left with degree 2")
        .details(
            "Thesis §6.2 (fig. 6.9 filtering by local thickness). The value of an edge is its polyline length "
            "(`length`), its edge attribute or label of that name, or the length-weighted mean of the point "
            "attribute of that name (e.g. `radius`). Edges with a value outside [min, max] (or NaN) are "
            "removed; ids are compacted keeping order. Memory: a copy of the graph.");
  }
  void run(RunContext& ctx) override {
    SpatialGraph g = *ctx.input<SpatialGraph>("graph");
    FilterOptions o;
    o.attribute = ctx.param<std::string>("attribute");
    o.min = ctx.param<double>("min");
    o.max = ctx.param<double>("max");
    o.remove_isolated_nodes = ctx.param<bool>("remove_isolated_nodes");
    o.merge = ctx.param<bool>("merge");
    filter_edges(g, o);
    ctx.output("graph", std::move(g));
  }
};
SKEL_REGISTER_MODULE(FilterModule);

class NetworkStatisticsModule final : public Module {
public:
  static ModuleSpec spec() {
    return ModuleSpec("analysis.network_statistics", "Segment, node and network statistics of a graph")
        .input<SpatialGraph>("graph", "spatial graph (point attribute radius optional)")
        .optional_input<VolumeU8>("mask", "region for the length density (default: the graph's source grid box)")
        .output<Table>("segments", "per edge: length, chord, tortuosity, radius stats, volume, surface")
        .output<Table>("nodes", "per node: degree, position")
        .output<Table>("summary", "one row: totals, densities, branch/end points, loops, orientation histogram")
        .param<std::string>("radius", std::string("radius"), "point attribute holding radii")
        .param<int64_t>("orientation_bins", 9, "bins of the angle between segments and the axis (0..90°)")
        .min(1)
        .max(180)
        .choice("axis", {"x", "y", "z"}, "z", "reference axis of the orientation histogram")
        .param<double>("orientation_window", 0.0,
                       "arc length over which segment directions are measured (0 = 10 x the median point step)")
        .min(0)
        .unit("µm")
        .details(
            "Thesis §6.1. Per segment: polyline length, chord (end-to-end distance), tortuosity = length / "
            "chord (NaN for loops), length-weighted mean, min and max radius, volume and lateral surface of "
            "the truncated cones between consecutive points (π r² integrated along the edge). Per node: "
            "degree (a loop counts twice) and position. Summary: nodes, edges, components, total length, "
            "reference volume (mask volume, else the box of the graph's source grid, else the points' bounding "
            "box), length density = total length / reference volume, branch points (degree >= 3), end points "
            "(degree 1), loops = cyclomatic number E - N + C, total volume/surface, and orientation_k = length "
            "of the pieces whose direction makes an angle to the axis in bin k. Directions are chords of "
            "consecutive pieces of arc length orientation_window cut along each edge (the last piece of an edge "
            "may be shorter): single voxel steps of a skeleton only take the 13 lattice directions (0°, 45°, "
            "54.7°, 90° to an axis), so a histogram of steps would show the grid instead of the network. Units: µm (spacing units).");
  }
  void run(RunContext& ctx) override {
    auto g = ctx.input<SpatialGraph>("graph");
    NetworkStatisticsOptions o;
    o.radius = ctx.param<std::string>("radius");
    o.orientation_bins = static_cast<int>(ctx.param<int64_t>("orientation_bins"));
    const std::string axis = ctx.param<std::string>("axis");
    o.axis = axis == "x" ? 0 : axis == "y" ? 1 : 2;
    o.orientation_window = ctx.param<double>("orientation_window");
    if (auto m = ctx.optional_input<VolumeU8>("mask")) o.reference_volume = mask_volume(*m);
    auto st = network_statistics(*g, o);
    ctx.output("segments", std::move(st.segments));
    ctx.output("nodes", std::move(st.nodes));
    ctx.output("summary", std::move(st.summary));
  }
};
SKEL_REGISTER_MODULE(NetworkStatisticsModule);

class TreesModule final : public Module {
public:
  static ModuleSpec spec() {
    return ModuleSpec("analysis.trees", "Vessel trees from root points and a minimum diameter")
        .input<SpatialGraph>("graph", "spatial graph (point attribute radius needed when min_diameter > 0)")
        .output<SpatialGraph>("graph", "graph with edge labels tree and branch_order")
        .output<Table>("trees", "per tree: root node, edges, total length")
        .param<std::vector<int64_t>>("roots", {}, "root node ids")
        .optional_value()
        .param<std::vector<double>>("root_points", {}, "root positions x y z, x y z ... (nearest node)")
        .optional_value()
        .unit("µm")
        .param<double>("min_diameter", 0.0, "edges thinner than this (2 × mean radius) are capillaries")
        .min(0)
        .unit("µm")
        .param<std::string>("radius", std::string("radius"), "point attribute holding radii")
        .details(
            "Thesis §6.1 (fig. 6.3): main vessel trees are separated from the capillary bed by diameter and "
            "root points. From all roots at once, a Dijkstra search along polyline lengths walks only edges "
            "whose diameter (2 × length-weighted mean radius) is >= min_diameter; each reached edge gets "
            "`tree` = 1-based index of its nearest root (ties: lower index) and `branch_order` = 1 at the "
            "root, +1 after each node of degree >= 3. All other edges: tree 0 (capillary), branch_order 0. "
            "Memory: a copy of the graph plus O(nodes).");
  }
  void run(RunContext& ctx) override {
    SpatialGraph g = *ctx.input<SpatialGraph>("graph");
    TreeOptions o;
    o.roots = ctx.param<std::vector<int64_t>>("roots");
    const auto rp = ctx.param<std::vector<double>>("root_points");
    if (rp.size() % 3 != 0)
      throw InputError("parameter 'root_points': expected x y z triples, got " + std::to_string(rp.size()) + " numbers");
    for (size_t i = 0; i < rp.size(); i += 3) o.root_points.push_back({rp[i], rp[i + 1], rp[i + 2]});
    o.min_diameter = ctx.param<double>("min_diameter");
    o.radius = ctx.param<std::string>("radius");
    auto s = extract_trees(g, o);
    const auto& tree = g.edge_labels.at("tree");
    std::vector<int64_t> id, root, edges(s.root_nodes.size(), 0);
    std::vector<double> len(s.root_nodes.size(), 0.0);
    for (int64_t e = 0; e < g.edge_count(); ++e)
      if (tree[e] > 0) {
        ++edges[tree[e] - 1];
        len[tree[e] - 1] += g.edge_length(e);
      }
    for (size_t r = 0; r < s.root_nodes.size(); ++r) {
      id.push_back(static_cast<int64_t>(r) + 1);
      root.push_back(s.root_nodes[r]);
    }
    Table t;
    t.add("tree", id).add("root_node", root).add("edges", edges).add("length", len, "µm");
    ctx.output("graph", std::move(g));
    ctx.output("trees", std::move(t));
  }
};
SKEL_REGISTER_MODULE(TreesModule);

class LabelPropagationModule final : public Module {
public:
  static ModuleSpec spec() {
    return ModuleSpec("analysis.label_propagation", "Colour the object by its nearest skeleton edge")
        .input<VolumeU8>("mask", "object (non-zero = object)")
        .optional_input<SpatialGraph>("graph", "graph whose edges colour the object")
        .optional_input<VolumeU32>("seeds", "instead of a graph: label volume (non-zero voxels are seeds)")
        .output<VolumeU32>("labels", "label per object voxel (0 = background or not reached)")
        .param<std::string>("label", std::string(""), "edge label to paint (value + 1); empty: edge id + 1")
        .optional_value()
        .choice("metric", {"euclidean", "geodesic"}, "euclidean",
                "nearest seed by Euclidean distance (physical units) or along the object (26-neighbour wave)")
        .details(
            "Thesis §6.2, fig. 6.14 (rods/plates decomposition): a skeleton cut at its branching points, each "
            "edge coloured, colours propagated so every object voxel takes the colour of the nearest skeleton "
            "point. Edges are drawn into the mask's grid (polylines sampled at <= 1/2 voxel; where edges "
            "overlap the lower id wins). euclidean: every object voxel takes the label of its nearest seed "
            "voxel in physical distance (exact Euclidean feature transform, anisotropic spacing; ties: smallest "
            "z, y, x); memory 4 B/voxel output + ~13 B/voxel while computing. geodesic: a breadth-first wave "
            "through the object's 26-neighbourhood (equal arrival: earlier seed; unreached voxels stay 0); "
            "memory 4 B/voxel + 8 B per object voxel. Labels: edge id + 1, or the chosen edge label + 1 (so 0 "
            "stays 'unlabelled').");
  }
  void run(RunContext& ctx) override {
    auto mask = ctx.input<VolumeU8>("mask");
    LabelPropagationOptions o;
    o.label = ctx.param<std::string>("label");
    o.metric = ctx.param<std::string>("metric") == "geodesic" ? PropagationMetric::geodesic : PropagationMetric::euclidean;
    o.threads = ctx.threads();
    o.interrupter = ctx.progress();
    if (auto g = ctx.optional_input<SpatialGraph>("graph")) {
      ctx.output("labels", propagate_edge_labels(*mask, *g, o));
    } else if (auto s = ctx.optional_input<VolumeU32>("seeds")) {
      ctx.output("labels", propagate_labels(*mask, *s, o));
    } else {
      throw InputError("inputs 'graph' / 'seeds': connect one of them");
    }
  }
};
SKEL_REGISTER_MODULE(LabelPropagationModule);

constexpr const char* kGraphFormats =
    "By extension: .am Amira SpatialGraph (ASCII; radius = thickness), .vtp VTK XML PolyData (ASCII; "
    "nodes as vertex cells, edges as polylines, attributes as point/cell data), .swc (trees only), "
    ".graphml, .csv (edge points; the nodes table goes to nodes_path). Attributes and labels are kept in "
    "every format except SWC (radius and swc_type only).";

class ReadGraphModule final : public Module {
public:
  static ModuleSpec spec() {
    return ModuleSpec("io.read_graph", "Read a spatial graph file (.am, .vtp, .swc, .graphml, .csv)")
        .output<SpatialGraph>("graph", "the graph")
        .path("path", "", PathRole::Input, "graph file")
        .path("nodes_path", "", PathRole::Input, "CSV only: nodes table (default: <stem>_nodes.csv)")
        .optional_value()
        .details(std::string(kGraphFormats) +
                 " Polyline end points are set to their nodes' positions. Malformed files are input errors "
                 "naming the file and what is wrong. Memory: the file text plus the graph.");
  }
  void run(RunContext& ctx) override {
    const auto p = ctx.input_path("path");
    const std::string np = ctx.param<std::string>("nodes_path");
    ctx.output("graph", read_graph(p, graph_format_from_path(p), np.empty() ? std::filesystem::path() : ctx.input_path("nodes_path")));
  }
};
SKEL_REGISTER_MODULE(ReadGraphModule);

class WriteGraphModule final : public Module {
public:
  static ModuleSpec spec() {
    return ModuleSpec("io.write_graph", "Write a spatial graph file (.am, .vtp, .swc, .graphml, .csv)")
        .input<SpatialGraph>("graph", "the graph")
        .path("path", "", PathRole::Output, "graph file; the format follows the extension")
        .path("nodes_path", "", PathRole::Output, "CSV only (required there): nodes table file")
        .optional_value()
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
    write_graph(*g, ctx.output_path("path"), f, np);
  }
};
SKEL_REGISTER_MODULE(WriteGraphModule);

SKEL_REGISTER_INSPECTOR("spatial graph", {".am", ".vtp", ".swc", ".graphml"}, [](const std::filesystem::path& p) {
  return read_graph(p, graph_format_from_path(p)).describe();
});

}  // namespace
}  // namespace skel
