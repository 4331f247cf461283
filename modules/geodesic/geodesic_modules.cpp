// Module wrappers of the geodesic family.
#include "geodesic/geodesic.hpp"
#include "geodesic/geodesic_blocks.hpp"
#include "geodesic/names.hpp"
#include "geodesic/surface.hpp"
#include "skel/module.hpp"
#include "skel/table.hpp"


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

Implementation: object voxels are grouped by base point b(p); one search per base point serves all
its voxels. A target at most 4 steps away needs no search where a monotone 6-path (every step towards
it) lies in L: its length is the 1-norm, a lower bound on every path (this settles most targets inside
thick parts; at 512³ plates 61 % of the searches). Searches are A* over L: the key of a voxel v is g(b, v) + h(v), h = the smallest 1-norm
distance to a target not reached yet (a lower bound on any 6-path, and consistent, so a voxel's
distance is final when it is closed). Only voxels with a key <= t are ever queued (threshold mode), and
a search stops as soon as all its targets are reached or no key <= t is left: a target not reached is
>= t. Closed voxels are marked by range encoding (thesis §2.3.2): each search takes the next 16-bit
stamp, so nothing is cleared after a search (the marks once every 65535 searches); in threshold mode
the smallest g each voxel was queued with in the search is kept the same way (search stamp and g in 4
bytes, t < 32767; one bit of g marks the voxel closed, so the stamps are not read then), so a voxel is
queued again only on a shorter path. When a search ends
with targets left, a breadth-first search to t + t/4 from the same base settles, by the triangle
inequality, the far targets of every base point within t/4 of it (a pivot), which saves most long
searches on plates; voxels with a target so proved to saturate need no further search. Landmarks (ALT,
threshold mode, t <= 253): after a search that closed at least 12·t voxels (typically across a plate's
rim) a breadth-first field to radius t is kept from its far target, and the last pivot's distances are
kept as a field too; later searches of the same block bound a target c by max(1-norm, |f(c) - f(v)|)
over the fields holding c (a field clipped at its radius is still a consistent lower bound), so they
close little more than the voxels near their shortest paths, with the same distances. In full mode,
targets in another 6-component of L are known to be infinite without searching. Results, and the
search counts (searches, pivots, saturated targets, visited voxels), are identical for any thread
count: the grid is cut into blocks (64-voxel x-ranges x y-bands x z-slabs, each at least 2·t/4 + 2
voxels thick) run in eight passes by the parity of their (x, y, z) index, so no two workers reach the
same base.

Memory (beyond the input mask and the two outputs; the larger of two phases): 2.1 bits per voxel of the
padded grid (two bitmaps with a 32-bit rank per 512 bits, 1.06 bits each) and 3 bytes per object
voxel (b(p) as an offset) throughout; the
nearest-point transform adds 2 bits per object voxel (this ring and the next), 0.5 bits per voxel of
the padded grid (a rank per word of the object bitmap) and, while it finds the first ring 64 voxels
at a time, 1 bit per voxel of the padded grid; the searches add 3
bytes per object voxel (bucket members as offsets from their base) and about 1.06 per boundary-layer
voxel (bucket sizes; + 4 for L's components in full mode), plus per worker thread 2 (stamp) + 4
(queued g, threshold mode) + 1 (pivot distance; 2 where t + t/4 > 254) + 2 (two landmark fields)
bytes per entry of its scratch: one entry per voxel of a box
around its block (the block plus t + t/4 + 1 on every side, about 2.5 M voxels for t = 40), or one
per boundary-layer voxel where that is fewer (small volumes, full mode; then both bitmaps also keep
a rank per word, +0.5 bits per voxel each), and the queues. In all about 11.3 bytes per object voxel
for the 512³ plates phantom, 17.2 for the sparser mixed one (the boxes' share falls with the size:
11.5 for 1280³ mixed, about 9 for 1280³ plates).

Block-wise under a memory budget (thesis §5.3), threshold mode: each block is computed on the block
with a margin of d_max + t/2 + 3 voxels (d_max: the largest chessboard distance of its voxels to the
background, found in the block and the block read again with a larger margin when needed; blocks
whose margin does not fit the budget are halved), and only its interior is kept. Then every nearest
point and every boundary path shorter than t lies in the block, and every path through the block's
artificial outside is at least t long: importance and surface_skeleton equal the in-memory result.
The table sums the statistics over the blocks with their margins. Memory: 28 bytes per voxel of the
largest block with margin. Full mode has no finite margin: under a budget it runs in memory when the
mask fits the budget at 28 bytes per voxel and is refused otherwise. With --resume a killed
threshold-mode run continues from its finished blocks (the margin guess and statistics are kept
with each block).)")
        .blockwise(16, kBlockBytesPerVoxel);
  }
  void run(RunContext& ctx) override {
    const Options options = ctx.options<Options>();
    if (const BlockPlan* blocks = ctx.blocks()) {
      const DataObject& mask = *ctx.input_data("mask");
      const Grid& g = any_volume_grid(mask, "input 'mask'");
      const uint64_t whole = static_cast<uint64_t>(g.voxel_count()) * static_cast<uint64_t>(kBlockBytesPerVoxel);
      if (options.mode == Mode::Threshold || whole > blocks->memory_budget) {
        auto importance = ctx.scratch_volume("importance", type_ids::volume_f32, g);
        auto surface = ctx.scratch_volume("surface_skeleton", type_ids::volume_u8, g);
        const BlockStatistics bs =
            boundary_distance_blocks(mask, *importance, *surface, options, blocks->block, blocks->memory_budget);
        if (bs.object_voxels == 0) ctx.warn("the mask is empty: importance is 0 everywhere");
        Table t;
        t.add("object_voxels", std::vector<int64_t>{bs.object_voxels});
        t.add("layer_voxels", std::vector<int64_t>{bs.summed.layer_voxels});
        t.add("base_points", std::vector<int64_t>{bs.summed.base_points});
        t.add("searches", std::vector<int64_t>{bs.summed.searches});
        t.add("saturated_by_pivot", std::vector<int64_t>{bs.summed.saturated_by_pivot});
        t.add("visited", std::vector<int64_t>{bs.summed.visited});
        t.add("working_bytes", std::vector<int64_t>{static_cast<int64_t>(bs.largest_block_bytes)}, "bytes");
        t.add("blocks", std::vector<int64_t>{bs.blocks});
        t.add("d_max", std::vector<int64_t>{bs.max_ring}, "voxels");
        t.add("largest_margin", std::vector<int64_t>{bs.largest_margin}, "voxels");
        ctx.output("importance", DataPtr(std::move(importance)));
        ctx.output("surface_skeleton", DataPtr(std::move(surface)));
        ctx.output("table", std::move(t));
        return;
      }
    }
    const DataPtr in = materialize(ctx.input_data("mask"));
    const auto* mask = dynamic_cast<const VolumeU8*>(in.get());
    if (mask == nullptr) throw InputError("input 'mask': expected " + std::string(type_ids::volume_u8) + ", got " + in->type_id());
    Result r = boundary_distance(*mask, options);
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

}  // namespace
}  // namespace skel::geodesic
