// Modules of the thinning family: thinning.doht and thinning.lee94.
#include <string>
#include <vector>

#include "skel/distributed.hpp"
#include "skel/module.hpp"
#include "skel/table.hpp"
#include "thinning/lee94.hpp"
#include "thinning/names.hpp"
#include "thinning/thinning.hpp"
#include "thinning/thinning_blocks.hpp"
#include "thinning/local_topology.hpp"

namespace skel::thinning {
namespace {

class DohtModule final : public Module {
public:
  static ModuleSpec spec() {
    return ModuleSpec(names::doht,
                      "Distance ordered homotopic thinning: homotopic, medial curve skeleton of a binary object")
        .input<VolumeU8>("mask", "binary object (voxel > 0 is object)")
        .input<AnyVolume>("priority",
                          "erosion order, same dims as mask: lower values are eroded first (usually a distance transform)")
        .optional_input<VolumeU8>("locked", "voxels (> 0) that are never removed, e.g. block halos or 2D skeleton parts")
        .output<VolumeU8>("skeleton", "the skeleton: 1 = skeleton voxel, 0 = other; a subset of the mask")
        .output<Table>("table", "one row of statistics: voxels, tests, removals, kept end points, stuck configurations")
        .param("variant", &ThinningOptions::variant,
                "basic: Algorithm 1 (removal in queue order); smooth: Algorithm 2 (directional sub-iterations, sequential rechecking; centred on plates)")
        .param("end_point_length", &ThinningOptions::end_point_length,
                        "l: 0 keeps no end points; l > 0 keeps end points of side branches longer than l voxels (1 keeps noise spurs; 2 and more are robust)")
        .range(0, 1000000)
        .unit("voxels")
        .param("halo", &BlockThinningOptions::halo,
               "under a memory budget only: halo H around each block (sub-blocks overlap by 2·H), at least the "
               "object's largest distance to its border; 0 derives it from the priority's maximum")
        .range(0, 100000)
        .unit("voxels")
        .details(R"(Thesis §2.3.1 (Algorithms 1 and 2, fig. 2.17, end-point importance, "Implementation of
thinning"). Grid point model with **(26, 6) adjacency** (object 26-connected, background 6-connected; not a
parameter). Voxels outside the array are background.

A voxel is deletable if it is simple (Characterization 2: its 26-neighbourhood object voxels form one
26-component and the background voxels of its 18-neighbourhood form one 6-component 6-adjacent to it),
not locked, and not a local end point (exactly one 26-neighbour) of a side branch longer than l
(importance > l). The importance follows the branch: p_0 = the end point, p_{i+1} = the only
neighbour of p_i once p_0..p_i are removed; it is the number of voxels that are local end points in
turn (counted up to l + 1). The end-point rule is applied when a voxel is tested; a kept end point is
not re-examined if its branch later changes beyond its 26-neighbourhood.
The simple test is exact: a bit-parallel evaluation of Characterization 2 on the 27-bit 3x3x3 word (the
26- and 6-component growth are masked shifts; tested against a direct reference implementation on 10^7
random and all structured neighbourhoods), behind a 128 KiB per-run cache of recent answers (simple or
not, and the sub-iteration directions of fig. 2.17); no global table, no warm-up.

Priorities are ranked into integer levels (integers with a small range: value - min; otherwise the rank
among the distinct values of object voxels), and a bucket queue with one FIFO per level gives the
O(n + m) bound of the thesis. Initially every object voxel with a background 6-neighbour is queued in
raster order; after a removal its unqueued 26-neighbours are queued at their own level.

smooth: the lowest non-empty level is taken as a whole; all its voxels are tested "in parallel" (on the
unchanged object; this step uses the threads) and each deletable voxel gets its sub-iteration
directions from the masks of fig. 2.17: for each of the 26 directions v the mask matches if the
neighbours t + w (w a non-zero vector whose non-zero components agree with v: 1 voxel for a face, 3 for
an edge, 7 for a corner direction) are background and t - v is object; v contributes its axis
directions (+x..-z). If no mask matches, the weaker masks "t + v background, t - v object" are used
(one always matches a simple voxel: an antipodally symmetric neighbourhood is never simple). One of the
six directions is chosen cyclically by iteration counter (+z, -z, +y, -y, +x, -x, first one present),
its candidates are re-tested and removed one by one (sequential rechecking), the others are re-queued,
and processing restarts at the lowest level. Results are deterministic and identical for any thread
count.

Locked configurations (fig. 2.23 / 2.10): thinning in the grid point model cannot reduce some
contractible configurations. After thinning, every 26-component of the skeleton that is contractible
(one component, no cavity, no tunnel), has more than one voxel and holds no kept end point and no
locked voxel is counted as stuck; the module warns with the number of such components and voxels
(table columns stuck_components, stuck_voxels). It never loops on them.

Memory: the skeleton output (1 byte per voxel) doubles as the state array; the queue holds 4 bytes
per queued voxel (8 in volumes above 2^32 voxels), 1 more per entry of the level being processed and
of a level holding re-queued smooth-variant candidates (their cached directions): at most the object
voxels, typically the boundary layer (0.3 bytes per voxel on 512³ rods, 0.9 on 512³ plates); levels are ranked from the
priority values on the fly (no per-voxel array). A large bucket grows without holding its old and new
buffers at once (the old pages are given back behind the copy), so the peak stays near the entries
queued. A uint8 priority (distance.chamfer with `narrow`)
costs 1 byte per voxel instead of 2 and gives the same skeleton. The input mask and priority are read only,
except in a headless in-memory run where this node is the mask's last reader: the executor then hands
the mask over and the skeleton is thinned in its buffer (1 byte per voxel less; the same skeleton).

Block-wise under a memory budget (thesis ch. 5.2, Algorithm 5): the mask is copied into the
skeleton (on disk), then every block is thinned as a sub-block (the block plus a halo of H voxels on
each side, clipped to the grid; neighbouring sub-blocks overlap by 2·H) by the same thinning with
extra locks, and the sub-block is written back. Locked are the voxels nearer the sub-block border
than the object border: the (3, 4, 5) chamfer distance to the background inside the sub-block
(computed on the mask; beyond the grid background as in memory, beyond an inner face unknown) is at
least 3·(f - 1), f the distance in voxels to the nearest inner face, so the outermost layer is always
locked. A removed voxel is simple in a sub-block whose border is fixed, hence in the whole volume:
the skeleton is homotopic to the mask (components, cavities, tunnels) for any halo, a subset of it,
and thin. Medialness needs every voxel unlocked in its own block: H >= the object's largest distance
d_max to its border. **halo** = 0 derives H = floor(1.11·d_max) + 1 from the priority's maximum
over the object (one scan; float priorities as distance.euclidean gives them: maximum / smallest
spacing; integer ones as distance.chamfer: maximum / 3; 1.11 > sqrt(11)/3 covers the chamfer's
excess over the Euclidean distance). A block interior with a voxel farther from the object border
than the halo is an error naming this parameter (a priority that is no distance, or a halo set too
small), as is a sub-block that does not fit the budget. A later block can change the state inside an
earlier block's sub-block (a branch retracting across a face, thesis fig. 5.8): such blocks run again
in further passes until a pass changes nothing (progress "thinning k/n blocks", "thinning pass 2
k/n blocks"). Block shape: the execution's block, else the largest cube whose sub-block takes a
quarter of the budget. Differences to the in-memory skeleton: the order within a priority level and
the direction cycle of the smooth variant restart per block, so single voxels near block faces
differ (measured in tests/modules/thinning/thinning_blocks_test.cpp: see docs/architecture.md,
"Out-of-core execution"). The table's tests, removed and sub_iterations are sums over the block
runs, working_bytes the largest run's; priority_levels, kept_end_points, locked_voxels, stuck_* and
interior_voxels are not computed block-wise (-1); the columns blocks, passes, block_runs and halo are
added.
Memory per sub-block voxel: mask and state 1 + 1, priority 4 (float32), locks 1 + 1, padded mask and
uint32 chamfer of the lock test 1 + 4, skeleton 1, priority levels 2 and queue (budgeted) 4: 20
bytes (24 for a float64 priority). With --resume a killed run continues from the finished blocks of
the pass it was in: each block keeps its statistics and the box it changed, so the blocks visited
again and the skeleton are the uninterrupted run's. skelflow-mpi: each pass runs in wavefronts of
blocks whose sub-blocks do not overlap, one past the latest overlapping block before them in the
pass's order, split over the ranks by object voxels: the skeleton and table of one process.)")
        .blockwise(16, 20)
        .in_place("mask", "skeleton");
  }
  void run(RunContext& ctx) override {
    if (const BlockPlan* blocks = ctx.blocks()) {
      run_blocks(ctx, *blocks);
      return;
    }
    DataPtr priority = ctx.input_data("priority");
    auto locked = ctx.optional_input<VolumeU8>("locked");
    // Handed the mask (its last reader, docs/architecture.md): the skeleton is thinned in its buffer.
    std::shared_ptr<VolumeU8> in_place = ctx.take_input<VolumeU8>("mask");
    if (in_place && locked && locked.get() == in_place.get()) in_place.reset();
    ThinningResult r = in_place ? thin_doht_in_place(*in_place, *priority, locked.get(), ctx.options<ThinningOptions>())
                                : thin_doht(*ctx.input<VolumeU8>("mask"), *priority, locked.get(),
                                            ctx.options<ThinningOptions>());
    const ThinningStatistics& s = r.stats;
    if (s.object_voxels == 0) ctx.warn("the mask is empty: the skeleton is empty");
    if (s.stuck_components > 0) {
      ctx.warn(std::to_string(s.stuck_components) + " locked configuration(s) (thesis fig. 2.23) with " +
               std::to_string(s.stuck_voxels) +
               " voxels could not be thinned further in the grid point model; they stay in the skeleton");
    }
    Table t;
    t.add("object_voxels", std::vector<int64_t>{s.object_voxels});
    t.add("skeleton_voxels", std::vector<int64_t>{s.skeleton_voxels});
    t.add("priority_levels", std::vector<int64_t>{s.priority_levels});
    t.add("tests", std::vector<int64_t>{s.tests});
    t.add("removed", std::vector<int64_t>{s.removed});
    t.add("sub_iterations", std::vector<int64_t>{s.sub_iterations});
    t.add("kept_end_points", std::vector<int64_t>{s.kept_end_points});
    t.add("locked_voxels", std::vector<int64_t>{s.locked_voxels});
    t.add("stuck_components", std::vector<int64_t>{s.stuck_components});
    t.add("stuck_voxels", std::vector<int64_t>{s.stuck_voxels});
    t.add("interior_voxels", std::vector<int64_t>{s.interior_voxels});
    t.add("working_bytes", std::vector<int64_t>{static_cast<int64_t>(s.bytes)}, "bytes");
    if (in_place) ctx.output("skeleton", DataPtr(std::move(in_place)));
    else ctx.output("skeleton", std::move(r.skeleton));
    ctx.output("table", std::move(t));
  }

private:
  static void run_blocks(RunContext& ctx, const BlockPlan& blocks) {
    const DistributedStage stage;  // blocks split over the ranks in wavefronts (skelflow-mpi)
    DataPtr mask = ctx.input_data("mask");
    DataPtr priority = ctx.input_data("priority");
    DataPtr locked = ctx.input_data("locked");
    auto out = ctx.scratch_volume("skeleton", type_ids::volume_u8, any_volume_grid(*mask, "input 'mask'"));
    const BlockThinningResult r =
        thin_doht_blocks(*mask, *priority, locked.get(), *out, ctx.options<BlockThinningOptions>(), blocks);
    const ThinningStatistics& s = r.stats;
    if (s.object_voxels == 0) ctx.warn("the mask is empty: the skeleton is empty");
    Table t;
    t.add("object_voxels", std::vector<int64_t>{s.object_voxels});
    t.add("skeleton_voxels", std::vector<int64_t>{s.skeleton_voxels});
    t.add("priority_levels", std::vector<int64_t>{-1});
    t.add("tests", std::vector<int64_t>{s.tests});
    t.add("removed", std::vector<int64_t>{s.removed});
    t.add("sub_iterations", std::vector<int64_t>{s.sub_iterations});
    t.add("kept_end_points", std::vector<int64_t>{-1});
    t.add("locked_voxels", std::vector<int64_t>{-1});
    t.add("stuck_components", std::vector<int64_t>{-1});
    t.add("stuck_voxels", std::vector<int64_t>{-1});
    t.add("interior_voxels", std::vector<int64_t>{-1});
    t.add("working_bytes", std::vector<int64_t>{static_cast<int64_t>(s.bytes)}, "bytes");
    t.add("blocks", std::vector<int64_t>{r.blocks});
    t.add("passes", std::vector<int64_t>{r.passes});
    t.add("block_runs", std::vector<int64_t>{r.block_runs});
    t.add("halo", std::vector<int64_t>{r.halo}, "voxels");
    ctx.output("skeleton", DataPtr(std::move(out)));
    ctx.output("table", std::move(t));
  }
};
SKEL_REGISTER_MODULE(DohtModule);

class Lee94Module final : public Module {
public:
  static ModuleSpec spec() {
    return ModuleSpec(names::lee94,
                      "Lee94 thinning exactly as scikit-image skeletonize_3d / Fiji Skeletonize3D (may lose small components)")
        .input<VolumeU8>("mask", "binary object (voxel > 0 is object)")
        .output<VolumeU8>("skeleton", "the skeleton: 1 = skeleton voxel, 0 = other; a subset of the mask")
        .output<Table>("table",
                       "one row of statistics: voxels, passes, candidates, removed, rejected, vanished components")
        .details(R"(Lee, Kashyap & Chu 1994 (3-D medial surface/axis thinning), computed voxel for voxel as
scikit-image's `skeletonize_3d` (`skeletonize(method='lee')`) and Fiji's Skeletonize3D compute it, so that
published Fiji/AnalyzeSkeleton numbers can be reproduced. Tested identical to scikit-image 0.19 on random
blobs, tubes, plates, cubes, objects touching the border, thin and 2D inputs, and to the skeleton Fiji
computed for scikit-image's 3D blobs test volume. **Use thinning.doht for Skelflow's own analyses.**

Honest difference: this variant is not homotopic in every case. Its sequential re-check only asks whether
the object voxels of the 26-neighbourhood form at most one 26-component, so a voxel that became isolated
is deleted and small components (two or three voxels, short thin pieces) can vanish; neither the Euler
test nor the background connectivity is re-checked. The module warns with the number of vanished
components (table column vanished_components). thinning.doht never loses a component. There is no
end-point parameter: Lee94 keeps every end point (exactly one 26-neighbour) and no medial-surface option.

Algorithm: repeated passes of six sub-iterations, one per border direction in Fiji's order (y-1, y+1,
x+1, x-1, z+1, z-1 for an array indexed [z][y][x], x fastest; only the first four when the volume has one
z-slice, as scikit-image does for 2D images). Each sub-iteration collects, on the unchanged image and in
raster order, the object voxels whose neighbour in that direction is background, that are not end points,
that keep the Euler characteristic (Lee's table 2, delta G_26 over the eight octants) and whose
neighbourhood is one 26-component; then re-checks them one by one in that order and deletes those still
passing the component test. It stops after a pass that deletes nothing. Voxels outside the array are
background (scikit-image pads by one voxel).

Speed: the padded object packed as bits (it stays in cache); border voxels found 64 at a time; the
Euler test as two look-ups in 128 KiB tables (the octants of the lower and of the upper half of the cube);
the component test as bit-parallel dilations; candidate collection on the threads (row chunks concatenated
in raster order, so results are identical for any thread count); after the first pass only voxels near a
deletion made since that direction last looked are examined (flags per row and per group of eight voxels).

Memory: 1 byte per voxel for the skeleton output; working memory 0.15-0.2 bytes per voxel for the padded
object as bits (one 64-bit word per 64 voxels of a row plus one spare word per row) and as much again for
the dirty flags, 1 byte per (y, z) row, and 24 bytes per candidate of one sub-iteration (at most the
object's boundary layer: in total 0.7-1.5 bytes per voxel on the benchmark's rods and plates); the mask is
read only.)");
  }
  void run(RunContext& ctx) override {
    auto mask = ctx.input<VolumeU8>("mask");
    Lee94Result r = thin_lee94(*mask, ctx.options<Lee94Options>());
    const Lee94Statistics& s = r.stats;
    if (s.object_voxels == 0) ctx.warn("the mask is empty: the skeleton is empty");
    if (s.vanished_components > 0) {
      ctx.warn(std::to_string(s.vanished_components) +
               " component(s) of the mask vanished (Lee94's re-check deletes isolated voxels, as scikit-image "
               "and Fiji do); thinning.doht keeps every component");
    }
    Table t;
    t.add("object_voxels", std::vector<int64_t>{s.object_voxels});
    t.add("skeleton_voxels", std::vector<int64_t>{s.skeleton_voxels});
    t.add("passes", std::vector<int64_t>{s.passes});
    t.add("candidates", std::vector<int64_t>{s.candidates});
    t.add("removed", std::vector<int64_t>{s.removed});
    t.add("rejected", std::vector<int64_t>{s.rejected});
    t.add("vanished_components", std::vector<int64_t>{s.vanished_components});
    t.add("scanned_rows", std::vector<int64_t>{s.scanned_rows});
    t.add("working_bytes", std::vector<int64_t>{static_cast<int64_t>(s.bytes)}, "bytes");
    ctx.output("skeleton", std::move(r.skeleton));
    ctx.output("table", std::move(t));
  }
};
SKEL_REGISTER_MODULE(Lee94Module);

}  // namespace
}  // namespace skel::thinning
