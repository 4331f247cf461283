// Registration modules (thesis §6.2): landmark fit, ICP refinement, applying transforms, and the
// landmark / transform file modules io.read_landmarks, io.write_landmarks, io.read_transform,
// io.write_transform (with `skelflow info` inspectors for .landmarkAscii, .fcsv and .tfm).
#include <fstream>
#include <sstream>

#include "io/landmark_io.hpp"
#include "io/volume_format.hpp"
#include "registration/names.hpp"
#include "registration/registration.hpp"
#include "registration/stitch.hpp"
#include "skel/out_of_core.hpp"
#include "skel/module.hpp"
#include "skel/text.hpp"
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

enum class PositionUnit { physical, voxels };
constexpr auto enum_names(PositionUnit) {
  return std::to_array<EnumName<PositionUnit>>({{PositionUnit::physical, "physical"}, {PositionUnit::voxels, "voxels"}});
}

std::string read_text_file(const std::filesystem::path& path) {
  std::ifstream in(path, std::ios::binary);
  std::error_code ec;
  if (!in) throw InputError(path.string() + (std::filesystem::exists(path, ec) ? ": cannot open the file for reading" : ": file not found"));
  std::ostringstream s;
  s << in.rdbuf();
  return s.str();
}

// The tiles of a tile list: headers read (not the voxels), positions converted to voxels, box readers
// through the volume format registry. Errors name the list's line and the tile.
std::vector<StitchTile> load_tile_list(const std::filesystem::path& list, PositionUnit unit) {
  const std::filesystem::path shown = list.filename();
  std::vector<StitchTile> tiles;
  for (const auto& e : parse_tile_list(read_text_file(list), list)) {
    StitchTile t;
    t.name = e.name;
    t.where = shown.string() + ":" + std::to_string(e.line);
    io::VolumeHeader h;
    try {
      h = io::read_volume_header(e.file);
    } catch (const InputError& err) {
      throw InputError(t.where + ": tile '" + e.name + "': " + err.what());
    }
    t.grid = h.grid;
    t.type_id = io::volume_type_for_dtype(h.dtype);
    for (size_t k = 0; k < 3; ++k) t.position[k] = unit == PositionUnit::voxels ? e.position[k] : e.position[k] / h.grid.spacing[k];
    t.read_box = [file = e.file](const Dims& begin, const Dims& size) {
      return io::read_any_volume_box(file, io::VolumeReadOptions{}, begin, size);
    };
    tiles.push_back(std::move(t));
  }
  return tiles;
}

