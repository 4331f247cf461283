// Modules of the bone analysis (thesis §6.2): the ratio g/d on skeletons (analysis.tubularity), rods
// and plates per voxel by g/d (analysis.rods_plates; algorithms in geodesic/surface.hpp) and per
// skeleton element with the structural indices (analysis.rods_plates_elements; analysis/rods_plates.hpp).
#include <cmath>

#include "analysis/names.hpp"
#include "analysis/rods_plates.hpp"
#include "geodesic/surface.hpp"
#include "skel/module.hpp"
#include "skel/spatial_graph.hpp"
#include "skel/table.hpp"
#include "skel/units.hpp"

namespace skel::analysis {
namespace {

ModuleSpec& distance_unit_params(ModuleSpec& s) {
  return s.param("distance_unit", &geodesic::TubularityOptions::unit,
                  "unit of the distance input: physical (distance.euclidean; divided by the mean spacing), chamfer (divided by chamfer_unit), voxels")
      .param("chamfer_unit", &geodesic::TubularityOptions::chamfer_unit, "chamfer value of one voxel step (3 for the 3-4-5 chamfer distance)")
      .min(1e-6);
}

class Tubularity final : public Module {
public:
  static ModuleSpec spec() {
    ModuleSpec s(names::tubularity, "The ratio g/d on skeleton voxels: geodesic importance over boundary distance");
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
    VolumeF32 ratio = geodesic::tubularity(*sk, *imp, *dist, ctx.options<geodesic::TubularityOptions>());
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
    ModuleSpec s(names::rods_plates, "Rods/plates decomposition of a (bone) object from its skeleton and g/d");
    s.input<VolumeU8>("mask", "the object (voxel > 0)")
        .input<VolumeU8>("skeleton", "its (mixed-dimensional) skeleton")
        .input<VolumeF32>("importance", "geodesic.boundary_distance importance")
        .add_input("distance", all_volume_types(), "distance to the boundary", true)
        .output<VolumeU8>("labels", "every object voxel: 1 rod, 2 plate (0 background)")
        .output<VolumeU8>("skeleton_labels", "skeleton voxels: 1 rod, 2 plate")
        .output<Table>("table", "per class: voxels, volume, fraction, surface, skeleton voxels, pieces, mean thickness, plate-to-rod ratio")
        .param("ratio_threshold", &geodesic::RodsPlatesOptions::ratio_threshold, "g/d at or above which a skeleton voxel is plate").min(0);
    distance_unit_params(s);
    s.details(R"(Thesis §6.2 and fig. 6.14. Skeleton voxels are classified by the ratio g/d (see
analysis.tubularity): rods give about pi, plates far more. The default threshold 5 sits between pi and
the values of plates wider than a few thicknesses; with threshold-mode importance saturating at t,
plates of thickness 2d are recognised while t/d >= 5 (choose t >= 10·d_max). Every object voxel takes
the class of its nearest skeleton voxel (exact Euclidean feature transform), which decomposes the
object into rod and plate parts. The table gives the structural indices bone researchers report: rod
and plate volume and volume fraction, surface (voxel faces × face area), skeleton voxels, pieces
(26-components of each class's skeleton), mean thickness (2 × mean distance on the class's skeleton,
in the distance input's unit) and the plate-to-rod volume ratio. This is the per-voxel method: near a
plate's rim g/d behaves as on a rod (about pi), so plate borders come out as rods (thesis §6.2);
analysis.rods_plates_elements decides per skeleton element (curve piece or surface patch) instead and
gives the structural indices per element. Memory: 1 byte (labels) + 4 (ratio)
+ 4–8 (feature transform) + 4 bytes per voxel during the transform.)");
    return s;
  }
  void run(RunContext& ctx) override {
    auto mask = ctx.input<VolumeU8>("mask");
    auto o = ctx.options<geodesic::RodsPlatesOptions>();
    ctx.fill(o.tubularity);
    auto r = geodesic::rods_plates(*mask, *ctx.input<VolumeU8>("skeleton"), *ctx.input<VolumeF32>("importance"),
                                   *ctx.input_data("distance"), o);
    ctx.output("labels", std::move(r.labels));
    ctx.output("skeleton_labels", std::move(r.skeleton_labels));
    ctx.output("table", std::move(r.table));
  }
};
SKEL_REGISTER_MODULE(RodsPlates);

class RodsPlatesElements final : public Module {
public:
  static ModuleSpec spec() {
    return ModuleSpec(names::rods_plates_elements,
                      "Rods and plates per skeleton element: the mixed skeleton cut into elements, each a rod or a plate, propagated to the object; structural indices")
        .input<VolumeU8>("mask", "the object (voxel > 0), e.g. segmented bone")
        .input<VolumeU8>("skeleton", "its mixed (plate + curve) skeleton, e.g. thinning.doht with the plates locked")
        .add_input("distance", all_volume_types(), "distance to the boundary in physical units (distance.euclidean)", true)
        .output<VolumeI32>("elements", "element id of every object voxel (that of its nearest skeleton voxel), 0 outside")
        .output<VolumeU8>("classes", "every object voxel: 1 rod, 2 plate (0 background)")
        .output<VolumeI32>("skeleton_elements", "element id on the skeleton voxels only")
        .output<Table>("table", "one row per element: id, class, kind, skeleton voxels, voxels, volume, thickness, length (rods), area (plates), junctions")
        .output<Table>("indices", "structural indices: TV, BV, BV/TV, rBV/BV, pBV/BV, rod and plate counts, mean rod thickness and length, mean plate thickness and area, junctions, rod-plate junctions")
        .param("plate_aspect", &RodsPlatesElementOptions::plate_aspect,
               "a surface patch is a plate when the square root of its area is at least plate_aspect times its thickness")
        .min(0)
        .details(R"(Thesis §6.2, fig. 6.14: the skeleton is cut into structural elements, each element is
coloured as a whole and the colours are propagated to the object, every voxel taking the element of the
nearest skeleton point. Here the skeleton is the mixed skeleton (plates and curves) and elements are
found by the manifold type of each skeleton voxel (fig. 3.9, the dual-cube cell complex of §3.1.1, as in
geometry.skeleton_to_graph): curve voxels (1-manifold, 1-boundary, isolated) and surface voxels
(2-manifold, 2-boundary) form elements as the components of one kind through the complex's 1-cells;
junction voxels separate them (a rod meeting a plate ends at a 1-x-junction voxel of the plate; two
plates meet along a line of junction voxels). A curve element is a rod (an edge of the graph part of
the skeleton). A surface element is a plate when its extent is large against its thickness:
sqrt(A) >= plate_aspect · T, with A the area of its one-voxel-thin skeleton patch (voxel count × mean
spacing²) and T = 2 × the mean distance to the boundary over its voxels; otherwise (small surface
fragments inside thick rods) it is a rod. Because a plate is decided as a whole, its border stays plate,
where the per-voxel g/d threshold of analysis.rods_plates calls border voxels rods (g/d ≈ pi there).

Junction voxels are then joined to the nearest element through the 1-cells (breadth first; a plate
before a rod, then the lowest id); a cluster of junction voxels touching no element becomes an element
of its own (kind `cluster`, a rod). Every object voxel takes the element of its nearest skeleton voxel
(exact Euclidean feature transform). Elements are numbered in the order of their first skeleton voxel
(raster order), cluster elements last.

Table per element: `thickness` = 2 × mean distance over the element's own skeleton voxels; `length`
(rods) = length of the 1-cells of its skeleton voxels, a 1-cell to another element counting half (for
rods that are not curves: the length of a cylinder of the element's volume and thickness); `area`
(plates) = volume / thickness, the mid-surface area of a plate of uniform thickness (the skeleton patch
itself ends short of the rim and counts an inclined plane's voxels once per staircase step, so its
voxel count underestimates the area); `junctions` = junction
clusters it touches. Indices: TV = the grid's volume, BV = the object's; rBV/BV and pBV/BV the volume
fractions of rods and plates; rod and plate thickness, length and area are means over elements;
`junctions` counts junction clusters, `rod_plate_junctions` those touching a rod and a plate. Lengths in
the mask's unit. The per-voxel g/d method stays available as analysis.rods_plates.

Memory: outputs 4 (elements) + 1 (classes) + 4 (skeleton elements) bytes per voxel; working 1 byte per
voxel plus the feature transform (4 or 8 bytes per voxel out, 4 during); 60-100 bytes per skeleton
voxel (voxel list 8, manifold type 1, element, own-element, junction and proposal ids 16, 1-cell lists
8 + 8 per incident 1-cell: about 2 on curves, 4-8 on surfaces).)");
  }
  void run(RunContext& ctx) override {
    auto mask = ctx.input<VolumeU8>("mask");
    auto r = rods_plates_elements(*mask, *ctx.input<VolumeU8>("skeleton"), *ctx.input_data("distance"),
                                  ctx.options<RodsPlatesElementOptions>());
    if (r.segmentation.voxels.empty()) ctx.warn("the skeleton has no voxel inside the mask: no elements");
    ctx.output("elements", std::move(r.elements));
    ctx.output("classes", std::move(r.classes));
    ctx.output("skeleton_elements", std::move(r.skeleton_elements));
    ctx.output("table", std::move(r.table));
    ctx.output("indices", std::move(r.indices));
  }
};
SKEL_REGISTER_MODULE(RodsPlatesElements);

}  // namespace
}  // namespace skel::analysis
