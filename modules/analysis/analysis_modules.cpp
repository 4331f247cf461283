// Modules of the analysis family: topology numbers, network statistics, trees, label propagation,
// dangling ends.
#include "analysis/names.hpp"
#include "analysis/network_analysis.hpp"
#include "analysis/report.hpp"
#include "analysis/topology.hpp"
#include "graph/editor.hpp"
#include "skel/fs.hpp"
#include "skel/module.hpp"
#include "skel/table.hpp"
#include "skel/units.hpp"

namespace skel::analysis {
namespace {

class TopologyModule final : public Module {
public:
  static ModuleSpec spec() {
    return ModuleSpec(names::topology,
                      "Topology numbers of a binary volume: components, cavities, Euler characteristic, tunnels")
        .input<VolumeU8>("mask", "binary object (voxel > 0 is object)")
        .output<Table>("table", "one row: object_voxels, components, cavities, euler, tunnels")
        .details(R"(Grid point model with (26, 6) adjacency (thesis §2.3); voxels outside the array are
background. components: 26-components of the object. cavities: 6-components of the background that do
not reach the outside of the array (the outside counts as one unbounded component and is not a cavity).
euler: Euler characteristic of the grid cell complex X(P), counted over all 2x2x2 windows (each grid
vertex owns itself and the edges, faces and cube towards +x, +y, +z; 256-entry table).
tunnels: first Betti number b1 = components + cavities - euler (Euler-Poincaré: chi = b0 - b1 + b2).
Components and cavities are counted by union-find over x-runs of the object and of the background (no
labels, no flood fill). Results are identical for any thread count. Memory: 1 byte per voxel of the
padded grid for the Euler count (freed before the component counts), then about 24 bytes per run.
512³ rods, 2 threads: 0.97 s.)");
  }
  void run(RunContext& ctx) override {
    auto mask = ctx.input<VolumeU8>("mask");
    const TopologyNumbers tn = topology(*mask, {.threads = ctx.threads(), .interrupter = ctx.progress()});
    Table t;
    t.add("object_voxels", std::vector<int64_t>{tn.object_voxels});
    t.add("components", std::vector<int64_t>{tn.components});
    t.add("cavities", std::vector<int64_t>{tn.cavities});
    t.add("euler", std::vector<int64_t>{tn.euler});
    t.add("tunnels", std::vector<int64_t>{tn.tunnels});
    ctx.output("table", std::move(t));
  }
};
SKEL_REGISTER_MODULE(TopologyModule);

class NetworkStatisticsModule final : public Module {
public:
  static ModuleSpec spec() {
    return ModuleSpec(names::network_statistics, "Segment, node and network statistics of a graph")
        .input<SpatialGraph>("graph", "spatial graph (point attribute radius optional)")
        .add_input("mask", all_volume_types(),
                   "region for the length density, its non-zero voxels (a mask, or a distance map: positive exactly "
                   "on the object); default: the graph's source grid box",
                   false)
        .output<Table>("segments", "per edge: length, chord, tortuosity, radius stats, volume, surface")
        .output<Table>("nodes", "per node: degree, position")
        .output<Table>("summary", "one row: totals, densities, branch/end points, loops, orientation histogram")
        .output<SpatialGraph>("graph", "the input with the per-edge statistics as edge attributes (length, chord, tortuosity, orientation, direction_x/y/z, radius stats, volume, surface) and labels (component, branch_type: 0 internal, 1 terminal, 2 isolated, 3 loop), node labels degree and component: written by io.write_graph into .am, .vtp, .graphml")
        .param("radius", &NetworkStatisticsOptions::radius, "point attribute holding radii")
        .param("length_estimator", &NetworkStatisticsOptions::length_estimator,
               "how edges that are voxel paths are measured: tangent (steps projected onto the local tangent; "
               "unbiased on digital lines and curves), chain_code (Kiryati-Kübler step weights), polyline "
               "(sum of point distances: ~9 % long on voxel staircases)")
        .param("tangent_points", &NetworkStatisticsOptions::tangent_points,
               "tangent estimator: points on either side of a step whose chord gives the tangent")
        .min(1)
        .max(1000)
        .param("orientation_bins", &NetworkStatisticsOptions::orientation_bins, "bins of the angle between segments and the axis (0..90°)")
        .min(1)
        .max(180)
        .param("axis", &NetworkStatisticsOptions::axis, "reference axis of the orientation histogram")
        .param("orientation_window", &NetworkStatisticsOptions::orientation_window,
                       "arc length over which segment directions are measured (0 = 10 x the median point step)")
        .min(0)
        .unit(units::length)
        .details(
            "Thesis §6.1. Per segment: length, chord (end-to-end distance), tortuosity = length / "
            "chord (NaN for loops), length-weighted mean, min and max radius, volume and lateral surface of "
            "the truncated cones between consecutive points (π r² integrated along the edge). Per node: "
            "degree (a loop counts twice) and position. Summary: nodes, edges, components, total length, "
            "reference volume (mask volume, else the box of the graph's source grid, else the points' bounding "
            "box), length density = total length / reference volume, branch points (degree >= 3), end points "
            "(degree 1), loops = cyclomatic number E - N + C, total volume/surface, and orientation_k = length "
            "of the pieces whose direction makes an angle to the axis in bin k. Directions are chords of "
            "consecutive pieces of arc length orientation_window cut along each edge (the last piece of an edge "
            "may be shorter): single voxel steps of a skeleton only take the 13 lattice directions (0°, 45°, "
            "54.7°, 90° to an axis), so a histogram of steps would show the grid instead of the network. "
            "Length (length_estimator): an edge whose inner points are 26-connected voxel centres of the graph's "
            "source grid (a skeleton's voxel path) is a digital curve, and the sum of its steps (1, √2, √3 "
            "voxels) overestimates the curve it digitises by ~8-10 % at generic directions. `tangent` "
            "counts each step with its projection onto the local tangent, the chord from tangent_points points "
            "before to tangent_points points after the step (tangent-based length estimation of digital "
            "curves, Coeurjolly & Klette, IEEE TPAMI 26(2) 2004): over a straight stretch the projections "
            "telescope to its chord, so the zigzag cancels; measured on digital straight lines and circles "
            "of radius >= 10 voxels at random orientations its mean error is within 1 % (polyline: +9 %). "
            "`chain_code` weights steps changing 1, 2, 3 coordinates by 0.9016, 1.289, 1.615 (Kiryati & "
            "Kübler, Pattern Recognition 28(3) 1995): unbiased only on average over directions (a run along "
            "an axis counts 0.9016 per voxel). `polyline` (the default, as before this parameter existed) sums the "
            "point distances (exact for graphs whose polylines are the curve: ground truth, drawn or smoothed "
            "graphs); use `tangent` for skeleton graphs (pipelines/vessel_network.yaml does). Edges that are not voxel paths are measured as "
            "polylines by every estimator; no estimate is below the chord. Skeleton branches of thinning.doht "
            "end about where the medial axis does, at the centre of a tube's rounded end (measured on capsules "
            "in bench/RESULTS.md), so terminal branches need no trimming. Radius statistics, volume and surface "
            "use the polyline; the orientation histogram's pieces are cut along it and count in proportion to "
            "the edge's length, so that the histogram sums to total_length. Units: the graph's (its source volume's spacing unit, or its file's), named in every column header. "
            "The `graph` output is a copy of the input (memory: as the input graph) with the per-edge values as "
            "edge attributes and labels, so that io.write_graph carries them into .am, .vtp and .graphml.");
  }
  void run(RunContext& ctx) override {
    auto g = ctx.input<SpatialGraph>("graph");
    auto o = ctx.options<NetworkStatisticsOptions>();
    if (DataPtr m = ctx.input_data("mask")) {
      units::check_same(g->unit, "input 'graph'", volume_grid(*m, "input 'mask'").unit, "input 'mask'");
      o.reference_volume = mask_volume(*m, "input 'mask'");
    }
    auto st = network_statistics(*g, o);
    ctx.output("segments", std::move(st.segments));
    ctx.output("nodes", std::move(st.nodes));
    ctx.output("summary", std::move(st.summary));
    ctx.output("graph", std::move(st.graph));
  }
};
SKEL_REGISTER_MODULE(NetworkStatisticsModule);

// `root_points` is a flat list x y z, x y z, ...
void set_root_points(TreeOptions& o, const std::vector<double>& rp) {
  if (rp.size() % 3 != 0)
    throw InputError("parameter 'root_points': expected x y z triples, got " + std::to_string(rp.size()) + " numbers");
  for (size_t i = 0; i < rp.size(); i += 3) o.root_points.push_back({rp[i], rp[i + 1], rp[i + 2]});
}

class TreesModule final : public Module {
public:
  static ModuleSpec spec() {
    return ModuleSpec(names::trees, "Vessel trees from root points and a minimum diameter")
        .input<SpatialGraph>("graph", "spatial graph (point attribute radius needed when min_diameter > 0)")
        .output<SpatialGraph>("graph", "graph with edge labels tree and branch_order")
        .output<Table>("trees", "per tree: root node, edges, total length")
        .param("roots", &TreeOptions::roots, "root node ids")
        .optional_value()
        .param_fn<TreeOptions>("root_points", std::vector<double>{}, set_root_points, "root positions x y z, x y z ... (nearest node)")
        .optional_value()
        .unit(units::length)
        .param("min_diameter", &TreeOptions::min_diameter, "edges thinner than this (2 × mean radius) are capillaries")
        .min(0)
        .unit(units::length)
        .param("radius", &TreeOptions::radius, "point attribute holding radii")
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
    auto s = extract_trees(g, ctx.options<TreeOptions>());
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
    t.add("tree", id).add("root_node", root).add("edges", edges).add("length", len, g.unit);
    ctx.output("graph", std::move(g));
    ctx.output("trees", std::move(t));
  }
};
SKEL_REGISTER_MODULE(TreesModule);

class LabelPropagationModule final : public Module {
public:
  static ModuleSpec spec() {
    return ModuleSpec(names::label_propagation, "Colour the object by its nearest skeleton edge")
        .input<VolumeU8>("mask", "object (non-zero = object)")
        .optional_input<SpatialGraph>("graph", "graph whose edges colour the object")
        .optional_input<VolumeU32>("seeds", "instead of a graph: label volume (non-zero voxels are seeds)")
        .output<VolumeU32>("labels", "label per object voxel (0 = background or not reached)")
        .param("label", &LabelPropagationOptions::label, "edge label to paint (value + 1); empty: edge id + 1")
        .optional_value()
        .param("metric", &LabelPropagationOptions::metric,
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
    const auto o = ctx.options<LabelPropagationOptions>();
    if (auto g = ctx.optional_input<SpatialGraph>("graph")) {
      units::check_same(g->unit, "input 'graph'", mask->unit(), "input 'mask'");
      ctx.output("labels", propagate_edge_labels(*mask, *g, o));
    } else if (auto s = ctx.optional_input<VolumeU32>("seeds")) {
      ctx.output("labels", propagate_labels(*mask, *s, o));
    } else {
      throw InputError("inputs 'graph' / 'seeds': connect one of them");
    }
  }
};
SKEL_REGISTER_MODULE(LabelPropagationModule);

class DanglingEnds final : public Module {
public:
  static ModuleSpec spec() {
    return ModuleSpec(names::dangling_ends, "End points of a network with their most likely partner across a gap")
        .input<SpatialGraph>("graph", "network graph")
        .output<Table>("table", "one row per end point: position, partner (node or edge point), distance, angle, score")
        .output<SpatialGraph>("graph", "the input with node attribute `gap_score` (0 = no partner) and label `dangling` (1 at end points)")
        .param("max_distance", &graph::DanglingOptions::max_distance, "largest gap to bridge").min(0).unit(units::length)
        .param("max_angle", &graph::DanglingOptions::max_angle_deg, "largest angle between the segment's direction and the gap").range(0, 180).unit("degrees")
        .param("direction_length", &graph::DanglingOptions::direction_length, "how far back along the segment its direction is measured").min(0).unit(units::length)
        .details(R"(Thesis §6.1: about 4 % of the segments end unconnected because vessels were not filled
completely; the user is guided to these ends and connects them. For every node of degree 1 the
direction of its segment is measured over `direction_length`; candidates are the points of all other
edges (including their end nodes) within `max_distance` whose direction from the end lies within
`max_angle`. Score = distance × (1 + (1 − cos angle)), × 0.8 when the partner is itself an end point
(two ends facing each other is the typical gap); the lowest score wins. Rows are sorted by score,
ends without a partner last. A k-d tree (nanoflann) over all polyline points keeps this O(P log P).)");
  }
  void run(RunContext& ctx) override {
    auto g = ctx.input<SpatialGraph>("graph");
    const auto ends = graph::find_dangling_ends(*g, ctx.options<graph::DanglingOptions>());
    std::vector<int64_t> node, partner_node, partner_edge, partner_point;
    std::vector<double> x, y, z, px, py, pz, dist, angle, score;
    std::vector<std::string> kind;
    SpatialGraph out(*g);
    auto& gs = out.ensure_node_attribute("gap_score");
    auto& dl = out.ensure_node_label("dangling");
    for (const auto& d : ends) {
      node.push_back(d.node);
      x.push_back(d.position[0]);
      y.push_back(d.position[1]);
      z.push_back(d.position[2]);
      kind.push_back(!d.has_partner ? "none" : d.partner_is_node ? "node" : "edge");
      partner_node.push_back(d.partner_node);
      partner_edge.push_back(d.partner_edge);
      partner_point.push_back(d.partner_point);
      px.push_back(d.partner_position[0]);
      py.push_back(d.partner_position[1]);
      pz.push_back(d.partner_position[2]);
      dist.push_back(d.distance);
      angle.push_back(d.angle_deg);
      score.push_back(d.score);
      dl[d.node] = 1;
      gs[d.node] = d.has_partner ? static_cast<float>(d.score) : 0.0f;
    }
    Table t;
    t.add("node", node);
    t.add("x", x, g->unit);
    t.add("y", y, g->unit);
    t.add("z", z, g->unit);
    t.add("partner", kind);
    t.add("partner_node", partner_node);
    t.add("partner_edge", partner_edge);
    t.add("partner_point", partner_point);
    t.add("partner_x", px, g->unit);
    t.add("partner_y", py, g->unit);
    t.add("partner_z", pz, g->unit);
    t.add("distance", dist, g->unit);
    t.add("angle", angle, "degrees");
    t.add("score", score);
    ctx.output("table", std::move(t));
    ctx.output("graph", std::move(out));
  }
};
SKEL_REGISTER_MODULE(DanglingEnds);

class ReportModule final : public Module {
public:
  static ModuleSpec spec() {
    return ModuleSpec(names::report, "Self-contained HTML report of a graph: summary, histograms, trees, picture over a MIP")
        .input<SpatialGraph>("graph", "spatial graph (e.g. the graph output of analysis.network_statistics)")
        .optional_input<Table>("summary", "summary table of analysis.network_statistics (shown with its units)")
        .optional_input<Table>("segments", "per-edge table of analysis.network_statistics (its length, tortuosity, mean_radius are histogrammed)")
        .optional_input<Table>("trees", "per-tree table of analysis.trees")
        .optional_input<AnyVolume>("image", "image for the maximum-intensity projection under the network picture (same unit as the graph)")
        .path("path", "", PathRole::Output, "HTML file to create; written to a temporary file and renamed when the run succeeds")
        .extensions({".html", ".htm"})
        .param("title", &ReportOptions::title, "heading and <title> of the page")
        .param("bins", &ReportOptions::bins, "bins of the radius, length and tortuosity histograms (edges rounded to 1, 2, 2.5, 5 x 10^k)")
        .min(1)
        .max(200)
        .param("radius", &ReportOptions::radius, "point attribute holding radii (edge attribute mean_radius wins when present)")
        .param("max_image_size", &ReportOptions::max_image_size, "longer side of the embedded MIP in pixels (the projection is subsampled by an integer stride)")
        .min(16)
        .max(16384)
        .details(
            "One HTML file with everything embedded: no JavaScript, no external file, no network access when it "
            "is opened. Sections: the graph (nodes, edges, total length in the graph's unit, branch and end "
            "points), the summary table when connected (one row shown as quantity / value / unit), hand-written "
            "SVG histograms of the length-weighted mean radius (when the graph has radii), the segment length, "
            "the tortuosity (length / chord; loops excluded) and the inclination of each edge's chord to the z "
            "axis (0..90° in 10° bins); each bar carries its count and the counts of a histogram sum to the "
            "number of edges with a defined value. Per-tree tables come from the trees input, else from the "
            "graph's edge label `tree` (analysis.trees). The picture shows the edges projected along z as SVG "
            "polylines in physical coordinates, over the maximum-intensity projection of the image (any voxel "
            "type, scaled min..max to 8 bits) embedded as a greyscale PNG data URI; direction cosines are not "
            "applied. Memory: 8 bytes per pixel of the projection (nx × ny / stride²) plus the page text "
            "(about 100 bytes per polyline point); the volume is read once, not copied. Written atomically.");
  }
  void run(RunContext& ctx) override {
    auto g = ctx.input<SpatialGraph>("graph");
    auto summary = ctx.optional_input<Table>("summary");
    auto segments = ctx.optional_input<Table>("segments");
    auto trees = ctx.optional_input<Table>("trees");
    DataPtr image = ctx.input_data("image");
    ReportInputs in{.graph = g.get(), .summary = summary.get(), .segments = segments.get(), .trees = trees.get(), .image = image.get()};
    const std::string html = make_report_html(in, ctx.options<ReportOptions>());
    write_file_atomically(ctx.output_path("path"), html);
  }
};
SKEL_REGISTER_MODULE(ReportModule);

}  // namespace
}  // namespace skel::analysis
