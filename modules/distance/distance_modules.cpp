// Modules of the distance family: thin wrappers over distance/distance.hpp.
#include <array>
#include <cmath>
#include <memory>

#include "distance/distance.hpp"
#include "distance/names.hpp"
#include "skel/distributed.hpp"
#include "skel/mask.hpp"
#include "skel/module.hpp"

namespace skel::distance {
namespace {

// The mask input as a VolumeU8 (voxel > 0 is object): uint8 masks are used as they are, other integer
// volumes are converted (1 extra byte per voxel), floating-point ones are an InputError naming the port;
// values other than 0 and 1 (a grey image wired in) give a warning.
std::shared_ptr<const VolumeU8> mask_input(RunContext& ctx, const std::string& port) {
  DataPtr d = ctx.input_data(port);
  if (!d) throw InputError("input '" + port + "' is not connected");
  std::string warning;
  auto m = shared_mask(d, "input '" + port + "'", &warning);
  if (!warning.empty()) ctx.warn(warning);
  return m;
}

const char* kMaskDoc = "object mask: any integer volume, voxel > 0 is object, 0 is background";
// The three isotropic chamfer weights (face, edge, vertex) of the `weights` parameter.
void set_isotropic_weights(ChamferOptions& o, const std::array<int64_t, 3>& w) {
  o.weights = ChamferWeights::isotropic(static_cast<uint32_t>(w[0]), static_cast<uint32_t>(w[1]), static_cast<uint32_t>(w[2]));
}
constexpr std::array<int64_t, 3> kDefaultWeights{3, 4, 5};

const char* kBorderDoc =
    "treat voxels outside the array as object (default: they are background, so the distance never "
    "exceeds the distance to the array's border)";

class ChamferModule final : public Module {
public:
  static ModuleSpec spec() {
    return ModuleSpec(names::chamfer, "Chamfer distance to the background by two raster scans")
        .input<AnyIntegerVolume>("mask", kMaskDoc)
        .add_output("distance", {VoxelTraits<uint8_t>::id, VoxelTraits<uint16_t>::id, VoxelTraits<uint32_t>::id},
                    "chamfer distance in chamfer units (uint16 where every possible value fits, else uint32; uint8 "
                    "with `narrow` where every value of this mask is below 255); 0 on background")
        .param_fn<ChamferOptions>("weights", kDefaultWeights, set_isotropic_weights,
                                  "integer weights (face, edge, vertex) of the 26 neighbour steps on isotropic grids")
        .range(1, 1000000)
        .param("derive_from_spacing", &ChamferOptions::derive_from_spacing,
                     "derive the seven step weights from the voxel spacing (anisotropic grids) instead of `weights`")
        .param("spacing_scale", &ChamferOptions::spacing_scale,
                       "with derive_from_spacing: weight of one step of the smallest spacing (3 gives 3,4,5 on isotropic grids)")
        .range(1, 1000)
        .param("border_is_object", &DistanceOptions::border_is_object, kBorderDoc)
        .param("narrow", &ChamferOptions::narrow,
               "uint8 output when every distance of this mask is below 255 (half the memory, the same values); "
               "else uint16/uint32 as without it")
        .details(R"(Thesis §2.3.1 (Borgefors' chamfer distance, fig. 2.14) and ch. 5.1. A forward raster scan
(z, y, x increasing) propagates d(n) + w from the 13 already visited neighbours (plane z-1, row y-1,
voxel x-1); a backward scan does the mirror. For weights obeying the chamfer-norm conditions
(face <= edge <= vertex, edge <= 2 face, vertex <= face + edge, e.g. 3,4,5) the result equals the
shortest weighted 26-path to the background (tested against Dijkstra).

Anisotropic grids (derive_from_spacing, after Fouard & Malandain): each step weighs
round(spacing_scale * physical step length / smallest spacing); one chamfer unit is then
(smallest spacing / spacing_scale) physical units. With `weights`, one unit is 1/face of a voxel step.

Output type: decided before computing from an upper bound of every possible value on this grid (a path
of face steps to the nearest possible background voxel): uint16 if it is below 65535, else uint32 —
values are never saturated. Voxels outside the array are background by default; with
border_is_object a mask without any background voxel gives the type's maximum (65535 or 2^32-1)
everywhere, above every real distance. An empty mask gives all zeros.

With `narrow` (in memory only; block-wise runs keep uint16/uint32) the scans run in uint8 with
saturation at 255 (SIMD, 16 voxels per step): since min(d + w, 255) is monotone, every value is
min(d, 255) of the uint16 result d. If no voxel is
saturated the uint8 volume is the output (equal values: a priority for thinning.doht gives the same
skeleton with 1 byte per voxel instead of 2); otherwise (a distance of 255 or more: objects thicker
than about 170 voxels with 3,4,5) the uint16/uint32 transform is computed instead, the uint8 pass
wasted.

The raster scans are sequential (each row depends on the previous one); `threads` is not used.
Memory: the output, 2 (or 4) bytes per voxel (1 with `narrow` where it fits), plus a few rows of scratch.

Block-wise under a memory budget (thesis Algorithm 4): blocks with a one-voxel overlap, eight
block-wise scans (2·nz·(2nx-1)·(2ny-1) block visits), bit-identical to the in-memory result for
weights obeying the conditions above. Memory per block: 1 (mask) + 4 (distance) bytes per voxel.
With --resume a killed run continues from the last block visit its journal holds (the start and
both sweeps are journaled per block; the journal is bounded by twice the volume's bytes and
compacted between sweeps, so a sweep past that bound resumes from where the bound was reached).)")
        .blockwise(1, 5);
  }
  void run(RunContext& ctx) override {
    if (const BlockPlan* blocks = ctx.blocks()) {
      // skelflow-mpi: Algorithm 4's scans carry values from block to block in a fixed order, so
      // rank 0 computes them into a volume shared by all ranks while the others wait.
      const DistributedStage stage;
      DataPtr mask = ctx.input_data("mask");
      const auto options = ctx.options<ChamferOptions>();
      const Grid& g = any_volume_grid(*mask, "input 'mask'");
      auto out = ctx.scratch_volume("distance", chamfer_output_type(g, options), g);
      on_root_rank([&] { chamfer_blocks(*mask, *out, options, blocks->block); });
      ctx.output("distance", DataPtr(std::move(out)));
      return;
    }
    auto mask = mask_input(ctx, "mask");
    ctx.output("distance", chamfer(*mask, ctx.options<ChamferOptions>()));
  }
};
SKEL_REGISTER_MODULE(ChamferModule);

class EuclideanModule final : public Module {
public:
  static ModuleSpec spec() {
    return ModuleSpec(names::euclidean, "Exact Euclidean distance to the background, in physical units")
        .input<AnyIntegerVolume>("mask", kMaskDoc)
        .output<VolumeF32>("distance", "Euclidean distance to the nearest background voxel centre (in the spacing unit); 0 on background")
        .param("squared", &EuclideanOptions::squared, "output squared distances (spacing unit²)")
        .param("border_is_object", &DistanceOptions::border_is_object, kBorderDoc)
        .details(R"(Exact Euclidean distance transform (thesis §2.3.1 uses it for exact medialness), separable:
one pass along x (each run of object voxels in a row gets the distance to its two ends), then one
pass along y and one along z computing the lower envelope of parabolas (Felzenszwalb & Huttenlocher)
per column, over the runs of object voxels only. The x and y passes run plane by plane (the y pass
reads the plane the x pass has just written, from cache; blocks of 16 adjacent columns), the z pass
gathers blocks of 64 adjacent columns (256 contiguous bytes per plane) into contiguous buffers and
takes the square root as it writes them back. The x pass flags the 64-voxel row segments that hold
object; the y and z passes neither read nor write back the others (background stays 0), so on a
sparse network most of the output's memory is written once and never read again. Anisotropic
spacing is exact: each axis weighs spacing².
Isotropic grids are computed in integer voxel units (exact for squared distances below 2^24 voxels²,
i.e. grids up to ~2400³), anisotropic ones per line in double precision (float between passes).
Multi-threaded over rows and planes; identical results for any thread count.

Voxels outside the array are background by default (the distance never exceeds the distance to the
array's border); with border_is_object a mask without background gives +inf everywhere. An empty
mask gives all zeros.
Memory: the output, 4 bytes per voxel, plus the segment flags (1 byte per 64 voxels) and per-thread
line buffers (~300 bytes per voxel of one line along z: 64 columns of floats and the envelope's sites).

Block-wise under a memory budget: the same three passes, each over slabs of whole lines along its
axis (the squared distances on disk between passes), bit-identical to the in-memory result. A slab
takes 5 bytes per voxel (mask + float32); its cross-section is chosen so that one slab along the
longest axis fits a quarter of the budget (cut down to whole chunks of the scratch volume), or is
the `block` of the pipeline's `execution:`. When
such a slab holds whole xy-planes, the x and y passes run together on slabs of whole planes (one
read and one write of the float volume less). With --resume a killed run continues from the
finished slabs of the pass it was in.)")
        .blockwise(0, 5);
  }
  void run(RunContext& ctx) override {
    if (const BlockPlan* blocks = ctx.blocks()) {
      const DistributedStage stage;  // slabs split over the ranks (skelflow-mpi)
      DataPtr mask = ctx.input_data("mask");
      const Grid& g = any_volume_grid(*mask, "input 'mask'");
      auto out = ctx.scratch_volume("distance", type_ids::volume_f32, g);
      Dims cross = blocks->block_from_user ? blocks->block : euclidean_cross_section(blocks->memory_budget, g.dims);
      // A chosen cross-section is cut down to whole chunks of the scratch volume: every slab then
      // writes whole chunks (skelflow-mpi writes shared scratch volumes a chunk at a time).
      if (!blocks->block_from_user)
        for (int k = 0; k < 3; ++k)
          if (cross[k] > blocks->chunk[k]) cross[k] -= cross[k] % blocks->chunk[k];
      euclidean_blocks(*mask, *out, ctx.options<EuclideanOptions>(), cross);
      ctx.output("distance", DataPtr(std::move(out)));
      return;
    }
    auto mask = mask_input(ctx, "mask");
    ctx.output("distance", euclidean(*mask, ctx.options<EuclideanOptions>()));
  }
};
SKEL_REGISTER_MODULE(EuclideanModule);

class FeatureTransformModule final : public Module {
public:
  static ModuleSpec spec() {
    return ModuleSpec(names::feature_transform, "Index of the nearest background voxel of every voxel")
        .input<AnyIntegerVolume>("mask", kMaskDoc)
        .add_output("nearest", {VoxelTraits<uint32_t>::id, VoxelTraits<uint64_t>::id},
                    "linear index x + nx*(y + ny*z) of the nearest background voxel (uint32 below 2^32-1 voxels, else uint64); "
                    "the type's maximum where that point lies outside the array")
        .param("method", FeatureMethod::euclidean,
                "euclidean: exact Euclidean nearest voxel; chamfer_bp: b(p) of thesis §2.3.2 propagated along the chamfer raster scans")
        .param_fn<ChamferOptions>("weights", kDefaultWeights, set_isotropic_weights, "chamfer_bp only: weights (face, edge, vertex)")
        .range(1, 1000000)
        .param("border_is_object", &DistanceOptions::border_is_object, kBorderDoc)
        .details(R"(Background voxels get their own index. Voxels outside the array are background by default;
where the nearest one is such an outside point, `nearest` holds the type's maximum (4294967295 or
2^64-1). With border_is_object and no background at all, every voxel gets that value.

euclidean: exact, from the same separable lower-envelope passes as distance.euclidean, carrying the
index of each parabola's site. Ties between equidistant background voxels go to the smallest (z, y, x)
in lexicographic order (outside points counting as coordinate -1 or n), i.e. the smallest linear index
when all candidates are inside. Multi-threaded; identical for any thread count.

chamfer_bp: the nearest background point transform b(p) of thesis §2.3.2 ("the nearest background
voxel by a chamfer path", computed with chamfer propagation in O(n)): during the forward and backward
raster scans of distance.chamfer each voxel takes, with the strictly smaller value d(n) + w, the point
b(n) of the neighbour n it came from. Ties keep the first candidate in mask order (forward: plane z-1
row by row, then row y-1, then x-1; backward: the negated offsets in the same order). Sequential.

Memory: euclidean 4 bytes (index) + 4 bytes (squared distance, freed at the end) per voxel;
chamfer_bp 4 bytes (index) + 2 bytes (chamfer distance) per voxel (8 + 4 above 2^32 voxels).)");
  }
  void run(RunContext& ctx) override {
    auto mask = mask_input(ctx, "mask");
    if (ctx.param<FeatureMethod>("method") == FeatureMethod::chamfer_bp)
      ctx.output("nearest", chamfer_nearest(*mask, ctx.options<ChamferOptions>()).nearest);
    else
      ctx.output("nearest", feature_transform(*mask, ctx.options<DistanceOptions>()));
  }
};
SKEL_REGISTER_MODULE(FeatureTransformModule);

class SeededModule final : public Module {
public:
  static ModuleSpec spec() {
    return ModuleSpec(names::seeded, "Euclidean distance from a seed set (e.g. a skeleton) to every voxel")
        .input<AnyIntegerVolume>("seeds", "seed voxels: any integer volume, voxel > 0 is a seed")
        .optional_input<AnyIntegerVolume>("mask", "optional region (voxel > 0): distances are reported only inside it, 0 outside")
        .output<VolumeF32>("distance", "Euclidean distance to the nearest seed voxel centre (in the spacing unit); 0 on seeds")
        .param("squared", &SeededOptions::squared, "output squared distances (spacing unit²)")
        .details(R"(Used by skeleton comparison (thesis §6.2) and label propagation (fig. 6.14). The exact,
unrestricted Euclidean distance transform of the seed complement: paths are straight lines, not
constrained to the mask; the optional mask only zeroes the output outside it (it must have the
seeds' dimensions). Nothing outside the array is a seed. Without any seed the distance is +inf
everywhere. Same separable algorithm, exactness and threading as distance.euclidean.
Memory: the output, 4 bytes per voxel (plus 1 byte per voxel if seeds or mask are not uint8).)");
  }
  void run(RunContext& ctx) override {
    auto seeds = mask_input(ctx, "seeds");
    VolumeF32 d = seeded(*seeds, ctx.options<SeededOptions>());
    if (ctx.has_input("mask")) {
      auto mask = mask_input(ctx, "mask");
      if (mask->dims() != seeds->dims())
        throw InputError("mask: dimensions differ from the seeds' dimensions");
      const uint8_t* m = mask->data();
      float* p = d.data();
      for (int64_t i = 0, n = d.size(); i < n; ++i)
        if (!m[i]) p[i] = 0.0f;
    }
    ctx.output("distance", std::move(d));
  }
};
SKEL_REGISTER_MODULE(SeededModule);

}  // namespace
}  // namespace skel::distance
