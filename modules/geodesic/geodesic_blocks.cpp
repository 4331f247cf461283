// Geodesic boundary distance block by block (thesis §5.3): the in-core boundary_distance on each
// block with a margin of d_max + t/2, the interior kept. See geodesic_blocks.hpp.
#include "geodesic/geodesic_blocks.hpp"

#include <algorithm>
#include <limits>
#include <string>
#include <vector>

#include "skel/block_journal.hpp"
#include "skel/error.hpp"

namespace skel::geodesic {

namespace {

std::string dims_text(const Dims& d) {
  return std::to_string(d[0]) + "x" + std::to_string(d[1]) + "x" + std::to_string(d[2]);
}

// Chessboard distance of every voxel of `mask` to the nearest background voxel (voxels outside the
// array are background), capped at 65535: the ring numbers of boundary_distance's nearest-point
// propagation. Two raster passes over the 26-neighbourhood with unit weights (exact for the
// chessboard metric). Returns the largest value over the box [begin, begin + size).
int64_t max_ring_in(const VolumeU8& mask, const Dims& begin, const Dims& size) {
  const int64_t nx = mask.nx(), ny = mask.ny(), nz = mask.nz();
  std::vector<uint16_t> d(static_cast<size_t>(mask.size()));
  auto at = [&](int64_t x, int64_t y, int64_t z) -> int64_t {
    if (x < 0 || y < 0 || z < 0 || x >= nx || y >= ny || z >= nz) return 0;
    return d[static_cast<size_t>(x + nx * (y + ny * z))];
  };
  constexpr int64_t kCap = std::numeric_limits<uint16_t>::max();
  for (int64_t z = 0; z < nz; ++z)
    for (int64_t y = 0; y < ny; ++y)
      for (int64_t x = 0; x < nx; ++x) {
        const size_t i = static_cast<size_t>(x + nx * (y + ny * z));
        if (mask[static_cast<int64_t>(i)] == 0) {
          d[i] = 0;
          continue;
        }
        int64_t m = kCap;
        for (int64_t dz = -1; dz <= 0; ++dz)
          for (int64_t dy = -1; dy <= 1; ++dy)
            for (int64_t dx = -1; dx <= 1; ++dx) {
              if (dz == 0 && (dy > 0 || (dy == 0 && dx >= 0))) continue;
              m = std::min(m, at(x + dx, y + dy, z + dz));
            }
        d[i] = static_cast<uint16_t>(std::min(kCap, m + 1));
      }
  for (int64_t z = nz; z-- > 0;)
    for (int64_t y = ny; y-- > 0;)
      for (int64_t x = nx; x-- > 0;) {
        const size_t i = static_cast<size_t>(x + nx * (y + ny * z));
        if (d[i] == 0) continue;
        int64_t m = d[i];
        for (int64_t dz = 0; dz <= 1; ++dz)
          for (int64_t dy = -1; dy <= 1; ++dy)
            for (int64_t dx = -1; dx <= 1; ++dx) {
              if (dz == 0 && (dy < 0 || (dy == 0 && dx <= 0))) continue;
              m = std::min(m, at(x + dx, y + dy, z + dz) + 1);
            }
        d[i] = static_cast<uint16_t>(m);
      }
  int64_t best = 0;
  for (int64_t z = begin[2]; z < begin[2] + size[2]; ++z)
    for (int64_t y = begin[1]; y < begin[1] + size[1]; ++y)
      for (int64_t x = begin[0]; x < begin[0] + size[0]; ++x) best = std::max(best, at(x, y, z));
  return best;
}

struct Driver {
  const DataObject& mask;
  const ChunkedVolume& importance;
  const ChunkedVolume& surface;
  const Options& options;
  uint64_t budget;
  Grid grid;
  int64_t margin_guess = 0;
  BlockStatistics stats;

