#pragma once
// Comparing two reconstructions of one structure (thesis §6.2 "Analyzing Architectural Alterations",
// figs. 6.15/6.16): the distance of every skeleton point of a reference to the nearest point of the
// other skeleton (a Euclidean distance transform seeded at the other skeleton, as in the thesis), and
// the matching of two spatial graphs (nodes by an optimal assignment, edges by polyline overlap) with
// detection scores and NetMets-style geometric / connectivity errors.
//
// Conventions:
// - Skeleton volumes: any integer volume, voxel > 0 = skeleton point at its voxel centre
//   (Grid::position). Graphs: polyline points (SpatialGraph::edges[e].points) and isolated nodes.
// - Every distance and tolerance is in physical units (spacing, µm by default).
// - Results never depend on the thread count.
#include <cstdint>
#include <string>
#include <vector>

#include "skel/enum_names.hpp"
#include "skel/interrupter.hpp"
#include "skel/spatial_graph.hpp"
#include "skel/table.hpp"
#include "skel/volume.hpp"

namespace skel::comparison {

// ---------------------------------------------------------------------------------------------
// Skeleton distance

enum class DistanceMethod {
  Automatic,  // Transform when both inputs are volumes on the same grid, else KdTree
  Transform,  // seeded exact EDT of the other skeleton on the reference grid (both must be volumes
              // on the same grid; thesis §6.2)
  KdTree      // nearest other point by a k-d tree (nanoflann) in physical coordinates; any inputs
};
constexpr auto enum_names(DistanceMethod) {
  return std::to_array<EnumName<DistanceMethod>>(
      {{DistanceMethod::Automatic, "automatic"}, {DistanceMethod::Transform, "transform"}, {DistanceMethod::KdTree, "kdtree"}});
}
// "automatic" | "transform" | "kdtree"; throws InputError naming `what` otherwise.
DistanceMethod parse_distance_method(const std::string& text, const std::string& what = "method");

// One side of the comparison: a skeleton volume or a graph (exactly one is set).
struct SkeletonInput {
  const DataObject* volume = nullptr;     // any integer volume, > 0 = skeleton
  const SpatialGraph* graph = nullptr;
  std::string name = "reference";         // port name used in error messages
};

struct SkeletonDistanceOptions {
  double threshold = 2.0;         // points further than this are `changed` (physical units)
  bool symmetric = false;         // also other -> reference
  DistanceMethod method = DistanceMethod::Automatic;
  // Graphs as the *other* side are sampled along their polylines at most this far apart (physical
  // units; the distance to a graph is then exact up to sample_spacing / 2). <= 0: automatic, half the
  // smallest spacing of the reference volume / of the graph's source grid (1 if none is known).
  double sample_spacing = 0.0;
  bool nan_off_skeleton = false;  // off-skeleton voxels of the distance volumes: NaN instead of 0
  int threads = 0;
  Interrupter interrupter;
};

// Statistics of one direction. Weights: 1 per skeleton voxel for volumes; for graphs the polyline
// length a point stands for (half of each adjacent segment), so fractions are fractions of length.
struct DistanceStatistics {
  int64_t points = 0;           // number of points
  double weight = 0;            // total weight (points for volumes, length for graphs)
  double mean = 0, median = 0, p95 = 0, max = 0;  // weighted; max is the one-sided Hausdorff
  int64_t changed_points = 0;   // points with distance > threshold
  double changed_weight = 0;    // their weight
  double changed_fraction = 0;  // changed_weight / weight (0 when there are no points)
};

// Per-point distances of one side, in the layout of that side.
struct SideDistances {
  VolumeF32 distance;  // volume side: distance at skeleton voxels, 0 (or NaN) elsewhere; empty for graphs
  VolumeU8 changed;    // volume side: 1 where distance > threshold; empty for graphs
  SpatialGraph graph;  // graph side: copy with point attributes `distance` and `changed` (0/1),
                       // edge attribute `changed_fraction`; empty for volumes
  std::vector<double> values;   // distance per point in point order (voxels x-fastest / polyline points)
  std::vector<double> weights;  // weight per point
  DistanceStatistics stats;
  bool is_graph = false;
};

struct SkeletonDistanceResult {
  SideDistances reference;  // reference -> other
  SideDistances other;      // other -> reference (only when symmetric)
  DistanceStatistics symmetric;  // both directions pooled (max = symmetric Hausdorff); symmetric only
  DistanceMethod method_used = DistanceMethod::KdTree;
  // Rows: reference_to_other[, other_to_reference, symmetric]; columns direction, points, weight,
  // mean, median, p95, hausdorff, changed_points, changed_weight, changed_fraction, threshold.
  Table table;
};

// Throws InputError (naming the port) for a missing/non-integer volume or a graph/volume mix that
// `method` cannot handle, and when the Transform method is asked for inputs on different grids.
SkeletonDistanceResult skeleton_distance(const SkeletonInput& reference, const SkeletonInput& other,
                                         const SkeletonDistanceOptions& options = {});

// Weighted quantile (q in [0, 1]) of values: the smallest value whose cumulative weight (in
// ascending order) reaches q * total weight. Empty input: 0.
double weighted_quantile(std::vector<std::pair<double, double>> value_weight, double q);

// ---------------------------------------------------------------------------------------------
// Optimal assignment

// One candidate pair of a bipartite assignment problem.
struct AssignmentCandidate {
  int64_t left = 0, right = 0;
  double cost = 0;  // >= 0
};
// Minimum-cost maximum-cardinality matching on a sparse bipartite candidate graph: among all
// matchings with the largest number of pairs, one of least total cost. Successive shortest augmenting
// paths with Johnson potentials (the sparse Hungarian / Jonker–Volgenant scheme), solved per connected
// component of the candidate graph; deterministic (ties broken by candidate order).
// Returns match_left[l] = right partner or -1 (size n_left). Throws Error on ids out of range or
// negative/non-finite costs.
std::vector<int64_t> min_cost_matching(int64_t n_left, int64_t n_right,
                                       const std::vector<AssignmentCandidate>& candidates);

// ---------------------------------------------------------------------------------------------
// Graph matching

struct GraphMatchOptions {
  double node_tolerance = 3.0;   // nodes closer than this may match (physical units)
  double edge_tolerance = 3.0;   // a sample is covered if a sample of the other geometry is this close
  double sample_spacing = 1.0;   // polylines are sampled at most this far apart (physical units)
  double overlap = 0.8;          // fraction of an edge's samples that must be covered (0..1]
  int threads = 0;
  Interrupter interrupter;
};

struct MatchCounts {
  double reference = 0, other = 0;  // totals (counts, or lengths)
  double tp = 0, fp = 0, fn = 0;    // length: tp = covered reference length, fp = uncovered other length
  double precision = 0, recall = 0, f1 = 0;
};

struct GraphMatchResult {
  // Copies of the inputs with node and edge labels `matched` (0/1) and `match` (id of the partner in
  // the other graph or -1), edge attribute `coverage` (fraction of the edge's samples covered by the
  // other graph's geometry) and point attribute `covered` (0/1 per polyline point).
  SpatialGraph reference, other;
  MatchCounts nodes, edges, length;
  // NetMets-style errors (Mayerich et al. 2012), with a hard tolerance instead of a Gaussian:
  double geometric_fnr = 0;     // fraction of reference length not covered by the other
  double geometric_fpr = 0;     // fraction of other length not covered by the reference
  double connectivity_fnr = 0;  // of the reference edges whose geometry is found (coverage >= overlap),
                                // the fraction not matched as edges (wrong or missing connections)
  double connectivity_fpr = 0;  // the same for the other graph's edges
  int64_t reference_samples = 0, other_samples = 0;
  Table table;   // rows nodes, edges, length: reference, other, tp, fp, fn, precision, recall, f1
  Table errors;  // one row: geometric_fnr, geometric_fpr, connectivity_fnr, connectivity_fpr, counts
};

// Matching (documented precisely in docs/comparison.md):
// 1. Nodes: candidates are pairs closer than node_tolerance; min_cost_matching with the distance as
//    cost (all nodes, of any degree).
// 2. Samples: each edge polyline is resampled at equal arc-length steps <= sample_spacing (both ends
//    included); a sample is covered by a geometry if a sample of it lies within edge_tolerance.
// 3. Edges: reference edge e and other edge f are candidates when their end nodes are matched to
//    each other ({m(e.node0), m(e.node1)} == {f.node0, f.node1}) and at least `overlap` of e's
//    samples are covered by f's samples and of f's by e's; min_cost_matching with cost
//    2 − coverage(e by f) − coverage(f by e) picks one partner per edge.
// 4. Length: covered reference length (samples weighted by the length they stand for) is tp, the
//    uncovered reference length fn, the uncovered other length fp.
GraphMatchResult graph_match(const SpatialGraph& reference, const SpatialGraph& other,
                             const GraphMatchOptions& options = {});

// Equal-arc-length resampling of a polyline with steps <= spacing (both ends kept; a polyline of
// zero length gives its first point). Weight of each sample = the length it stands for.
void resample_polyline(const std::vector<Vec3>& points, double spacing, std::vector<Vec3>& samples,
                       std::vector<double>& weights);

}  // namespace skel::comparison
