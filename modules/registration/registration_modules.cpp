// Registration modules (thesis §6.2): landmark fit, ICP refinement, applying transforms, and the
// landmark / transform file modules io.read_landmarks, io.write_landmarks, io.read_transform,
// io.write_transform (with `skelflow info` inspectors for .landmarkAscii, .fcsv and .tfm).
#include <sstream>

#include "io/landmark_io.hpp"
#include "registration/names.hpp"
#include "registration/registration.hpp"
#include "skel/module.hpp"
#include "skel/units.hpp"

namespace skel::registration {
namespace {

using namespace registration;

std::vector<std::string> volume_or_graph_types() {
  std::vector<std::string> t = all_volume_types();
  t.emplace_back(type_ids::graph);
  return t;
}

class RegisterLandmarks final : public Module {
public:
  static ModuleSpec spec() {
    return ModuleSpec(names::landmarks, "Fit a rigid, similarity or affine transform to corresponding landmarks")
        .optional_input<LandmarkSet>("landmarks", "landmark object with >= 2 sets (fixed_set and moving_set pick them)")
        .optional_input<LandmarkSet>("fixed", "fixed (reference) landmarks, set 0 used; instead of 'landmarks'")
        .optional_input<LandmarkSet>("moving", "moving landmarks, set 0 used; same count and order as 'fixed'")
        .output<Transform>("transform", "least-squares transform mapping moving coordinates onto fixed ones")
        .output<Table>("table", "residual per landmark (dx, dy, dz, distance) and a last row 'RMS'")
        .param("model", TransformKind::Rigid,
                "rigid: rotation + translation; similarity: + uniform scale; affine: general linear + translation")
        .param<int64_t>("fixed_set", 0, "set of 'landmarks' holding the fixed points").min(0)
        .param<int64_t>("moving_set", 1, "set of 'landmarks' holding the moving points").min(0)
        .details(R"(Closed-form least-squares fit of corresponding landmark pairs, as in thesis §6.2
("Analyzing Architectural Alterations"): the two scans of one specimen are aligned with landmarks
picked by hand. Rigid and similarity use Umeyama's SVD solution (Kabsch with the determinant sign
fix, so the rotation never contains a reflection, even when the landmarks are mirrored: the fit then
simply has large residuals); similarity adds the optimal uniform scale; affine solves the linear
least-squares problem by column-pivoting QR on centred coordinates.

Convention: the transform maps *moving* physical coordinates onto *fixed* ones (p_fixed ≈ T p_moving),
which is what `registration.apply_transform` needs to bring the moving data onto the fixed data.

Errors: neither or both of `landmarks` and `fixed`+`moving`; fewer than 3 pairs (4 for affine);
all points coinciding, collinear points (rigid, similarity) or coplanar points (affine) in either set
(tested on the principal spreads of the centred points, relative tolerance 1e-7).

Table: one row per landmark (landmark name, fixed_x/y/z, moving_x/y/z, dx/dy/dz = T(moving) −
fixed, distance) and a final row "RMS" whose dx/dy/dz hold the per-axis RMS and `distance` the
overall RMS (coordinates 0 there). Memory: O(landmarks).)");
  }
  void run(RunContext& ctx) override {
    const auto model = ctx.param<TransformKind>("model");
    const bool has_set = ctx.has_input("landmarks");
    const bool has_pair = ctx.has_input("fixed") || ctx.has_input("moving");
    if (has_set == has_pair) {
      throw InputError("connect either 'landmarks' (one object with >= 2 sets) or both 'fixed' and 'moving'");
    }
    std::vector<Vec3> fixed, moving;
    std::vector<std::string> names;
    std::string what, unit;
    if (has_set) {
      auto lm = ctx.input<LandmarkSet>("landmarks");
      const int64_t fs = ctx.param<int64_t>("fixed_set"), ms = ctx.param<int64_t>("moving_set");
      if (lm->set_count() < 2) {
        throw InputError("input 'landmarks': has " + std::to_string(lm->set_count()) + " set(s); expected at least 2");
      }
      if (fs >= lm->set_count()) throw InputError("param 'fixed_set': " + std::to_string(fs) + " >= number of sets " + std::to_string(lm->set_count()));
      if (ms >= lm->set_count()) throw InputError("param 'moving_set': " + std::to_string(ms) + " >= number of sets " + std::to_string(lm->set_count()));
      if (fs == ms) throw InputError("param 'moving_set': equals 'fixed_set' (" + std::to_string(fs) + ")");
      fixed = lm->set(fs);
      moving = lm->set(ms);
      names = lm->names;
      unit = lm->unit;
      what = "input 'landmarks'";
    } else {
      auto f = ctx.input<LandmarkSet>("fixed");
      auto m = ctx.input<LandmarkSet>("moving");
      if (f->set_count() < 1) throw InputError("input 'fixed': has no landmark set");
      if (m->set_count() < 1) throw InputError("input 'moving': has no landmark set");
      fixed = f->set(0);
      moving = m->set(0);
      names = f->names;
      units::check_same(f->unit, "input 'fixed'", m->unit, "input 'moving'");
      unit = f->unit;
      what = "inputs 'fixed'/'moving'";
    }
    const LandmarkFit fit = fit_landmarks(fixed, moving, model, what);
    ctx.output("transform", fit.transform);
    ctx.output("table", residual_table(names, fixed, moving, fit, unit));
  }
};
SKEL_REGISTER_MODULE(RegisterLandmarks);

class RefineRegistration final : public Module {
public:
  static ModuleSpec spec() {
    return ModuleSpec(names::refine, "Refine a transform by ICP on skeleton or graph point sets")
        .add_input("fixed", volume_or_graph_types(), "fixed points: non-zero voxels of a (skeleton) volume, or a graph's nodes and edge points", true)
        .add_input("moving", volume_or_graph_types(), "moving points, same kinds as 'fixed'", true)
        .optional_input<Transform>("initial", "start transform moving → fixed (e.g. from registration.landmarks); identity if absent")
        .output<Transform>("transform", "refined transform mapping moving coordinates onto fixed ones")
        .output<Table>("table", "per iteration: pairs used, RMS before and after the update")
        .param("model", &IcpOptions::model, "transform model fitted in every iteration")
        .param("iterations", &IcpOptions::iterations, "maximum number of ICP iterations").range(1, 10000)
        .param("trim_fraction", &IcpOptions::trim_fraction, "fraction of the closest correspondences kept in each iteration (1 = all)").range(0.01, 1.0)
        .param_fn<IcpOptions>("max_distance", 0.0, [](IcpOptions& o, double d) { if (d > 0.0) o.max_distance = d; },
                              "drop correspondences farther apart than this (0 = no limit)").min(0.0).unit(units::length)
        .param("tolerance", &IcpOptions::tolerance, "stop when an iteration lowers the RMS of its pairs by less than this")
        .default_value(1e-6).min(0.0).unit(units::length)
        .param("max_points", &IcpOptions::max_points, "use at most this many moving points (regular subsample; 0 = all)").min(0)
        .details(R"(Point-to-point ICP (Besl & McKay) refining the landmark fit of thesis §6.2 on the
skeletons (or graphs) themselves — Amira stops at the landmark fit. Point sets: for a volume, the
physical centres of its non-zero voxels (a skeleton, a mask); for a SpatialGraph, its node positions
and interior polyline points.

Each iteration maps the moving points by the current transform, finds the nearest fixed point with a
nanoflann k-d tree (built once on the fixed points), drops pairs farther than `max_distance`, keeps
the `trim_fraction` closest pairs (trimmed ICP, robust to structures present in only one scan — a
fracture, removed rods), and refits the model in closed form (same solver as registration.landmarks,
never a reflection for rigid/similarity). It stops after `iterations` or when the RMS of the kept
pairs improves by less than `tolerance`. The table lists, per iteration, the pairs used, rms_before
(under the incoming transform) and rms_after (same pairs, updated transform): the first row's
rms_before is the RMS before refinement, the last row's rms_after the RMS after.

Results are identical for any thread count (each nearest-neighbour query is independent; sorting
and fitting are serial). Memory: 24 bytes per fixed and per moving point plus the k-d tree (~1/16
of that again); a full 1280³ mask would give 2·10⁹ points, so feed skeletons or use `max_points`.)");
  }
  void run(RunContext& ctx) override {
    const auto o = ctx.options<IcpOptions>();
    const auto fixed = points_of(*ctx.input_data("fixed"), "input 'fixed'");
    const auto moving = points_of(*ctx.input_data("moving"), "input 'moving'");
    const std::string unit = ctx.input_data("fixed")->physical_unit();
    units::check_same(unit, "input 'fixed'", ctx.input_data("moving")->physical_unit(), "input 'moving'");
    auto initial = ctx.optional_input<Transform>("initial");
    const IcpResult r = refine_icp(fixed, moving, initial ? *initial : Transform{}, o);
    if (!r.converged) {
      ctx.warn("ICP did not converge within " + std::to_string(o.iterations) + " iterations (tolerance " +
               std::to_string(o.tolerance) + ")");
    }
    ctx.output("transform", r.transform);
    ctx.output("table", icp_table(r, unit));
  }
};
SKEL_REGISTER_MODULE(RefineRegistration);

class ApplyTransform final : public Module {
public:
  static ModuleSpec spec() {
    return ModuleSpec(names::apply_transform, "Apply a transform to a volume, a graph or landmarks")
        .input<Transform>("transform", "transform mapping moving coordinates onto fixed ones")
        .add_input("volume", all_volume_types(), "volume to resample (optional; one of volume, graph, landmarks)", false)
        .optional_input<SpatialGraph>("graph", "graph whose nodes and polyline points are moved")
        .optional_input<LandmarkSet>("landmarks", "landmarks whose points (all sets) are moved")
        .add_input("reference", all_volume_types(), "volume whose grid becomes the output grid (optional)", false)
        .add_output("volume", all_volume_types(), "resampled volume (same voxel type as the input)")
        .output<SpatialGraph>("graph", "transformed graph")
        .output<LandmarkSet>("landmarks", "transformed landmarks")
        .param("interpolation", &ResampleOptions::interpolation,
                "auto: nearest for integer volumes (masks, labels), linear for float volumes")
        .param<bool>("inverse", false, "apply the inverse transform (fixed → moving)")
        .details(R"(Brings the moving data of thesis §6.2 onto the fixed data once the transform is known.

Volume: every output voxel centre p takes the input value at T⁻¹(p) (backward mapping, so there are no
holes). The output grid is the `reference` volume's grid when connected (e.g. the fixed scan),
otherwise the bounding box of the transformed input at the input's spacing. Nearest neighbour keeps
masks and labels exact; linear is trilinear interpolation (integer results rounded and clamped).
Positions outside the input's voxel boxes get 0; within half a voxel of the input border the edge
value is replicated. Parallel over output rows, 64-bit indices, identical results for any thread
count. Memory: the output volume only (its voxel size: 1 byte per voxel for masks), no temporary
per voxel.

Graph: node positions and polyline points are mapped; float attributes whose name contains radius,
thickness, diameter or length are multiplied by the transform's scale |det A|^(1/3) (exact for rigid
and similarity, a mean for affine); labels and other attributes are kept. The graph's source grid
becomes the reference grid, or the transformed bounding box of the old one.

Landmarks: every point of every set is mapped; names are kept.

Exactly one of `volume`, `graph`, `landmarks` must be connected; the output of the same name is
produced. `inverse` applies T⁻¹ instead (a singular affine transform is an error).)");
  }
  void run(RunContext& ctx) override {
    auto t = ctx.input<Transform>("transform");
    const Transform tr = ctx.param<bool>("inverse") ? t->inverse() : *t;
    const int connected = static_cast<int>(ctx.has_input("volume")) + static_cast<int>(ctx.has_input("graph")) +
                          static_cast<int>(ctx.has_input("landmarks"));
    if (connected != 1) {
      throw InputError("connect exactly one of 'volume', 'graph', 'landmarks' (" + std::to_string(connected) + " connected)");
    }
    DataPtr ref = ctx.input_data("reference");
    const char* connected_name = ctx.has_input("volume") ? "volume" : ctx.has_input("graph") ? "graph" : "landmarks";
    if (ref)
      units::check_same(ctx.input_data(connected_name)->physical_unit(), std::string("input '") + connected_name + "'",
                        ref->physical_unit(), "input 'reference'");
    if (ctx.has_input("volume")) {
      const auto o = ctx.options<ResampleOptions>();
      DataPtr in = ctx.input_data("volume");
      const Grid out_grid = ref ? volume_grid(*ref, "input 'reference'") : transformed_bounding_grid(volume_grid(*in, "input 'volume'"), tr);
      DataPtr out = visit_volume(*in, "input 'volume'", [&](const auto& v) -> DataPtr {
        return std::make_shared<std::decay_t<decltype(v)>>(transform_volume(v, tr, out_grid, o));
      });
      ctx.output("volume", out);
    } else if (ctx.has_input("graph")) {
      const Grid g = ref ? volume_grid(*ref, "input 'reference'") : Grid{};
      ctx.output("graph", transform_graph(*ctx.input<SpatialGraph>("graph"), tr, g));
    } else {
      ctx.output("landmarks", transform_landmarks(*ctx.input<LandmarkSet>("landmarks"), tr));
    }
  }
};
SKEL_REGISTER_MODULE(ApplyTransform);

}  // namespace
}  // namespace skel::registration
