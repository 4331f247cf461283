// Module wrappers of the geodesic family.
#include "analysis/names.hpp"
#include "geodesic/geodesic.hpp"
#include "geodesic/names.hpp"
#include "geodesic/surface.hpp"
#include "skel/spatial_graph.hpp"
#include "skel/module.hpp"
#include "skel/table.hpp"

#include <cmath>

namespace skel::geodesic {
namespace {

class BoundaryDistance final : public Module {
public:
  static ModuleSpec spec() {
    return ModuleSpec(names::boundary_distance,
                      "Geodesic boundary distance: importance of object voxels for plate-like (2D) skeletons")
        .input<VolumeU8>("mask", "binary object (voxel > 0 is object)")
        .output<VolumeF32>("importance", "max geodesic distance g(b(p), b(q)) over the considered neighbours; 0 on background")
        .output<VolumeU8>("surface_skeleton", "object voxels with importance >= threshold (1), else 0")
        .output<Table>("table", "statistics: object and boundary-layer voxels, searches, memory")
        .param("threshold", &Options::threshold, "t: importance that selects the surface skeleton; propagation stops at t in threshold mode")
        .range(1, 1000000).unit("voxel steps")
        .param("mode", &Options::mode,
                "threshold: values saturate at t (fast, k·t²/r̄); full: exact values everywhere (+inf where no path exists), e.g. as a thinning priority")
        .details(R"(Thesis §2.3.2. b(p) is the nearest background point of p, found by propagating nearest
points inward from the boundary layer ring by ring (26-neighbourhood, physical spacing). The geodesic
distance g of two points of the background layer L (background voxels 26-adjacent to the object) is the
length of the shortest **6-path inside L**, in voxel steps (anisotropic spacing does not weight steps);
it is infinite when no such path exists. The importance of an object voxel p is the maximum of
g(b(p), b(q)) over its three lower 6-neighbours q, and over its three upper 6-neighbours where they are
background. Voxels outside the array count as background: the one-voxel ring around the array belongs
to L where it touches the object.

Implementation: object voxels are grouped by base point b(p); one breadth-first search per base point
serves all its voxels and stops when all their targets are reached or at t (threshold mode). Searches
run level by level, so they need only a visited mark per boundary voxel, reset through the list of
visited voxels (a search costs what it visits, never the size of L). When a search runs to t, it is
extended to t + t/4 and settles, by the triangle inequality, the far targets of every base point within
t/4 of it (a pivot), which saves most long searches on plates; voxels with a target so proved to
saturate need no further search. Targets in another component of L are known to be infinite without
searching. Results, and the search counts (searches, pivots, saturated targets, visited voxels), are
identical for any thread count: the grid is cut into blocks (z-slabs x y-bands at least 2·t/4 + 2
voxels thick) run in four passes by the parity of (slab, band), so no two workers reach the same base.

Memory (beyond the input mask and the two outputs; the larger of two phases): 4 bits per voxel of the
padded grid (two ranked bitmaps), plus for the nearest-point transform 4 + 1 bytes per object voxel and
6 per boundary-layer voxel, for the searches 4 (b(p)) + 4 (bucket position) bytes per object voxel
and 4 + 4 bytes per boundary-layer voxel plus 2 (t <= 203) or 3 per boundary-layer voxel and worker
thread.)");
  }
  void run(RunContext& ctx) override {
    auto mask = ctx.input<VolumeU8>("mask");
    Result r = boundary_distance(*mask, ctx.options<Options>());
    if (r.stats.object_voxels == 0) ctx.warn("the mask is empty: importance is 0 everywhere");
    Table t;
    t.add("object_voxels", std::vector<int64_t>{r.stats.object_voxels});
    t.add("layer_voxels", std::vector<int64_t>{r.stats.layer_voxels});
    t.add("base_points", std::vector<int64_t>{r.stats.base_points});
    t.add("searches", std::vector<int64_t>{r.stats.searches});
    t.add("saturated_by_pivot", std::vector<int64_t>{r.stats.saturated_by_pivot});
    t.add("visited", std::vector<int64_t>{r.stats.visited});
    t.add("working_bytes", std::vector<int64_t>{static_cast<int64_t>(r.stats.bytes)}, "bytes");
    ctx.output("importance", std::move(r.importance));
    ctx.output("surface_skeleton", std::move(r.surface_skeleton));
    ctx.output("table", std::move(t));
  }
};
SKEL_REGISTER_MODULE(BoundaryDistance);

ModuleSpec& distance_unit_params(ModuleSpec& s) {
  return s.param("distance_unit", &TubularityOptions::unit,
                  "unit of the distance input: physical (distance.euclidean; divided by the mean spacing), chamfer (divided by chamfer_unit), voxels")
      .param("chamfer_unit", &TubularityOptions::chamfer_unit, "chamfer value of one voxel step (3 for the 3-4-5 chamfer distance)")
      .min(1e-6);
}

class ThinSurface final : public Module {
public:
  static ModuleSpec spec() {
    return ModuleSpec(names::thin_surface, "Thins selected surface voxels to a one-voxel-thin plate skeleton")
        .input<VolumeU8>("surface", "surface voxels (e.g. geodesic.boundary_distance surface_skeleton)")
        .output<VolumeU8>("skeleton", "one-voxel-thin surface skeleton (0/1)")
        .details(R"(Thesis §2.3.2, fig. 2.35: the voxels selected by a threshold on the geodesic importance
represent 2-cells but are often two voxels thick. This removes simple voxels (26/6) in six directional
sub-iterations with sequential rechecking (after Borgefors et al. 1999): a voxel goes in sub-iteration
d only if its neighbour at +d is outside the set and the one at -d inside (a two-voxel-thick part), and
never if some axis has both 6-neighbours outside the set — surface points, surface edges and curve
ends. The plate skeleton thus becomes thin but keeps its geometric extent, its cavities and its
topology. Memory: 1 byte per voxel (output) plus 8 bytes per surface voxel.)");
  }
  void run(RunContext& ctx) override {
    auto in = ctx.input<VolumeU8>("surface");
    auto r = thin_surface(*in, ctx.options<ThinSurfaceOptions>());
    ctx.output("skeleton", std::move(r.surface));
  }
};
SKEL_REGISTER_MODULE(ThinSurface);

class Tubularity final : public Module {
public:
  static ModuleSpec spec() {
    ModuleSpec s(analysis::names::tubularity, "The ratio g/d on skeleton voxels: geodesic importance over boundary distance");
    s.input<VolumeU8>("skeleton", "skeleton voxels (0/1)")
        .input<VolumeF32>("importance", "geodesic.boundary_distance importance")
        .add_input("distance", all_volume_types(), "distance to the boundary (distance.euclidean or distance.chamfer)", true)
        .optional_input<SpatialGraph>("graph", "graph whose points get the ratio as point attribute `tubularity`")
        .output<VolumeF32>("ratio", "g/d on skeleton voxels, 0 elsewhere")
        .output<SpatialGraph>("graph", "the input graph with point attribute `tubularity` (if a graph was given)");
    distance_unit_params(s);
    s.details(R"(Thesis §6.2 (figs. 6.9, 6.11, 6.13): g is the geodesic importance (voxel steps along the
boundary layer), d the distance to the boundary converted to voxels. On a rod of radius r the two
nearest boundary points of neighbouring voxels lie on opposite sides, half a circumference apart: g is
about pi·r and g/d about pi. On a plate the path goes around the plate's rim, so g grows with the
plate's width and g/d is large (t/d when the importance saturates at t). The ratio therefore separates
rod-like from plate-like parts independently of thickness. d below half a voxel counts as half a voxel.
Graph points take the ratio of the voxel they lie in (0 off the skeleton). Memory: 4 bytes per voxel.)");
    return s;
  }
  void run(RunContext& ctx) override {
    auto sk = ctx.input<VolumeU8>("skeleton");
    auto imp = ctx.input<VolumeF32>("importance");
    auto dist = ctx.input_data("distance");
    VolumeF32 ratio = tubularity(*sk, *imp, *dist, ctx.options<TubularityOptions>());
    if (auto g = ctx.optional_input<SpatialGraph>("graph")) {
      SpatialGraph out(*g);
      auto& pa = out.ensure_point_attribute("tubularity");
      const Grid& gr = ratio.grid();
      for (int64_t e = 0; e < out.edge_count(); ++e)
        for (size_t i = 0; i < out.edges[e].points.size(); ++i) {
          const auto& p = out.edges[e].points[i];
          int64_t c[3];
          for (int k = 0; k < 3; ++k) c[k] = std::llround((p[k] - gr.origin[k]) / gr.spacing[k]);
          pa[e][i] = ratio.at_or(c[0], c[1], c[2], 0.0f);
        }
      ctx.output("graph", std::move(out));
    }
    ctx.output("ratio", std::move(ratio));
  }
};
SKEL_REGISTER_MODULE(Tubularity);

class RodsPlates final : public Module {
public:
  static ModuleSpec spec() {
    ModuleSpec s(analysis::names::rods_plates, "Rods/plates decomposition of a (bone) object from its skeleton and g/d");
    s.input<VolumeU8>("mask", "the object (voxel > 0)")
        .input<VolumeU8>("skeleton", "its (mixed-dimensional) skeleton")
        .input<VolumeF32>("importance", "geodesic.boundary_distance importance")
        .add_input("distance", all_volume_types(), "distance to the boundary", true)
        .output<VolumeU8>("labels", "every object voxel: 1 rod, 2 plate (0 background)")
        .output<VolumeU8>("skeleton_labels", "skeleton voxels: 1 rod, 2 plate")
        .output<Table>("table", "per class: voxels, volume, fraction, surface, skeleton voxels, pieces, mean thickness, plate-to-rod ratio")
        .param("ratio_threshold", &RodsPlatesOptions::ratio_threshold, "g/d at or above which a skeleton voxel is plate").min(0);
    distance_unit_params(s);
    s.details(R"(Thesis §6.2 and fig. 6.14. Skeleton voxels are classified by the ratio g/d (see
analysis.tubularity): rods give about pi, plates far more. The default threshold 5 sits between pi and
the values of plates wider than a few thicknesses; with threshold-mode importance saturating at t,
plates of thickness 2d are recognised while t/d >= 5 (choose t >= 10·d_max). Every object voxel takes
the class of its nearest skeleton voxel (exact Euclidean feature transform), which decomposes the
object into rod and plate parts. The table gives the structural indices bone researchers report: rod
and plate volume and volume fraction, surface (voxel faces × face area), skeleton voxels, pieces
(26-components of each class's skeleton), mean thickness (2 × mean distance on the class's skeleton,
in the distance input's unit) and the plate-to-rod volume ratio. Memory: 1 byte (labels) + 4 (ratio)
+ 4–8 (feature transform) + 4 bytes per voxel during the transform.)");
    return s;
  }
  void run(RunContext& ctx) override {
    auto mask = ctx.input<VolumeU8>("mask");
    auto o = ctx.options<RodsPlatesOptions>();
    ctx.fill(o.tubularity);
    auto r = rods_plates(*mask, *ctx.input<VolumeU8>("skeleton"), *ctx.input<VolumeF32>("importance"),
                                   *ctx.input_data("distance"), o);
    ctx.output("labels", std::move(r.labels));
    ctx.output("skeleton_labels", std::move(r.skeleton_labels));
    ctx.output("table", std::move(r.table));
  }
};
SKEL_REGISTER_MODULE(RodsPlates);

}  // namespace
}  // namespace skel::geodesic
