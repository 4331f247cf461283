// Modules of the comparison family: skeleton distance (thesis §6.2) and graph matching.
#include "comparison/comparison.hpp"
#include "comparison/names.hpp"
#include "skel/module.hpp"
#include "skel/units.hpp"

namespace skel::comparison {
namespace {

std::vector<std::string> skeleton_or_graph_types() {
  std::vector<std::string> t = integer_volume_types();
  t.emplace_back(type_ids::graph);
  return t;
}

comparison::SkeletonInput skeleton_input(const RunContext& ctx, const std::string& port) {
  comparison::SkeletonInput in;
  in.name = port;
  DataPtr d = ctx.input_data(port);
  if (!d) throw InputError("input '" + port + "' is not connected");
  if (auto g = dynamic_cast<const SpatialGraph*>(d.get())) in.graph = g;
  else in.volume = d.get();
  return in;
}

// Value of the distance volumes off the skeleton.
enum class OffSkeleton { zero, nan };
constexpr auto enum_names(OffSkeleton) {
  return std::to_array<EnumName<OffSkeleton>>({{OffSkeleton::zero, "zero"}, {OffSkeleton::nan, "nan"}});
}

class SkeletonDistanceModule final : public Module {
public:
  static ModuleSpec spec() {
    return ModuleSpec(names::skeleton_distance,
                      "Distance of every reference skeleton point to the nearest point of another skeleton")
        .add_input("reference", skeleton_or_graph_types(), "reference skeleton: integer volume (voxel > 0 = skeleton point) or graph", true)
        .add_input("other", skeleton_or_graph_types(), "skeleton compared against: integer volume or graph, same or different grid", true)
        .output<VolumeF32>("distance", "reference is a volume: distance (spacing unit) at each reference skeleton voxel, 0 or NaN elsewhere (off_skeleton)")
        .output<VolumeU8>("changed", "reference is a volume: 1 at reference skeleton voxels with distance > threshold")
        .output<SpatialGraph>("graph", "reference is a graph: a copy with point attributes distance and changed (0/1), edge attribute changed_fraction")
        .output<VolumeF32>("other_distance", "symmetric and other is a volume: distance of each other skeleton voxel to the reference")
        .output<VolumeU8>("other_changed", "symmetric and other is a volume: other skeleton voxels further than threshold from the reference")
        .output<SpatialGraph>("other_graph", "symmetric and other is a graph: a copy with point attributes distance and changed")
        .output<Table>("table", "rows reference_to_other [, other_to_reference, symmetric]: points, weight, mean, median, p95, hausdorff, changed_points, changed_weight, changed_fraction, threshold")
        .param("threshold", &SkeletonDistanceOptions::threshold, "points further than this from the other skeleton are changed").min(0).unit(units::length)
        .param("symmetric", &SkeletonDistanceOptions::symmetric, "also measure other -> reference; the table gets both directions and the symmetric (pooled) row")
        .param("method", &SkeletonDistanceOptions::method,
                "transform: seeded Euclidean distance transform (volumes on one grid); kdtree: nearest point in physical coordinates (any inputs); automatic: transform when possible")
        .param("sample_spacing", &SkeletonDistanceOptions::sample_spacing, "a graph compared against is sampled along its polylines at most this far apart; 0 = half the smallest voxel spacing of the inputs").min(0).unit(units::length)
        .param_fn<SkeletonDistanceOptions>(
            "off_skeleton", OffSkeleton::zero,
            [](SkeletonDistanceOptions& o, OffSkeleton v) { o.nan_off_skeleton = v == OffSkeleton::nan; },
            "value of the distance volumes off the skeleton")
        .details(R"(Thesis §6.2 "Analyzing Architectural Alterations" (figs. 6.15, 6.16): after registration, the
skeleton of the original scan is compared to the skeleton after compression testing by "a distance
transformation seeded at the skeleton"; points far from the other skeleton moved or vanished.
Method `transform` (the thesis' way; chosen automatically when both inputs are volumes on the same
grid, dims, spacing and origin equal): the exact Euclidean distance transform seeded at the other
skeleton (distance.seeded: separable lower envelopes, anisotropic spacing) is read at every
reference skeleton voxel. Method `kdtree` (graphs, or volumes on different grids, e.g. before
resampling): nearest-point queries in a nanoflann k-d tree over the other skeleton's points in
physical coordinates — voxel centres of a volume; node positions, polyline points and polyline
samples every sample_spacing of a graph (so the distance to a graph is exact up to
sample_spacing / 2). Both give the exact Euclidean distance between voxel centres on one grid.
Statistics are weighted: 1 per voxel for a volume, the length a polyline point stands for (half of
each adjacent segment) for a graph, so `changed_fraction` is the fraction of the reference length
(point count for volumes) further than `threshold`. median and p95 are weighted quantiles (the
smallest value whose cumulative weight reaches 50 % / 95 %); hausdorff is the maximum (one-sided;
the symmetric row pools both directions, its hausdorff is the symmetric Hausdorff distance).
An empty other skeleton gives +inf distances. Outputs exist only for the matching input kinds
(volume outputs for volume inputs, graph outputs for graph inputs). Memory (transform): 5 bytes per
voxel (seeded distance 4 B + seed mask 1 B unless other is uint8) plus the outputs distance 4 B
and changed 1 B per voxel, plus ~48 B per skeleton point; kdtree: ~80 B per point. Deterministic
for any thread count.)");
  }
  void run(RunContext& ctx) override {
    const auto o = ctx.options<SkeletonDistanceOptions>();
    auto r = comparison::skeleton_distance(skeleton_input(ctx, "reference"), skeleton_input(ctx, "other"), o);
    if (r.reference.is_graph) {
      ctx.output("graph", std::move(r.reference.graph));
    } else {
      ctx.output("distance", std::move(r.reference.distance));
      ctx.output("changed", std::move(r.reference.changed));
    }
    if (o.symmetric) {
      if (r.other.is_graph) {
        ctx.output("other_graph", std::move(r.other.graph));
      } else {
        ctx.output("other_distance", std::move(r.other.distance));
        ctx.output("other_changed", std::move(r.other.changed));
      }
    }
    ctx.output("table", std::move(r.table));
  }
};
SKEL_REGISTER_MODULE(SkeletonDistanceModule);

class GraphMatchModule final : public Module {
public:
  static ModuleSpec spec() {
    return ModuleSpec(names::graph_match, "Matches two spatial graphs: nodes, edges and length, precision/recall/F1")
        .input<SpatialGraph>("reference", "reference graph (e.g. ground truth)")
        .input<SpatialGraph>("other", "graph to evaluate (e.g. a reconstruction)")
        .output<SpatialGraph>("reference_graph", "reference copy: node/edge labels matched (0/1) and match (partner id or -1), edge attribute coverage, point attribute covered")
        .output<SpatialGraph>("other_graph", "other copy with the same labels and attributes (matched 0 = extra)")
        .output<Table>("table", "rows nodes, edges, length: reference, other, tp, fp, fn, precision, recall, f1")
        .output<Table>("errors", "NetMets-style errors: geometric_fnr, geometric_fpr, connectivity_fnr, connectivity_fpr, lengths, sample counts")
        .param("node_tolerance", &GraphMatchOptions::node_tolerance, "nodes at most this far apart may be matched").min(0).unit(units::length)
        .param("edge_tolerance", &GraphMatchOptions::edge_tolerance, "a polyline sample is covered if a sample of the other geometry is at most this far").min(0).unit(units::length)
        .param("sample_spacing", &GraphMatchOptions::sample_spacing, "polylines are resampled at equal steps of at most this length").min(1e-9).unit(units::length)
        .param("overlap", &GraphMatchOptions::overlap, "fraction of an edge's samples (both ways) that must be covered by its partner edge").range(1e-6, 1)
        .details(R"(Compares two reconstructions of one network (two methods, two time points, a reconstruction
against ground truth). 1. Nodes: every pair closer than node_tolerance is a candidate; an optimal
assignment — the maximum number of pairs, and among those the least total distance — is found by
successive shortest augmenting paths with potentials (sparse Hungarian / Jonker–Volgenant) on each
connected component of the candidate graph; tested against brute force. 2. Polylines are resampled
at equal arc-length steps <= sample_spacing (ends included; each sample weighs the length it stands
for); a sample is covered by a geometry when a sample of that geometry lies within edge_tolerance
(k-d tree, nanoflann). 3. Edges: reference edge e and other edge f are candidates when their end
nodes are matched to each other ({match(e.node0), match(e.node1)} = {f.node0, f.node1}, loops
included) and at least `overlap` of e's samples are covered by f's samples and of f's by e's; an
optimal assignment with cost 2 − coverage(e by f) − coverage(f by e) picks one partner per edge.
Unmatched reference edges are false negatives, unmatched other edges false positives (the same for
nodes). 4. Length: tp = covered reference length, fn = uncovered reference length, fp = uncovered
other length; precision = (other − fp) / other, recall = tp / reference (1 when the total is 0).
NetMets (Mayerich et al. 2012) with a hard tolerance: geometric FNR/FPR = uncovered length
fractions; connectivity FNR = of the reference edges whose geometry is found (coverage >= overlap)
the fraction without an edge match (missing or wrong connections), FPR likewise for the other graph.
Memory: ~100 B per sample and per node. Deterministic for any thread count.)");
  }
  void run(RunContext& ctx) override {
    auto r = graph_match(*ctx.input<SpatialGraph>("reference"), *ctx.input<SpatialGraph>("other"),
                         ctx.options<GraphMatchOptions>());
    ctx.output("reference_graph", std::move(r.reference));
    ctx.output("other_graph", std::move(r.other));
    ctx.output("table", std::move(r.table));
    ctx.output("errors", std::move(r.errors));
  }
};
SKEL_REGISTER_MODULE(GraphMatchModule);

}  // namespace
}  // namespace skel::comparison
