// Modules of the geometry family: skeleton → spatial graph by dual cubes.
#include "geometry/names.hpp"
#include "geometry/skeleton_to_graph.hpp"
#include "skel/module.hpp"

namespace skel::geometry {
namespace {

class SkeletonToGraphModule final : public Module {
public:
  static ModuleSpec spec() {
    return ModuleSpec(names::skeleton_to_graph, "Voxel skeleton to a spatial graph by dual cubes")
        .input<VolumeU8>("skeleton", "voxel skeleton (non-zero = skeleton voxel)")
        .optional_input<AnyVolume>("distance", "distance volume on the same grid; gives the point attribute radius")
        .output<SpatialGraph>("graph", "nodes at junctions/ends, edges with polylines in the skeleton's physical unit, radius per point")
        .output<VolumeU8>("manifold", "manifold type per voxel (only when with_manifold is true)")
        .param("smooth_passes", &SkeletonToGraphOptions::smooth_passes, "Gaussian smoothing passes over edge points (0 = off)")
        .min(0)
        .param("smooth_kernel", &SkeletonToGraphOptions::smooth_kernel, "smoothing window in points (>= 3)")
        .min(3)
        .param("radius_scale", &SkeletonToGraphOptions::radius_scale, "radius = distance value × radius_scale (1 for distances in the spacing unit)")
        .min(0)
        .param("with_manifold", &SkeletonToGraphOptions::want_manifold, "also output the manifold type volume")
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
    const auto o = ctx.options<SkeletonToGraphOptions>();
    auto r = skeleton_to_graph(*skel_in, dist.get(), o);
    ctx.output("graph", std::move(r.graph));
    if (o.want_manifold) ctx.output("manifold", std::move(r.manifold));
  }
};
SKEL_REGISTER_MODULE(SkeletonToGraphModule);

}  // namespace
}  // namespace skel::geometry