  // The box of [begin, begin + size) with margin m on every side, clipped to the grid.
  void outer(const Dims& begin, const Dims& size, int64_t m, Dims& ob, Dims& os) const {
    for (int a = 0; a < 3; ++a) {
      ob[a] = std::max<int64_t>(0, begin[a] - m);
      os[a] = std::min(grid.dims[a], begin[a] + size[a] + m) - ob[a];
    }
  }
  static uint64_t box_bytes(const Dims& os) {
    return static_cast<uint64_t>(os[0] * os[1] * os[2]) * static_cast<uint64_t>(kBlockBytesPerVoxel);
  }
  // True when the box reaches the grid's border on every side where it is narrower than margin m.
  bool margin_holds(const Dims& begin, const Dims& size, const Dims& ob, const Dims& os, int64_t m) const {
    for (int a = 0; a < 3; ++a) {
      if (ob[a] > 0 && begin[a] - ob[a] < m) return false;
      if (ob[a] + os[a] < grid.dims[a] && ob[a] + os[a] - (begin[a] + size[a]) < m) return false;
    }
    return true;
  }
  // `ring`: a lower bound of the block's d_max (the largest ring found in a box too small to be
  // sure), or -1 when none was read.
  [[noreturn]] void refuse(const Dims& begin, const Dims& os, int64_t m, int64_t ring) const {
    const std::string why = ring >= 0 ? "d_max >= " + std::to_string(ring) + " + t/2 " +
                                            std::to_string((options.threshold + 1) / 2) + " + 3"
                                      : "at least t/2 " + std::to_string((options.threshold + 1) / 2) + " + 3, plus d_max";
    throw InputError("parameter 'threshold': the block at voxel (" + std::to_string(begin[0]) + ", " +
                     std::to_string(begin[1]) + ", " + std::to_string(begin[2]) + ") needs a margin of " +
                     std::to_string(m) + " voxels (" + why + ", thesis §5.3); even with an interior of 8 " +
                     "voxels the block with its margin (" + dims_text(os) + " voxels) needs " +
                     format_byte_size(box_bytes(os)) + ", more than the memory budget " + format_byte_size(budget) +
                     ": raise the memory budget or lower the threshold");
  }

