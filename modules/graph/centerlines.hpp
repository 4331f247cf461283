#pragma once
// VMTK-style centerlines (one polyline per inlet–outlet path, overlapping along the shared vessels)
// merged into a branch graph.
#include <string>

#include "skel/interrupter.hpp"
#include "skel/spatial_graph.hpp"

namespace skel::graph {

struct MergeCenterlinesOptions {
  // A point closer than this to a point of an earlier polyline lies on that polyline (physical
  // units). 0: radius_factor × the point's radius.
  double tolerance = 0.0;
  double radius_factor = 1.0;
  // Point attribute with the radius (VMTK: the maximum inscribed sphere radius); optional when
  // tolerance > 0. Copied to the output as point attribute `radius`.
  std::string radius = "MaximumInscribedSphereRadius";
  Interrupter interrupter;
};

// Every edge of `centerlines` is one path (its polyline, in order; its nodes are ignored). Paths are
// taken in edge order: a point within the tolerance of a point of an earlier path is that point (the
// nearest one), other points are new; a path adds the stretches where it runs on new points, joined
// to the shared points where it leaves and rejoins the earlier paths. The result is split at every
// point where paths part (degree != 2): nodes at inlets, outlets and bifurcations, one edge per
// branch, point attribute `radius` (when the input has radii), the input's unit and source grid.
// Throws InputError if tolerance is 0 and the radius attribute is missing.
SpatialGraph merge_centerlines(const SpatialGraph& centerlines, const MergeCenterlinesOptions& options);

}  // namespace skel::graph
