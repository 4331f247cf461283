// Segmentation modules: threshold (manual or Otsu), Gaussian smoothing, median, illumination
// correction along z, connected components, cavity filling, binary morphology.
#include <cmath>
#include <limits>

#include "segmentation/names.hpp"
#include "segmentation/segmentation.hpp"
#include "skel/distributed.hpp"
#include "skel/mask.hpp"
#include "skel/module.hpp"
#include "skel/units.hpp"

namespace skel::segmentation {
namespace {

// The `mask` input as a 0/1 copy; a volume holding other values than 0 and 1 (a grey image wired into
// the port) gives a warning naming the port.
VolumeU8 mask_input(RunContext& ctx) {
  std::string warning;
  VolumeU8 m = to_mask(*ctx.input_data("mask"), "input 'mask'", &warning);
  if (!warning.empty()) ctx.warn(warning);
  return m;
}

class Threshold final : public Module {
public:
  static ModuleSpec spec() {
    return ModuleSpec(names::threshold, "Binary mask of the voxels between two values (or above Otsu's threshold)")
        .add_input("image", all_volume_types(), "scalar image", true)
        .output<VolumeU8>("mask", "1 where low <= value <= high, else 0")
        .output<Table>("table", "the thresholds used and the object fraction")
        .param("method", &ThresholdOptions::method, "manual: use low/high; otsu: low = Otsu's threshold of the image, high = +inf")
        .param("low", &ThresholdOptions::low, "lowest object value (inclusive)")
        .param("high", &ThresholdOptions::high, "highest object value (inclusive); .inf for none")
        .details(R"(Manual: voxels with low <= value <= high become object (1). Otsu: the threshold maximises
the between-class variance of a 256-bin histogram between the image's minimum and maximum (exact bins
for uint8); voxels above it become object. NaN voxels are background. The table reports the
thresholds used and the object fraction, so a pipeline run documents itself. An empty result is
allowed (a warning says so). Memory: 1 byte per voxel (output).

Block-wise under a memory budget: blocks of the image in, blocks of the mask out (on disk); Otsu
first reads the image twice more (value range, histogram). The same mask and table as in memory.
With --resume a killed run reads the range and histogram again and continues from its finished
mask blocks.)")
        .blockwise(0, 9);
  }
  void run(RunContext& ctx) override {
    if (const BlockPlan* blocks = ctx.blocks()) {
      const DistributedStage stage;  // blocks split over the ranks (skelflow-mpi)
      const DataObject& image = *ctx.input_data("image");
      auto mask = ctx.scratch_volume("mask", type_ids::volume_u8, any_volume_grid(image, "input 'image'"));
      const BlockThresholdResult r =
          threshold_blocks(image, *mask, ctx.options<ThresholdOptions>(), blocks->block, ctx.progress());
      if (r.object_voxels == 0) ctx.warn("no voxel lies between the thresholds: the mask is empty");
      const int64_t n = mask->grid().voxel_count();
      Table t;
      t.add("low", std::vector<double>{r.low}).add("high", std::vector<double>{r.high});
      t.add("object_fraction", std::vector<double>{n ? static_cast<double>(r.object_voxels) / static_cast<double>(n) : 0.0});
      ctx.output("mask", DataPtr(std::move(mask)));
      ctx.output("table", std::move(t));
      return;
    }
    ThresholdResult r = threshold(*ctx.input_data("image"), ctx.options<ThresholdOptions>());
    if (r.object_voxels == 0) ctx.warn("no voxel lies between the thresholds: the mask is empty");
    Table t;
    t.add("low", std::vector<double>{r.low}).add("high", std::vector<double>{r.high});
    const int64_t n = r.mask.size();
    t.add("object_fraction", std::vector<double>{n ? static_cast<double>(r.object_voxels) / static_cast<double>(n) : 0.0});
    ctx.output("mask", std::move(r.mask));
    ctx.output("table", std::move(t));
  }
};
SKEL_REGISTER_MODULE(Threshold);

class Gaussian final : public Module {
public:
  static ModuleSpec spec() {
    return ModuleSpec(names::gaussian, "Separable Gaussian smoothing with sigma in physical units")
        .add_input("image", all_volume_types(), "scalar image", true)
        .output<VolumeF32>("image", "smoothed image (float32)")
        .param("sigma", &GaussianOptions::sigma, "standard deviation per axis [x, y, z]; 0 skips an axis")
        .min(0).unit(units::length)
        .param("truncate", &GaussianOptions::truncate, "kernel radius in standard deviations").range(1, 10)
        .details(R"(Thesis §6.1 pre-processing. Three 1D convolutions (x, y, z), each with a normalised
sampled Gaussian of radius max(1, ceil(truncate·sigma/spacing)) voxels; the border value is replicated
(SciPy mode "nearest"). The x pass works on padded rows, the y and z passes combine whole x-rows
(vectorised over x, one slice or one xz-plane copied per task). Parallel over rows/slices; the result
does not depend on the thread count. Memory: 4 bytes per voxel (output, also the work buffer) plus one
slice per thread; none for the output when the input is float32 and this node is its last reader in a
headless in-memory run: the executor then hands the input over and the image is smoothed in place
(the same bytes).

Block-wise under a memory budget: each block is read with the kernel radius around it (halo =
max(1, ceil(truncate·sigma/spacing)) voxels per axis), smoothed as in memory and its interior
written: the same values as in memory. Memory per block with halo: 8 (input) + 4 (float) bytes per
voxel. With --resume a killed run continues from its finished blocks.)")
        .blockwise(8, 12)
        .in_place("image", "image");
  }
  void run(RunContext& ctx) override {
    if (auto image = ctx.take_input<VolumeF32>("image")) {
      gaussian_in_place(*image, ctx.options<GaussianOptions>());
      ctx.output("image", DataPtr(std::move(image)));
      return;
    }
    if (const BlockPlan* blocks = ctx.blocks()) {
      const DistributedStage stage;  // blocks split over the ranks (skelflow-mpi)
      const DataObject& image = *ctx.input_data("image");
      auto out = ctx.scratch_volume("image", type_ids::volume_f32, any_volume_grid(image, "input 'image'"));
      gaussian_blocks(image, *out, ctx.options<GaussianOptions>(), blocks->block);
      ctx.output("image", DataPtr(std::move(out)));
      return;
    }
    ctx.output("image", gaussian(*ctx.input_data("image"), ctx.options<GaussianOptions>()));
  }
};
SKEL_REGISTER_MODULE(Gaussian);

class Components final : public Module {
public:
  static ModuleSpec spec() {
    return ModuleSpec(names::connected_components, "Connected components of a mask, with sizes and bounding boxes")
        .add_input("mask", integer_volume_types(), "binary mask (voxel > 0 is object)", true)
        .output<VolumeU32>("labels", "0 background, 1 the largest kept component, 2 the next, ...")
        .output<VolumeU8>("mask", "the kept components as a 0/1 mask")
        .output<Table>("table", "per component: label, voxels, volume, bounding box, centroid")
        .param("connectivity", &ComponentOptions::connectivity, "6 (faces), 18 (and edges) or 26 (and corners)")
        .param("min_size", &ComponentOptions::min_size, "components with fewer voxels are removed").min(0).unit("voxels")
        .param("min_fraction", &ComponentOptions::min_fraction,
               "components with fewer voxels than this fraction of the largest component are removed (0: off); "
               "removes noise at any volume size without dropping large pieces of a network")
        .range(0.0, 1.0)
        .param("keep_largest", &ComponentOptions::keep_largest,
               "keep only the largest component (a warning names any removed component of at least a tenth of its size)")
        .details(R"(Thesis §6.2. Mask rule: voxel > 0 is object for any integer volume; a float volume is an
error naming the port. Union-find over runs (maximal x-intervals of object voxels): runs are extracted
per row in parallel, each row is merged with its backward neighbour rows (2, 4 or 4 rows for 6/18/26;
diagonal x-neighbours count for 18 on face rows and for 26 on all rows) inside z-slabs in parallel,
then slab borders are merged. Labels are ordered by size, largest first; equal sizes keep the order of
their first voxel in raster order (x fastest), so labels do not depend on the thread count. An empty
mask gives all-zero labels, an empty table and a warning; a full volume gives one component.
Selection: min_size (voxels) and min_fraction (of the largest component's voxels) remove small
components, keep_largest all but the largest. Whenever a removed component holds at least a tenth of
the largest one's voxels, a warning names its size: a vessel network cut in two by the threshold (or
by the volume's border) would otherwise lose half of itself silently. For networks, min_fraction
(e.g. 0.05) removes noise at any volume size and keeps every large piece.
Memory: 4 (labels) + 1 (mask) bytes per voxel of output, plus 16 bytes per run and 8 per row
(typically < 1 byte per voxel; worst case, alternating voxels, 8 per voxel). In a headless in-memory
run the label volume is not made when no node reads `labels`, and the kept mask is written into the
input mask when this node is its last reader (the executor hands it over): then only the runs.

Block-wise under a memory budget: two passes over the blocks. Pass 1 finds the components of each
block (pieces) and keeps in memory their statistics and their runs on the block's six faces; pieces
that touch across block faces, edges and corners are then united in memory. Pass 2 reads each block
again, finds the same pieces and writes the final labels and mask: the same labels, mask and table as
in memory, and no scratch volume besides the two outputs. Memory per block: 1 (mask) + 4 + 1
(outputs) bytes per voxel plus its runs; for the whole volume ~100 bytes per piece and 24 per piece
run on a block face. With --resume a killed run continues from the finished blocks of the pass it was
in (each block's pieces are kept with it).)")
        .blockwise(0, 8)
        .in_place("mask", "mask");
  }
  void run(RunContext& ctx) override {
    if (const BlockPlan* blocks = ctx.blocks()) {
      const DistributedStage stage;  // blocks split over the ranks (skelflow-mpi)
      const DataObject& mask = *ctx.input_data("mask");
      const Grid& g = any_volume_grid(mask, "input 'mask'");
      auto labels = ctx.scratch_volume("labels", type_ids::volume_u32, g);
      auto kept = ctx.scratch_volume("mask", type_ids::volume_u8, g);
      auto r = connected_components_blocks(mask, *labels, *kept, ctx.options<ComponentOptions>(), blocks->block);
      if (r.count == 0) ctx.warn("no component left (empty mask or min_size too large)");
      if (!r.warning.empty()) ctx.warn(r.warning);
      ctx.output("labels", DataPtr(std::move(labels)));
      ctx.output("mask", DataPtr(std::move(kept)));
      ctx.output("table", std::move(r.table));
      return;
    }
    ComponentOptions o = ctx.options<ComponentOptions>();
    o.labels = ctx.output_wanted("labels");
    std::string not_binary;
    ComponentsResult r;
    if (std::shared_ptr<VolumeU8> taken = ctx.take_input<VolumeU8>("mask")) {  // kept components written into it
      (void)shared_mask(taken, "input 'mask'", &not_binary);
      if (!not_binary.empty()) ctx.warn(not_binary);
      r = connected_components_in_place(*taken, o);
      ctx.output("mask", DataPtr(std::move(taken)));
    } else {
      auto m = shared_mask(ctx.input_data("mask"), "input 'mask'", &not_binary);
      if (!not_binary.empty()) ctx.warn(not_binary);
      r = connected_components(*m, o);
      ctx.output("mask", std::move(r.mask));
    }
    if (r.count == 0) ctx.warn("no component left (empty mask or min_size too large)");
    if (!r.warning.empty()) ctx.warn(r.warning);
    if (o.labels) ctx.output("labels", std::move(r.labels));
    ctx.output("table", std::move(r.table));
  }
};
SKEL_REGISTER_MODULE(Components);

class Median final : public Module {
public:
  static ModuleSpec spec() {
    return ModuleSpec(names::median, "Median filter over a cube of (2·radius+1)³ voxels")
        .add_input("image", all_volume_types(), "scalar image", true)
        .add_output("image", all_volume_types(), "filtered image (same type as the input)")
        .param("radius", &MedianOptions::radius, "half width of the cube; 1 = 3×3×3").range(0, 10).unit("voxels")
        .details(R"(Thesis §6.1: removes salt-and-pepper noise before smoothing. Each voxel takes the median
of the (2r+1)³ cube around it; voxels outside the volume take the value of the nearest border voxel
(SciPy mode "nearest"). radius 1: a forgetful-selection network (keep 15 of the 27 values, drop the
minimum and maximum, add the next; about 400 min/max per voxel) vectorised over 64 voxels of a row;
radius > 1: nth_element per voxel (O(r³) per voxel, slow for large radii). radius 0 copies. Parallel
over rows; identical for any thread count. Memory: output of the input's type plus 9 padded rows per
thread.

Block-wise under a memory budget: each block is read with `radius` voxels around it, filtered as in
memory and its interior written: the same values as in memory. Memory per block with halo: twice
the input's bytes per voxel. With --resume a killed run continues from its finished blocks.)")
        .blockwise(1, 16);
  }
  void run(RunContext& ctx) override {
    if (const BlockPlan* blocks = ctx.blocks()) {
      const DistributedStage stage;  // blocks split over the ranks (skelflow-mpi)
      const DataObject& image = *ctx.input_data("image");
      auto out = ctx.scratch_volume("image", image.type_id(), any_volume_grid(image, "input 'image'"));
      median_blocks(image, *out, ctx.options<MedianOptions>(), blocks->block);
      ctx.output("image", DataPtr(std::move(out)));
      return;
    }
    ctx.output("image", median(*ctx.input_data("image"), ctx.options<MedianOptions>()));
  }
};
SKEL_REGISTER_MODULE(Median);

class IlluminationZ final : public Module {
public:
  static ModuleSpec spec() {
    return ModuleSpec(names::illumination_z, "Correct the loss of brightness with depth by scaling each z-slice")
        .add_input("image", all_volume_types(), "scalar image (a confocal stack, z = depth)", true)
        .output<VolumeF32>("image", "corrected image (float32)")
        .output<Table>("table", "per slice: z, statistic m(z) (fitted mode), factor f(z)")
        .param("mode", &IlluminationOptions::mode, "fit: factor from a line fitted to slice brightness; given: factor = intercept + slope·z")
        .param("percentile", &IlluminationOptions::percentile, "fit: fraction of brightest voxels per slice whose mean is the slice brightness").range(1e-6, 1)
        .param("slope", &IlluminationOptions::slope, "given: factor change per slice (z = slice index)")
        .param("intercept", &IlluminationOptions::intercept, "given: factor of slice 0")
        .details(R"(Thesis §6.1: "the drop of illumination in deeper slices is corrected for by scaling image
values with a linear function in z". Fit mode: m(z) = mean of the brightest `percentile` fraction of
slice z (at least one voxel); a least-squares line L(z) = a + b·z through (z, m(z)); each slice is
multiplied by L(0)/L(z), which makes the fitted brightness constant (an error if L(z) <= 0 anywhere).
Given mode: slice z is multiplied by intercept + slope·z. Slice statistics use nth_element per slice
(parallel over slices). Memory: 4 bytes per voxel (output) plus one slice of doubles per thread.

Block-wise under a memory budget: fit mode first reads slabs of whole slices (as many as a quarter of
the budget holds at the input's bytes plus 8 per voxel; at least one) for the slice statistics, then
every block (halo 0) is scaled by its slices' factors into an on-disk float32 volume: the same
statistics, factors and voxels as in memory. Memory per block: input bytes + 4 per voxel; per slab:
input bytes per voxel plus one slice of doubles per thread. With --resume a killed run computes the
slice statistics again and continues from its finished blocks.)")
        .blockwise(0, 12);
  }
  void run(RunContext& ctx) override {
    const auto o = ctx.options<IlluminationOptions>();
    const bool fit = o.mode == IlluminationMode::fit;
    IlluminationResult r;
    DataPtr image;
    if (const BlockPlan* blocks = ctx.blocks()) {
      const DataObject& in = *ctx.input_data("image");
      const Grid& g = any_volume_grid(in, "input 'image'");
      auto out = ctx.scratch_volume("image", type_ids::volume_f32, g);
      const uint64_t slice = static_cast<uint64_t>(g.dims[0] * g.dims[1]) * static_cast<uint64_t>(voxel_bytes(in.type_id()) + 8);
      const auto slab = static_cast<int64_t>(std::max<uint64_t>(1, blocks->memory_budget / 4 / std::max<uint64_t>(slice, 1)));
      r = illumination_z_blocks(in, *out, o, blocks->block, slab);
      image = std::move(out);
    } else {
      r = illumination_z(*ctx.input_data("image"), o);
      image = std::make_shared<VolumeF32>(std::move(r.image));
    }
    Table t;
    std::vector<int64_t> z(r.factor.size());
    for (size_t i = 0; i < z.size(); ++i) z[i] = static_cast<int64_t>(i);
    t.add("z", z);
    if (fit) t.add("statistic", r.slice_statistic);
    t.add("factor", r.factor);
    if (fit) ctx.warn("fitted brightness " + std::to_string(r.fit_intercept) + " + " + std::to_string(r.fit_slope) + "·z");
    ctx.output("image", std::move(image));
    ctx.output("table", std::move(t));
  }
};
SKEL_REGISTER_MODULE(IlluminationZ);

class Morphology final : public Module {
public:
  static ModuleSpec spec() {
    return ModuleSpec(names::morphology, "Binary erosion, dilation, opening or closing with a ball")
        .add_input("mask", integer_volume_types(), "binary mask (voxel > 0 is object)", true)
        .output<VolumeU8>("mask", "the result as a 0/1 mask")
        .param("operation", &MorphologyOptions::op, "open = erode then dilate; close = dilate then erode")
        .param("radius", &MorphologyOptions::radius, "ball radius; the ball is every offset with dx²+dy²+dz² <= radius²").min(0).unit("voxels")
        .details(R"(Mask rule: voxel > 0 is object for any integer volume; a float volume is an error naming
the port. The structuring element is the exact digital ball of the given radius in voxel units (spacing
is ignored). Dilation: object where the squared Euclidean distance to the nearest object voxel is
<= radius²; erosion: object voxels whose squared distance to the nearest background voxel is > radius²,
voxels outside the volume counting as background for erosion and as nothing for dilation (SciPy's
border_value = 0). Exact separable squared distance transforms (integer lower envelopes), so the cost
does not grow with the radius. Empty mask: dilation/closing/erosion/opening give an empty mask;
full volume: dilation gives a full volume, erosion keeps voxels farther than radius from the border.
Memory: 4 bytes per voxel (squared distances) + 1 (output); open/close hold one intermediate mask more.)");
  }
  void run(RunContext& ctx) override {
    ctx.output("mask", morphology(mask_input(ctx), ctx.options<MorphologyOptions>()));
  }
};
SKEL_REGISTER_MODULE(Morphology);

class FillCavities final : public Module {
public:
  static ModuleSpec spec() {
    return ModuleSpec(names::fill_cavities, "Fill enclosed background (cavities) of a mask")
        .add_input("mask", integer_volume_types(), "binary mask (voxel > 0 is object)", true)
        .output<VolumeU8>("mask", "the mask with every cavity filled")
        .details(R"(Thesis §6.2 (bone pre-processing): background components that are not 6-connected to
the border of the volume become object, so the object has no cavities (the outside counts as connected
to the border). Mask rule: voxel > 0 is object for any integer volume; a float volume is an error
naming the port. Empty mask: unchanged (all background touches the border); full volume: unchanged.
Union-find over the x-runs of the background (6-connected), on the node's threads; memory: the output
plus about 24 bytes per background run.

Block-wise under a memory budget: background components per block, united across block faces in
memory (their runs on the block faces are kept), then each block is read again and its cavities
filled; the same mask as in memory, no scratch volume besides the output. Memory per block: 1 (mask)
+ 1 (output) bytes per voxel plus its runs; ~100 bytes per background piece and 24 per piece run on
a block face. With --resume a killed run continues from the finished blocks of the pass it was in.
skelflow-mpi: both passes are split over the ranks (the pieces exchanged, as in connected_components).)")
        .blockwise(0, 4);
  }
  void run(RunContext& ctx) override {
    if (const BlockPlan* blocks = ctx.blocks()) {
      const DistributedStage stage;  // blocks split over the ranks (skelflow-mpi)
      const DataObject& mask = *ctx.input_data("mask");
      const Grid& g = any_volume_grid(mask, "input 'mask'");
      auto out = ctx.scratch_volume("mask", type_ids::volume_u8, g);
      const int64_t filled = segmentation::fill_cavities_blocks(mask, *out, blocks->block, ctx.threads(), ctx.progress());
      if (filled) ctx.warn("filled " + std::to_string(filled) + " cavity voxels");
      ctx.output("mask", DataPtr(std::move(out)));
      return;
    }
    int64_t filled = 0;
    VolumeU8 m = segmentation::fill_cavities(mask_input(ctx), &filled,
                                              ctx.threads());
    if (filled) ctx.warn("filled " + std::to_string(filled) + " cavity voxels");
    ctx.output("mask", std::move(m));
  }
};
SKEL_REGISTER_MODULE(FillCavities);

}  // namespace
}  // namespace skel::segmentation