class StitchTiles final : public Module {
public:
  static ModuleSpec spec() {
    return ModuleSpec(names::stitch_tiles, "Align overlapping tiles by cross-correlation and merge them into one volume")
        .path("tile_list", "", PathRole::Input,
              "tile list (CSV): one line file,x,y,z per tile; files relative to the list's folder")
        .extensions({".csv", ".txt"}, "tile list")
        .add_output("volume", all_volume_types(), "the merged volume (voxel type, spacing and unit of the tiles)")
        .output<Table>("tiles", "per tile: nominal and refined position, placement in the merged volume, pairs used")
        .output<Table>("pairs", "per overlapping pair: NCC peak, measured offset, residual after the global fit, status")
        .param("position_unit", PositionUnit::physical,
               "physical: the list's x, y, z are stage positions in the tiles' unit; voxels: in voxels")
        .param("search_radius", &StitchOptions::search_radius,
               "offsets searched around the nominal offset of each pair, per axis (cover twice the stage error)")
        .range(0, 256).unit("voxels")
        .param("min_correlation", &StitchOptions::min_correlation,
               "pairs whose NCC peak is lower are dropped from the global fit (and listed as low_correlation)")
        .range(-1.0, 1.0)
        .param("min_overlap", &StitchOptions::min_overlap,
               "nominal overlap along every axis that makes two tiles a pair").min(2).unit("voxels")
        .param("fixed_tile", &StitchOptions::fixed_tile, "tile (0-based, in the order of the list) that keeps its nominal position").min(0)
        .output_type_from("volume", [](const OutputTypeQuery& q) {
          const auto list = q.input_path("tile_list");
          const auto entries = parse_tile_list(read_text_file(list), list);
          const auto& e = entries.front();
          io::VolumeHeader h;
          try {
            h = io::read_volume_header(e.file);
          } catch (const InputError& err) {
            throw InputError(list.filename().string() + ":" + std::to_string(e.line) + ": tile '" + e.name + "': " + err.what());
          }
          return DeducedOutput{{io::volume_type_for_dtype(h.dtype)}, "tile '" + e.name + "' holds " + h.dtype + " voxels"};
        })
        .details(R"(Stitching of overlapping tiles as for the confocal vessel mosaics of thesis §6.1: the
imprecise stage positions of the blocks are corrected by searching for the shift that maximises the
correlation of the grey values in their overlap, and the blocks are sampled onto one large grid.

Tile list (CSV, `.csv` or `.txt`): one line `file,x,y,z` per tile; `file` relative to the list's
folder (or absolute), any volume format the registry reads (a TIFF stack, a folder of TIFF slices, a
`.zarr` folder, NRRD, HDF5, ...); x, y, z the stage position of the tile's voxel (0, 0, 0) in the
tiles' unit (`position_unit: physical`, divided by the spacing) or in voxels (`position_unit:
voxels`). An optional header line (`file,x,y,z`), blank lines and `#` comments are skipped; fields
may be quoted. All tiles need one voxel type, one spacing and one unit; every tile must overlap
another by `min_overlap` voxels along every axis. Errors name the list's line and the tile.

1. Pairs: tiles whose nominal boxes overlap by at least `min_overlap` voxels along every axis.
2. Pairwise alignment: normalised cross-correlation (NCC) of the two tiles over their overlap, for
   every offset within ±`search_radius` voxels (per axis) of the nominal one, first with the overlap
   sampled every 2 or 4 voxels per axis (so that at least 4096 voxels are compared), then the 8 best
   offsets and hill climbing over the 26 neighbours at full resolution; the sub-voxel part is the
   vertex of a parabola through the peak and its two neighbours along each axis. The fine texture is
   kept at every stage, so the position along an elongated structure (a vessel crossing the
   overlap) is still found. Only the overlaps (plus the search radius) are read. Cost per pair:
   (2·search_radius + 1)³ NCC evaluations on the sampled overlap. Progress: "pair k/n".
3. Pairs whose peak NCC is below `min_correlation` are dropped (status low_correlation in `pairs`;
   a warning names them).
4. Global refinement: positions P minimising Σ ncc · |P_b − P_a − measured_ab|² over the kept pairs
   (sparse normal equations, Eigen's LDLT), `fixed_tile` kept at its nominal position (and the first
   tile of any group of tiles not connected to it by kept pairs; tiles without any kept pair keep
   their nominal positions, with a warning). Inconsistent pairwise errors are averaged instead of
   accumulated along a chain.
5. Merge: tiles placed at their refined positions rounded to whole voxels (no interpolation of
   voxel values, so masks and labels stay exact; the sub-voxel positions are in `tiles`), each
   voxel the weighted mean of the tiles covering it with weights Π min(i + 1, n − i) falling
   linearly towards each tile's borders (linear blending), rounded for integer types; 0 where no
   tile lies. The merged grid has the tiles' spacing and unit, and its origin at the lowest position.

Memory: alignment holds the overlap regions of one pair as float32 (4 bytes per voxel, plus 1/7 for
the coarse levels). The merge works in blocks: 16 bytes per voxel of a block (double sum and
weight) plus the tile boxes read for it (their voxel size) and the output. In memory the output is
the merged volume (its voxel size in bytes per voxel; blocks are z-slabs of 16 M voxels). Under a
memory budget (`--memory-budget`) a merged volume larger than the budget is written block by block
onto disk (a chunked scratch volume), never held in memory; each block reads only the tile boxes it
touches (formats with box reading, e.g. TIFF, HDF5, Zarr, read only those; the others read the tile
file and cut).

Tables: `tiles` (tile, file, nominal_x/y/z and refined x/y/z in the unit, placed_x/y/z in voxels of
the merged volume, pairs used); `pairs` (tile_a, tile_b, file_a, file_b, overlap_voxels, correlation,
dx/dy/dz = measured offset of b relative to a in the unit, residual after the global fit, status).)")
        .blockwise(0, 24);
  }
  void run(RunContext& ctx) override {
    auto o = ctx.options<StitchOptions>();
    const auto tiles = load_tile_list(ctx.input_path("tile_list"), ctx.param<PositionUnit>("position_unit"));
    const StitchLayout layout = align_tiles(tiles, o);
    std::string low;
    for (const auto& p : layout.pairs)
      if (p.status == PairStatus::low_correlation)
        low += (low.empty() ? "" : ", ") + tiles[static_cast<size_t>(p.a)].name + " / " + tiles[static_cast<size_t>(p.b)].name +
               " (" + text::format_double(p.correlation, 3) + ")";
    if (!low.empty()) ctx.warn("pairs dropped for a correlation below min_correlation: " + low);
    std::string lonely;
    for (const int64_t i : layout.unconnected) lonely += (lonely.empty() ? "" : ", ") + tiles[static_cast<size_t>(i)].where + " " + tiles[static_cast<size_t>(i)].name;
    if (!lonely.empty()) ctx.warn("tiles without any kept pair keep their nominal positions: " + lonely);
    const uint64_t bytes = static_cast<uint64_t>(layout.grid.voxel_count()) * static_cast<uint64_t>(voxel_bytes(layout.type_id));
    const BlockPlan* blocks = ctx.blocks();
    if (blocks && bytes > blocks->memory_budget) {
      auto out = ctx.scratch_volume("volume", layout.type_id, layout.grid);
      merge_tiles_into(tiles, layout, *out, blocks->block, o);
      ctx.output("volume", DataPtr(std::move(out)));
    } else {
      ctx.output("volume", merge_tiles_in_memory(tiles, layout, o));
    }
    ctx.output("tiles", tile_table(tiles, layout));
    ctx.output("pairs", pair_table(tiles, layout));
  }
};
SKEL_REGISTER_MODULE(StitchTiles);

}  // namespace
}  // namespace skel::registration
