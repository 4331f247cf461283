// Block-wise distance ordered homotopic thinning (thesis ch. 5.2, Algorithm 5). One thinning
// implementation: each sub-block is thinned by thin_doht with a lock mask; this file only cuts the
// volume into sub-blocks, computes the locks and schedules the passes.
#include "thinning/thinning_blocks.hpp"

#include <algorithm>
#include <cmath>
#include <cstring>
#include <limits>
#include <optional>
#include <string>
#include <vector>

#include "distance/distance.hpp"
#include "skel/block_journal.hpp"
#include "skel/distributed.hpp"

namespace skel::thinning {
namespace {

std::string dims_text(const Dims& d) {
  return std::to_string(d[0]) + "x" + std::to_string(d[1]) + "x" + std::to_string(d[2]);
}

// 0/1 copy of a mask block (any value > 0 is object).
VolumeU8 binary(VolumeU8 v) {
  for (auto& x : v) x = x ? 1 : 0;
  return v;
}

// Locks of one sub-block [ob, ob + os) of a grid of `gdims`, from the original mask `orig` of the
// sub-block: object voxels whose (3, 4, 5) chamfer distance to the object border inside the
// sub-block is at least 3·(f − 1), f the distance in voxels to the nearest inner face (a face that
// is not on the grid's border: the outermost layer has f = 1 and is always locked). Beyond inner
// faces the object is unknown (object); beyond the grid's border it is background, as in memory.
// `interior_begin/size`: the block interior (global); returns the number of object voxels in it
// that are locked (their object border may be beyond the halo).
int64_t border_locks(const VolumeU8& orig, const Dims& ob, const Dims& gdims, const Dims& interior_begin,
                     const Dims& interior_size, int threads, VolumeU8& locks) {
  const Dims os = orig.dims();
  bool lo_inner[3], hi_inner[3];
  for (int a = 0; a < 3; ++a) {
    lo_inner[a] = ob[a] > 0;
    hi_inner[a] = ob[a] + os[a] < gdims[a];
  }
  const bool any_inner = lo_inner[0] || lo_inner[1] || lo_inner[2] || hi_inner[0] || hi_inner[1] || hi_inner[2];
  if (!any_inner) return 0;  // the whole grid: no locks
  // The sub-block padded by one voxel: inside the grid (beyond an inner face) object, outside the
  // grid background; beyond the padding object (border_is_object), never nearer than the padding.
  // Only the box of the object voxels grown by one is computed: for an object voxel p, any background
  // voxel outside that box has one inside it, outside the object's box along the same axis and inside
  // the sub-block, that is not farther from p in the chamfer norm.
  Dims lo{os[0], os[1], os[2]}, hi{-1, -1, -1};
  for (int64_t z = 0; z < os[2]; ++z)
    for (int64_t y = 0; y < os[1]; ++y) {
      const uint8_t* row = &orig(0, y, z);
      int64_t x0 = 0;
      while (x0 < os[0] && !row[x0]) ++x0;
      if (x0 == os[0]) continue;
      int64_t x1 = os[0] - 1;
      while (!row[x1]) --x1;
      lo = {std::min(lo[0], x0), std::min(lo[1], y), std::min(lo[2], z)};
      hi = {std::max(hi[0], x1), std::max(hi[1], y), std::max(hi[2], z)};
    }
  if (hi[0] < 0) return 0;  // no object
  // Q in padded coordinates (sub-block voxel s is padded s + 1): [lo, hi + 2].
  const Dims qd{hi[0] - lo[0] + 3, hi[1] - lo[1] + 3, hi[2] - lo[2] + 3};
  VolumeU8 padded(qd, 0);
  for (int64_t qz = 0; qz < qd[2]; ++qz)
    for (int64_t qy = 0; qy < qd[1]; ++qy) {
      const int64_t py = qy + lo[1], pz = qz + lo[2];
      const bool in_yz = py >= 1 && py <= os[1] && pz >= 1 && pz <= os[2];
      const int64_t gy = ob[1] + py - 1, gz = ob[2] + pz - 1;
      const bool grid_yz = gy >= 0 && gy < gdims[1] && gz >= 0 && gz < gdims[2];
      if (!grid_yz) continue;  // outside the grid: background
      uint8_t* row = &padded(0, qy, qz);
      for (int64_t qx = 0; qx < qd[0]; ++qx) {
        const int64_t px = qx + lo[0];
        if (px == 0) row[qx] = lo_inner[0] ? 1 : 0;
        else if (px == os[0] + 1) row[qx] = hi_inner[0] ? 1 : 0;
        else row[qx] = in_yz ? orig(px - 1, py - 1, pz - 1) : 1;
      }
    }
  distance::ChamferOptions co;
  co.border_is_object = true;
  co.threads = threads;
  const VolumeU32 d = distance::chamfer_as<uint32_t>(padded, co);
  constexpr int64_t kFar = std::numeric_limits<int64_t>::max() / 8;
  int64_t unreached = 0;
  for (int64_t z = 0; z < os[2]; ++z)
    for (int64_t y = 0; y < os[1]; ++y)
      for (int64_t x = 0; x < os[0]; ++x) {
        if (!orig(x, y, z)) continue;
        const int64_t p[3] = {x, y, z};
        int64_t f = kFar;
        for (int a = 0; a < 3; ++a) {
          if (lo_inner[a]) f = std::min(f, p[a] + 1);
          if (hi_inner[a]) f = std::min(f, os[a] - p[a]);
        }
        bool interior = true;
        for (int a = 0; a < 3; ++a) {
          const int64_t gpos = ob[a] + p[a];
          interior = interior && gpos >= interior_begin[a] && gpos < interior_begin[a] + interior_size[a];
        }
        const int64_t c = d(x + 1 - lo[0], y + 1 - lo[1], z + 1 - lo[2]);
        if (c < 3 * (f - 1)) continue;
        locks(x, y, z) = 1;
        unreached += interior;
      }
  return unreached;
}

// Index of block (bx, by, bz) in z, y, x order.
int64_t block_index(const Dims& count, int64_t bx, int64_t by, int64_t bz) { return bx + count[0] * (by + count[1] * bz); }

}  // namespace

int64_t halo_for_distance(double d_max) {
  if (!(d_max >= 0) || !std::isfinite(d_max)) return 1;
  return static_cast<int64_t>(std::floor(1.11 * d_max)) + 1;
}

int64_t block_thinning_bytes_per_voxel(int64_t priority_voxel_bytes) {
  return 1 + 1 + priority_voxel_bytes + 1 + 1 + 1 + 4 + 1 + 2 + 4;
}

double priority_max_distance(const DataObject& mask, const DataObject& priority, const Dims& block) {
  const Grid& g = any_volume_grid(mask, "input 'mask'");
  const BlockLayout layout(g.dims, block);
  double best = 0;
  const bool is_float = priority.type_id() == type_ids::volume_f32 || priority.type_id() == type_ids::volume_f64;
  visit_voxel_type(priority.type_id(), "input 'priority'", [&](auto tag) {
    using T = decltype(tag);
    auto scan = [&](const Block& b) {
      const VolumeU8 m = read_block<uint8_t>(mask, b.begin, b.size, "input 'mask'");
      const Volume<T> p = read_block<T>(priority, b.begin, b.size, "input 'priority'");
      for (int64_t i = 0; i < m.size(); ++i)
        if (m[i]) {
          const double v = static_cast<double>(p[i]);
          if (std::isnan(v)) throw InputError("priority: NaN at an object voxel; expected finite values");
          best = std::max(best, v);
        }
    };
    if (distributing()) {  // skelflow-mpi: each rank scans its blocks; the maximum over the ranks
      for_each_owned_block(layout, Interrupter(), "thinning (halo)", scan);
      best = minmax_over_ranks(best, best).second;
      return;
    }
    const Dims c = layout.count();
    for (int64_t bz = 0; bz < c[2]; ++bz)
      for (int64_t by = 0; by < c[1]; ++by)
        for (int64_t bx = 0; bx < c[0]; ++bx) scan(layout.at(bx, by, bz));
  });
  if (is_float) {
    const double s = std::min({g.spacing[0], g.spacing[1], g.spacing[2]});
    return s > 0 ? best / s : best;
  }
  return best / 3.0;
}

BlockThinningResult thin_doht_blocks(const DataObject& mask, const DataObject& priority, const DataObject* locked,
                                     const ChunkedVolume& skeleton, const BlockThinningOptions& o,
                                     const BlockPlan& plan) {
  if (o.end_point_length < 0)
    throw InputError("end_point_length: expected >= 0, got " + std::to_string(o.end_point_length));
  if (o.halo < 0) throw InputError("param 'halo': expected >= 0 (0: from the priority), got " + std::to_string(o.halo));
  const Grid& g = any_volume_grid(mask, "input 'mask'");
  if (mask.type_id() != type_ids::volume_u8) throw InputError("input 'mask': expected volume.u8, got " + mask.type_id());
  const Grid& pg = any_volume_grid(priority, "input 'priority'");
  if (pg.dims != g.dims)
    throw InputError("priority: dims " + dims_text(pg.dims) + " differ from the mask's " + dims_text(g.dims));
  if (locked && any_volume_grid(*locked, "input 'locked'").dims != g.dims)
    throw InputError("locked: dims " + dims_text(any_volume_grid(*locked, "input 'locked'").dims) +
                     " differ from the mask's " + dims_text(g.dims));
  if (skeleton.dims() != g.dims || skeleton.type_id() != type_ids::volume_u8)
    throw Error("thin_doht_blocks: the skeleton must be volume.u8 on the mask's grid");

  BlockThinningResult res;
  res.bytes_per_voxel = block_thinning_bytes_per_voxel(voxel_bytes(priority.type_id()));
  const Interrupter& irq = o.interrupter;
  const Dims scan_block = plan.block;
  double d_max = 0;
  if (o.halo > 0) {
    res.halo = o.halo;
  } else {
    d_max = priority_max_distance(mask, priority, scan_block);
    res.halo = halo_for_distance(d_max);
  }
  const int64_t H = res.halo;
  res.block = plan.block_from_user ? plan.block
                                   : block_for_budget(plan.memory_budget, H, res.bytes_per_voxel, g.dims);
  // The sub-block must fit the budget (the whole of it: one sub-block is in memory at a time).
  {
    double side[3];
    for (int a = 0; a < 3; ++a)
      side[a] = static_cast<double>(std::min(g.dims[a], std::min(res.block[a], g.dims[a]) + 2 * H));
    const double need = side[0] * side[1] * side[2] * static_cast<double>(res.bytes_per_voxel);
    if (plan.memory_budget > 0 && need > static_cast<double>(plan.memory_budget))
      throw InputError("param 'halo': a halo of " + std::to_string(H) + " voxels" +
                       (o.halo > 0 ? std::string() : " (the object's largest distance to its border, " +
                                                         std::to_string(d_max) + " voxels, from the priority)") +
                       " around blocks of " + dims_text(res.block) + " voxels needs " +
                       format_byte_size(static_cast<uint64_t>(need)) + " per sub-block (" +
                       std::to_string(res.bytes_per_voxel) + " bytes per voxel), more than the memory budget of " +
                       format_byte_size(plan.memory_budget) + "; raise the budget or use a smaller block");
  }

  const BlockLayout layout(g.dims, res.block, H);
  const Dims count = layout.count();
  // The box [begin, begin + size) widened to whole chunks of the skeleton volume (clipped to the grid).
  const Dims chunk = plan.chunk;
  auto widen_to_chunks = [&](Dims& begin, Dims& size) {
    for (int a = 0; a < 3; ++a) {
      const int64_t c = std::max<int64_t>(1, chunk[a]);
      const int64_t lo = begin[a] / c * c, hi = std::min(g.dims[a], (begin[a] + size[a] + c - 1) / c * c);
      begin[a] = lo;
      size[a] = hi - lo;
    }
  };
  res.blocks = layout.total();

  // Resumable per block (--resume): the copy and every thinning pass are passes of the journal. The
  // state between blocks is the skeleton volume (replayed) and what each block committed with it:
  // its statistics and the box of voxels it changed, from which the blocks to visit again are
  // marked as in the uninterrupted run, so the passes and their block orders are the same.
  struct BlockRecord {
    int64_t ran = 0;  // 1: thin_doht ran on the sub-block
    int64_t tests = 0, removed = 0, sub_iterations = 0;
    uint64_t bytes = 0;
    Dims lo{0, 0, 0}, hi{-1, -1, -1};  // changed voxels, global (hi[0] < 0: none)
  };

  // The state: the mask as 0/1 in the skeleton volume. Object voxels per block: the cost estimate
  // of a block when the ranks share the blocks (skelflow-mpi).
  std::vector<int64_t> block_objects(static_cast<size_t>(res.blocks), 0);
  auto copy_block = [&](const Block& b) {
    const VolumeU8 m = binary(read_block<uint8_t>(mask, b.begin, b.size, "input 'mask'"));
    int64_t n = 0;
    for (const uint8_t v : m) n += v;
    skeleton.write(m, b.begin);
    return n;
  };
  if (distributing()) {
    const BlockLayout copy(g.dims, res.block);
    std::vector<double> costs(static_cast<size_t>(res.blocks));
    for (int64_t i = 0; i < res.blocks; ++i) {
      const Block b = copy.at(i % count[0], (i / count[0]) % count[1], i / (count[0] * count[1]));
      costs[static_cast<size_t>(i)] = static_cast<double>(b.size[0] * b.size[1] * b.size[2]);
    }
    const std::vector<std::string> n = exchange_owned_items(res.blocks, costs, [&](int64_t i) {
      return payload_of(copy_block(copy.at(i % count[0], (i / count[0]) % count[1], i / (count[0] * count[1]))));
    });
    for (int64_t i = 0; i < res.blocks; ++i) {
      block_objects[static_cast<size_t>(i)] = payload_as<int64_t>(n[static_cast<size_t>(i)]);
      res.stats.object_voxels += block_objects[static_cast<size_t>(i)];
    }
  } else {
    const BlockLayout copy(g.dims, res.block);
    for_each_block_resumable(
        copy, irq, "thinning (copy)",
        [&](const Block& b) {
          const int64_t n = copy_block(b);
          res.stats.object_voxels += n;
          return payload_of(n);
        },
        [&](const Block&, const std::string& p) { res.stats.object_voxels += payload_as<int64_t>(p); });
  }

  ThinningOptions to = o;
  std::vector<int64_t> order(static_cast<size_t>(res.blocks));
  for (int64_t i = 0; i < res.blocks; ++i) order[static_cast<size_t>(i)] = i;
  std::vector<int64_t> pos(static_cast<size_t>(res.blocks));
  while (!order.empty()) {
    ++res.passes;
    std::fill(pos.begin(), pos.end(), -1);
    for (size_t i = 0; i < order.size(); ++i) pos[static_cast<size_t>(order[i])] = static_cast<int64_t>(i);
    std::vector<char> again(static_cast<size_t>(res.blocks), 0);
    const int64_t total = static_cast<int64_t>(order.size());
    const std::string label = res.passes == 1 ? "thinning" : "thinning pass " + std::to_string(res.passes);
    report_blocks(irq, label, 0, total);
    ResumablePass pass;
    // Applies block bi's record (at place k of the pass): statistics, and the blocks whose
    // sub-blocks hold a changed voxel and that this pass does not visit any more run again in the
    // next pass.
    auto apply = [&](int64_t bi, int64_t k, const BlockRecord& rec) {
      if (rec.ran) {
        ++res.block_runs;
        res.stats.tests += rec.tests;
        res.stats.removed += rec.removed;
        res.stats.sub_iterations += rec.sub_iterations;
        res.stats.bytes = std::max(res.stats.bytes, rec.bytes);
      }
      if (rec.hi[0] < 0) return;
      Dims blo{}, bhi{};
      for (int a = 0; a < 3; ++a) {
        const int64_t glo = rec.lo[a] - H, ghi = rec.hi[a] + H;
        blo[a] = std::max<int64_t>(0, glo / res.block[a]);
        bhi[a] = std::min<int64_t>(count[a] - 1, std::max<int64_t>(0, ghi) / res.block[a]);
      }
      for (int64_t z = blo[2]; z <= bhi[2]; ++z)
        for (int64_t y = blo[1]; y <= bhi[1]; ++y)
          for (int64_t x = blo[0]; x <= bhi[0]; ++x) {
            const int64_t j = block_index(count, x, y, z);
            if (j == bi) continue;
            const int64_t pj = pos[static_cast<size_t>(j)];
            if (pj < 0 || pj < k) again[static_cast<size_t>(j)] = 1;
          }
    };
    // Thins block bi (at place k of the pass) on the state; returns its record. `aligned`
    // (skelflow-mpi): the sub-block is read and written back within its box widened to whole chunks
    // of the skeleton volume (the voxels outside the sub-block written back as they were read), so
    // that the shared store writes whole chunks, not row by row; the wavefronts keep the widened
    // boxes of concurrent blocks disjoint.
    auto thin_block = [&](int64_t bi, int64_t k, bool aligned) {
      const int64_t bx = bi % count[0], by = (bi / count[0]) % count[1], bz = bi / (count[0] * count[1]);
      const Block b = layout.at(bx, by, bz);
      const Dims& ob = b.outer_begin;
      const Dims& os = b.outer_size;
      BlockRecord rec;
      Dims wb = ob, ws = os;
      if (aligned) widen_to_chunks(wb, ws);
      VolumeU8 wide = skeleton.read<uint8_t>(wb, ws);
      std::optional<VolumeU8> boxed;
      if (aligned) {
        boxed.emplace(skeleton.box_grid(ob, os), 0);
        for (int64_t z = 0; z < os[2]; ++z)
          for (int64_t y = 0; y < os[1]; ++y)
            std::memcpy(&(*boxed)(0, y, z), &wide(ob[0] - wb[0], ob[1] - wb[1] + y, ob[2] - wb[2] + z), static_cast<size_t>(os[0]));
      }
      const VolumeU8& state = boxed ? *boxed : wide;
      if (std::find(state.begin(), state.end(), uint8_t{1}) == state.end()) return rec;  // no object: nothing to thin
      const VolumeU8 orig = binary(read_block<uint8_t>(mask, ob, os, "input 'mask'"));
      VolumeU8 locks(os, 0);
      const int64_t unreached = border_locks(orig, ob, g.dims, b.begin, b.size, o.threads, locks);
      if (unreached > 0)
        throw InputError("param 'halo': " + std::to_string(unreached) + " object voxels of block " + dims_text(b.index) +
                         " (voxels " + dims_text(b.begin) + " + " + dims_text(b.size) +
                         ") lie farther from the object border than the halo of " + std::to_string(H) + " voxels" +
                         (o.halo > 0 ? std::string("; raise 'halo' or set it to 0 (from the priority)")
                                     : std::string("; the priority (") + priority.type_id() +
                                           ") is no distance to the border in voxels: set 'halo' to the object's "
                                           "largest radius in voxels"));
      if (locked) {
        const VolumeU8 user = read_block<uint8_t>(*locked, ob, os, "input 'locked'");
        for (int64_t i = 0; i < locks.size(); ++i) locks[i] = (locks[i] || user[i]) ? 1 : 0;
      }
      const double f0 = static_cast<double>(k) / static_cast<double>(total);
      to.interrupter = irq.sub(f0, static_cast<double>(k + 1) / static_cast<double>(total));
      ThinningResult r = visit_voxel_type(priority.type_id(), "input 'priority'", [&](auto tag) {
        using T = decltype(tag);
        const Volume<T> p = read_block<T>(priority, ob, os, "input 'priority'");
        return thin_doht(state, p, &locks, to);
      });
      rec.ran = 1;
      rec.tests = r.stats.tests;
      rec.removed = r.stats.removed;
      rec.sub_iterations = r.stats.sub_iterations;
      rec.bytes = r.stats.bytes;
      // The box of changed voxels (sub-block coordinates).
      Dims lo{os[0], os[1], os[2]}, hi{-1, -1, -1};
      for (int64_t z = 0; z < os[2]; ++z)
        for (int64_t y = 0; y < os[1]; ++y)
          for (int64_t x = 0; x < os[0]; ++x)
            if (state(x, y, z) != r.skeleton(x, y, z)) {
              const int64_t p[3] = {x, y, z};
              for (int a = 0; a < 3; ++a) {
                lo[a] = std::min(lo[a], p[a]);
                hi[a] = std::max(hi[a], p[a]);
              }
            }
      if (hi[0] >= 0 && aligned) {
        for (int64_t z = 0; z < os[2]; ++z)
          for (int64_t y = 0; y < os[1]; ++y)
            std::memcpy(&wide(ob[0] - wb[0], ob[1] - wb[1] + y, ob[2] - wb[2] + z), &r.skeleton(0, y, z), static_cast<size_t>(os[0]));
        skeleton.write(wide, wb);
      } else if (hi[0] >= 0) {
        skeleton.write(r.skeleton, ob);
      }
      if (hi[0] >= 0) {
        for (int a = 0; a < 3; ++a) {
          rec.lo[a] = ob[a] + lo[a];
          rec.hi[a] = ob[a] + hi[a];
        }
      }
      return rec;
    };
    if (distributing()) {
      // skelflow-mpi: the pass's blocks in wavefronts (docs/architecture.md, "Running on several
      // processes"). Block k of the pass reads and writes its sub-block only, so its result depends
      // on exactly the blocks before it in the pass whose sub-blocks overlap its own; its wavefront is
      // one past the latest of theirs. Blocks of one wavefront have pairwise disjoint sub-blocks and
      // run on the ranks at the same time; each wavefront starts when the one before it has been
      // written to the shared skeleton. Every block thus sees the state it sees in the serial order,
      // and the skeleton, the records and the blocks marked for the next pass are the serial run's.
      std::vector<int64_t> wave(static_cast<size_t>(total), 0);
      Dims reach{};
      for (int a = 0; a < 3; ++a) reach[a] = (2 * H + 2 * chunk[a]) / std::max<int64_t>(1, res.block[a]) + 1;
      int64_t waves = 0;
      for (int64_t k = 0; k < total; ++k) {
        const int64_t bi = order[static_cast<size_t>(k)];
        const Dims bc{bi % count[0], (bi / count[0]) % count[1], bi / (count[0] * count[1])};
        const Block b = layout.at(bc[0], bc[1], bc[2]);
        Dims bb = b.outer_begin, bs = b.outer_size;
        widen_to_chunks(bb, bs);
        int64_t w = 0;
        for (int64_t z = std::max<int64_t>(0, bc[2] - reach[2]); z <= std::min(count[2] - 1, bc[2] + reach[2]); ++z)
          for (int64_t y = std::max<int64_t>(0, bc[1] - reach[1]); y <= std::min(count[1] - 1, bc[1] + reach[1]); ++y)
            for (int64_t x = std::max<int64_t>(0, bc[0] - reach[0]); x <= std::min(count[0] - 1, bc[0] + reach[0]); ++x) {
              const int64_t pj = pos[static_cast<size_t>(block_index(count, x, y, z))];
              if (pj < 0 || pj >= k) continue;
              const Block c = layout.at(x, y, z);
              Dims cb = c.outer_begin, cs = c.outer_size;
              widen_to_chunks(cb, cs);
              bool overlap = true;
              for (int a = 0; a < 3; ++a) overlap = overlap && bb[a] < cb[a] + cs[a] && cb[a] < bb[a] + bs[a];
              if (overlap) w = std::max(w, wave[static_cast<size_t>(pj)] + 1);
            }
        wave[static_cast<size_t>(k)] = w;
        waves = std::max(waves, w + 1);
      }
      std::vector<std::vector<int64_t>> in_wave(static_cast<size_t>(waves));
      for (int64_t k = 0; k < total; ++k) in_wave[static_cast<size_t>(wave[static_cast<size_t>(k)])].push_back(k);
      std::vector<BlockRecord> recs(static_cast<size_t>(total));
      int64_t done = 0;
      for (const auto& places : in_wave) {
        std::vector<double> costs;  // reading the sub-block, and thinning its object
        for (const int64_t k : places) {
          const int64_t bi = order[static_cast<size_t>(k)];
          costs.push_back(1.0 + static_cast<double>(block_objects[static_cast<size_t>(bi)]));
        }
        const int64_t n = static_cast<int64_t>(places.size());
        const std::vector<std::string> got = exchange_owned_items(n, costs, [&](int64_t t) {
          const int64_t k = places[static_cast<size_t>(t)];
          return payload_of(thin_block(order[static_cast<size_t>(k)], k, true));
        });
        for (int64_t t = 0; t < n; ++t)
          recs[static_cast<size_t>(places[static_cast<size_t>(t)])] = payload_as<BlockRecord>(got[static_cast<size_t>(t)]);
        done += n;
        report_blocks(irq, label, done, total);
      }
      for (int64_t k = 0; k < total; ++k) apply(order[static_cast<size_t>(k)], k, recs[static_cast<size_t>(k)]);
    } else {
      for (int64_t k = 0; k < total; ++k) {
        const int64_t bi = order[static_cast<size_t>(k)];
        if (const std::string* p = pass.kept(bi)) {
          apply(bi, k, payload_as<BlockRecord>(*p));
          continue;
        }
        const BlockRecord rec = thin_block(bi, k, false);
        apply(bi, k, rec);
        pass.commit(bi, payload_of(rec));
        report_blocks(irq, label, k + 1, total);
      }
    }
    order.clear();
    for (int64_t j = 0; j < res.blocks; ++j)
      if (again[static_cast<size_t>(j)]) order.push_back(j);
  }
  res.stats.skeleton_voxels = res.stats.object_voxels - res.stats.removed;
  return res;
}

}  // namespace skel::thinning
