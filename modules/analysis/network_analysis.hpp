#pragma once
// Network analysis on a SpatialGraph (thesis §6.1, §6.2): segment / node / summary statistics,
// vessel trees from root nodes and a minimum diameter, and label propagation from skeleton edges
// into the object (fig. 6.14 rods/plates decomposition).
#include <cstdint>
#include <string>
#include <vector>

#include "skel/enum_names.hpp"
#include "skel/interrupter.hpp"
#include "skel/spatial_graph.hpp"
#include "skel/table.hpp"
#include "skel/volume.hpp"

namespace skel::analysis {

enum class Axis { x, y, z };
constexpr auto enum_names(Axis) { return std::to_array<EnumName<Axis>>({{Axis::x, "x"}, {Axis::y, "y"}, {Axis::z, "z"}}); }

// How an edge's length is measured (the `length` column and total_length, length_density).
enum class LengthEstimator {
  // Sum of the distances between consecutive points: exact for polylines that are the curve itself
  // (ground truth, drawn or smoothed graphs), ~8-10 % long on the 26-connected voxel staircase of a
  // skeleton (a digital straight line at a generic angle is a zigzag of 1, √2 and √3 steps).
  polyline,
  // Tangent projection (Coeurjolly & Klette 2004, "A comparative evaluation of length estimators of
  // digital curves", IEEE TPAMI 26(2)): on edges that are voxel paths, every step counts with its
  // projection onto the local tangent, the chord over `tangent_points` points on either side; steps
  // across a straight stretch telescope to its chord, so the staircase's zigzag cancels. Edges that
  // are not voxel paths of graph.source_grid are measured as polylines.
  tangent,
  // Kiryati & Kübler's weighted chain code (1995, "On chain code probabilities and length estimators
  // for digitized three-dimensional curves", Pattern Recognition 28(3)): steps of 1, √2, √3 voxels
  // count 0.9016, 1.289, 1.615: unbiased on average over random directions, but 0.9016 per voxel
  // along an axis. On voxel-path edges; others as polylines. No estimate is below the edge's chord.
  chain_code,
};
constexpr auto enum_names(LengthEstimator) {
  return std::to_array<EnumName<LengthEstimator>>({{LengthEstimator::polyline, "polyline"},
                                                   {LengthEstimator::tangent, "tangent"},
                                                   {LengthEstimator::chain_code, "chain_code"}});
}
struct NetworkStatisticsOptions {
  std::string radius = "radius";  // point attribute with radii (optional; columns omitted without it)
  LengthEstimator length_estimator = LengthEstimator::polyline;
  int tangent_points = 5;  // points on either side of a step whose chord is the tangent (tangent estimator)
  int orientation_bins = 9;       // bins of the angle to `axis`, 0..90°
  Axis axis = Axis::z;
  // Arc length over which the direction is measured (chords of consecutive pieces of this length);
  // <= 0: 10 x the median point step of the graph. Single voxel steps only point along the 13
  // lattice directions, so a histogram of steps shows the grid, not the vessels.
  double orientation_window = 0.0;
  // Reference volume for densities, physical units³; <= 0: the bounding box of graph.source_grid,
  // or of the graph's points when the grid is unknown.
  double reference_volume = 0.0;
};
// Branch types of the edge label `branch_type` (a function of the end nodes' degrees).
enum class BranchType : int32_t {
  internal = 0,  // both ends at branch points (degree >= 3) or on a chain of degree 2
  terminal = 1,  // one end is an end point (degree 1), the other is not
  isolated = 2,  // both ends are end points: a lone segment
  loop = 3,      // node0 == node1: a closed ring
};
struct NetworkStatistics {
  Table segments, nodes, summary;
  // The input graph with the statistics as attributes, so that they travel into graph files: edge
  // attributes length, chord, tortuosity, orientation (angle of the chord to the axis, degrees;
  // NaN for loops), direction_x/y/z (unit chord), with radii mean_radius, min_radius, max_radius,
  // volume, surface; edge labels component (connected component, the tree id of a network without
  // analysis.trees), branch_type (BranchType); node labels degree and component.
  SpatialGraph graph;
};
// segments: edge, node0, node1, length, chord, tortuosity (length/chord, NaN for loops), and with
// radii mean_radius (length-weighted), min_radius, max_radius, volume (frusta), surface (lateral
// frusta areas). nodes: node, degree, x, y, z (+ radius). summary (one row): nodes, edges,
// components, total_length, reference_volume, length_density, branch_points (degree >= 3),
// end_points (degree 1), loops (cyclomatic number), total_volume, total_surface, orientation_window
// and orientation_k: the length of polyline pieces (arc length ~ orientation_window, cut greedily
// along each edge) whose chord makes an angle to the axis in bin k.
NetworkStatistics network_statistics(const SpatialGraph& graph, const NetworkStatisticsOptions& options = {});

namespace detail {
// The length of each step of polyline p (element i: p[i-1] -> p[i]; element 0 is 0) under
// `estimator`; edges that are not voxel paths of `grid` get their Euclidean step lengths.
std::vector<double> step_lengths(const std::vector<Vec3>& p, const Grid& grid, LengthEstimator estimator,
                                 int tangent_points);
}  // namespace detail

// Volume of the non-zero voxels of `mask` in physical units³ (reference volume for densities).
double mask_volume(const VolumeU8& mask);
// The same for a volume of any voxel type (non-zero = inside: a mask, a label image, a distance map
// that is positive exactly on the object). Throws InputError naming `what` for a non-volume.
double mask_volume(const DataObject& region, const std::string& what);

struct TreeOptions {
  std::vector<int64_t> roots;        // root node ids
  std::vector<Vec3> root_points;     // physical positions; the nearest node becomes a root
  double min_diameter = 0.0;         // edges with 2 × mean radius below this belong to no tree
  std::string radius = "radius";     // point attribute with radii (needed when min_diameter > 0)
};
struct TreeStats {
  int64_t tree_edges = 0, capillary_edges = 0;
  std::vector<int64_t> root_nodes;
};
// Labels every edge with `tree` (1-based index of the root whose tree it belongs to, 0 = capillary
// bed) and `branch_order` (1 for edges at the root, +1 after every branching node of degree >= 3;
// 0 for capillaries). Edges of diameter >= min_diameter reachable from a root through such edges
// belong to the tree whose root is nearest along the graph (ties: lower root index).
TreeStats extract_trees(SpatialGraph& graph, const TreeOptions& options);

enum class PropagationMetric {
  euclidean,  // nearest seed voxel in physical (anisotropic) Euclidean distance (exact feature transform)
  geodesic,   // nearest seed along the object: breadth-first wave through the 26-neighbourhood
};
constexpr auto enum_names(PropagationMetric) {
  return std::to_array<EnumName<PropagationMetric>>({{PropagationMetric::euclidean, "euclidean"}, {PropagationMetric::geodesic, "geodesic"}});
}
struct LabelPropagationOptions {
  std::string label;  // edge label to paint; empty: edge id + 1
  PropagationMetric metric = PropagationMetric::euclidean;
  int threads = 0;
  Interrupter interrupter;
};
// Colours every object voxel of `mask` with the label of the nearest edge: edges are drawn into the
// mask's grid as seeds (their polyline sampled at <= 1/2 voxel; where edges overlap the lower edge id
// wins). Euclidean: every object voxel takes the label of its nearest seed voxel (exact Euclidean
// feature transform of modules/distance; ties: smallest (z, y, x) seed); memory 4 bytes/voxel
// output + 1 + 4..8 (feature indices) + 4 (scratch) bytes/voxel. Geodesic: breadth-first wave
// through the object (equal arrival: the seed drawn first); voxels not reached stay 0; memory
// 4 bytes/voxel output + 8 bytes per object voxel in the wave queue. Seeds outside the mask are
// ignored.
VolumeU32 propagate_edge_labels(const VolumeU8& mask, const SpatialGraph& graph,
                                const LabelPropagationOptions& options = {});
// Same wave from a label volume (non-zero voxels are seeds, e.g. a labelled skeleton).
VolumeU32 propagate_labels(const VolumeU8& mask, const VolumeU32& seeds, const LabelPropagationOptions& options = {});

}  // namespace skel::analysis