  // Computes the interior [begin, begin + size) exactly; splits it when its margin does not fit.
  void run_box(const Dims& begin, const Dims& size) {
    const int64_t least = exact_margin(0, options.threshold);
    int64_t m = std::max<int64_t>(margin_guess, least);
    bool tried_least = m == least;
    int64_t known_ring = -1;
    for (;;) {
      Dims ob{}, os{};
      outer(begin, size, m, ob, os);
      if (budget > 0 && box_bytes(os) > budget) {
        if (!tried_least) {  // the previous block's margin may be more than this one needs
          m = least;
          tried_least = true;
          continue;
        }
        if (split(begin, size)) return;
        refuse(begin, os, m, known_ring);
      }
      const VolumeU8 box = read_block<uint8_t>(mask, ob, os, "input 'mask'");
      const Dims local{begin[0] - ob[0], begin[1] - ob[1], begin[2] - ob[2]};
      const int64_t ring = max_ring_in(box, local, size);
      const int64_t need = exact_margin(ring, options.threshold);
      known_ring = std::max(known_ring, ring);
      stats.max_ring = std::max(stats.max_ring, ring);
      if (!margin_holds(begin, size, ob, os, need)) {
        // The rings computed in the box are exact below the margin; a larger ring may be larger still.
        m = std::max(need, m + 1);
        ++stats.retries;
        continue;
      }
      margin_guess = need;
      stats.largest_margin = std::max(stats.largest_margin, need);
      stats.largest_block_bytes = std::max(stats.largest_block_bytes, box_bytes(os));
      Options o = options;
      o.interrupter = {};
      const Result r = boundary_distance(box, o);
      const VolumeF32 imp = read_block<float>(r.importance, local, size, "block");
      const VolumeU8 surf = read_block<uint8_t>(r.surface_skeleton, local, size, "block");
      importance.write(imp, begin);
      surface.write(surf, begin);
      for (int64_t z = 0; z < size[2]; ++z)
        for (int64_t y = 0; y < size[1]; ++y)
          for (int64_t x = 0; x < size[0]; ++x) stats.object_voxels += box(local[0] + x, local[1] + y, local[2] + z) != 0;
      const Statistics& s = r.stats;
      stats.summed.object_voxels += s.object_voxels;
      stats.summed.layer_voxels += s.layer_voxels;
      stats.summed.base_points += s.base_points;
      stats.summed.searches += s.searches;
      stats.summed.pivots += s.pivots;
      stats.summed.long_searches += s.long_searches;
      stats.summed.saturated_by_pivot += s.saturated_by_pivot;
      stats.summed.visited += s.visited;
      stats.summed.landmarks += s.landmarks;
      stats.summed.bytes = std::max(stats.summed.bytes, s.bytes);
      return;
    }
  }
  // Halves the interior along its longest side (down to 8 voxels); false when it is that small.
  bool split(const Dims& begin, const Dims& size) {
    int a = 0;
    for (int k = 1; k < 3; ++k)
      if (size[k] > size[a]) a = k;
    if (size[a] <= 8) return false;
    Dims s0 = size, b1 = begin, s1 = size;
    s0[a] = size[a] / 2;
    b1[a] = begin[a] + s0[a];
    s1[a] = size[a] - s0[a];
    run_box(begin, s0);
    run_box(b1, s1);
    return true;
  }
};

}  // namespace

int64_t exact_margin(int64_t max_ring, int64_t threshold) { return max_ring + (threshold + 1) / 2 + 3; }

BlockStatistics boundary_distance_blocks(const DataObject& mask, const ChunkedVolume& importance,
                                         const ChunkedVolume& surface_skeleton, const Options& options,
                                         const Dims& block, uint64_t memory_budget) {
  const Grid& g = any_volume_grid(mask, "input 'mask'");
  if (mask.type_id() != type_ids::volume_u8)
    throw InputError("input 'mask': expected " + std::string(type_ids::volume_u8) + ", got " + mask.type_id());
  if (options.mode != Mode::Threshold)
    throw InputError("parameter 'mode': full gives exact values over unbounded boundary paths, which no block "
                     "margin holds; under a memory budget use mode threshold (margin d_max + t/2, thesis §5.3)");
  if (options.threshold < 1) throw InputError("parameter 'threshold': expected >= 1, got " + std::to_string(options.threshold));
  if (importance.dims() != g.dims || importance.type_id() != type_ids::volume_f32 || surface_skeleton.dims() != g.dims ||
      surface_skeleton.type_id() != type_ids::volume_u8)
    throw Error("boundary_distance_blocks: the outputs must be float32 and uint8 on the mask's grid");
  Driver d{mask, importance, surface_skeleton, options, memory_budget, g, 0, {}};
  const BlockLayout layout(g.dims, block);
  d.stats.blocks = layout.total();
  // Resumable per block (--resume). The state carried from block to block (the margin guess and the
  // statistics) is committed with each block; the values of a block do not depend on it (any
  // margin that holds is exact, a split block gives the same voxels), only the work does.
  struct Carried {
    int64_t margin_guess;
    BlockStatistics stats;
  };
  for_each_block_resumable(
      layout, options.interrupter, "geodesic",
      [&](const Block& b) {
        d.run_box(b.begin, b.size);
        return payload_of(Carried{d.margin_guess, d.stats});
      },
      [&](const Block&, const std::string& p) {  // committed blocks are a prefix: the last one's state
        const auto c = payload_as<Carried>(p);
        d.margin_guess = c.margin_guess;
        d.stats = c.stats;
      });
  return d.stats;
}

}  // namespace skel::geodesic
