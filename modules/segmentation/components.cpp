// Connected components by union-find over runs (maximal x-intervals of object voxels): runs are
// extracted per row in parallel, rows are merged with their backward neighbour rows inside z-slabs in
// parallel (each slab owns a contiguous range of run ids), slab borders are merged afterwards, and
// the final labels are canonical (size descending, ties by first voxel in raster order), so they do
// not depend on the slab split or the thread count.
#include <algorithm>
#include <array>
#include <cstdlib>
#include <cstring>
#include <functional>
#include <map>
#include <numeric>
#include <vector>

#include "segmentation/segmentation.hpp"
#include "skel/block_journal.hpp"
#include "skel/distributed.hpp"
#include "skel/error.hpp"
#include "skel/mask.hpp"
#include "skel/units.hpp"
#include "skel/parallel.hpp"
#include "skel/union_find.hpp"

namespace skel::segmentation {
namespace {

struct Runs {
  std::vector<int64_t> row_start;  // ny*nz + 1 offsets into x0/x1
  std::vector<int32_t> x0, x1;     // [x0, x1)
};

// Runs of object voxels, or of background voxels (value 0) when `background`.
Runs extract_runs(const VolumeU8& mask, int threads, bool background = false) {
  const uint8_t flip = background ? 1 : 0;
  const int64_t nx = mask.nx(), rows = mask.ny() * mask.nz();
  Runs r;
  r.row_start.assign(static_cast<size_t>(rows + 1), 0);
  parallel_for(0, rows, threads, [&](int64_t b, int64_t e) {
    for (int64_t row = b; row < e; ++row) {
      const uint8_t* p = mask.data() + row * nx;
      int64_t c = 0;
      uint8_t prev = 0;
      for (int64_t x = 0; x < nx; ++x) {
        const uint8_t cur = static_cast<uint8_t>((p[x] != 0) ^ flip);
        c += cur & (prev ^ 1);
        prev = cur;
      }
      r.row_start[static_cast<size_t>(row + 1)] = c;
    }
  }, 256);
  for (int64_t row = 0; row < rows; ++row) r.row_start[static_cast<size_t>(row + 1)] += r.row_start[static_cast<size_t>(row)];
  const auto total = static_cast<size_t>(r.row_start.back());
  r.x0.resize(total);
  r.x1.resize(total);
  parallel_for(0, rows, threads, [&](int64_t b, int64_t e) {
    for (int64_t row = b; row < e; ++row) {
      const uint8_t* p = mask.data() + row * nx;
      auto k = static_cast<size_t>(r.row_start[static_cast<size_t>(row)]);
      int64_t x = 0;
      while (x < nx) {
        while (x < nx && ((p[x] != 0) ^ flip) == 0) ++x;
        if (x == nx) break;
        const int64_t s = x;
        while (x < nx && ((p[x] != 0) ^ flip) != 0) ++x;
        r.x0[k] = static_cast<int32_t>(s);
        r.x1[k] = static_cast<int32_t>(x);
        ++k;
      }
    }
  }, 256);
  return r;
}

// Unites the runs of row `cur` with those of row `nb` that touch them: `ext` = 1 when diagonal
// neighbours along x count (the rows differ in y or z by a face step, connectivity 18/26, or any
// step for 26), 0 for strict overlap.
void merge_rows(const Runs& r, UnionFind& uf, int64_t cur, int64_t nb, int32_t ext) {
  int64_t i = r.row_start[static_cast<size_t>(cur)], ie = r.row_start[static_cast<size_t>(cur + 1)];
  int64_t j = r.row_start[static_cast<size_t>(nb)], je = r.row_start[static_cast<size_t>(nb + 1)];
  while (i < ie && j < je) {
    const auto si = static_cast<size_t>(i), sj = static_cast<size_t>(j);
    if (r.x1[sj] + ext <= r.x0[si]) {
      ++j;
    } else if (r.x1[si] + ext <= r.x0[sj]) {
      ++i;
    } else {
      uf.unite(i, j);
      if (r.x1[si] < r.x1[sj]) ++i;
      else ++j;
    }
  }
}

struct RowStep {
  int dy, dz;
  int32_t ext;
};

// Unites the runs of neighbouring rows (connectivity 6, 18 or 26); parent[i] <= i afterwards.
std::vector<int64_t> union_runs(const Runs& r, int64_t ny, int64_t nz, int connectivity, int threads,
                                const Interrupter& interrupter) {
  UnionFind uf(static_cast<int64_t>(r.x0.size()));  // roots are the smallest run ids: parent[i] <= i

  // Backward neighbour rows of row (y, z).
  std::vector<RowStep> steps;
  if (connectivity == 6) {
    steps = {{-1, 0, 0}, {0, -1, 0}};
  } else if (connectivity == 18) {
    steps = {{-1, 0, 1}, {0, -1, 1}, {-1, -1, 0}, {1, -1, 0}};
  } else {
    steps = {{-1, 0, 1}, {0, -1, 1}, {-1, -1, 1}, {1, -1, 1}};
  }
  // mode 0: in-plane steps only, 1: previous-plane steps only, 2: all.
  auto merge_row = [&](int64_t y, int64_t z, int mode) {
    const int64_t cur = y + ny * z;
    for (const RowStep& s : steps) {
      if ((s.dz != 0 && mode == 0) || (s.dz == 0 && mode == 1)) continue;
      const int64_t Y = y + s.dy, Z = z + s.dz;
      if (Y < 0 || Y >= ny || Z < 0) continue;
      merge_rows(r, uf, cur, Y + ny * Z, s.ext);
    }
  };
  // Slabs of planes merged in parallel (each slab touches only its own run ids), then the first
  // plane of every slab with the plane before it.
  const int64_t slabs = std::max<int64_t>(1, std::min<int64_t>(nz, 4 * effective_threads(threads)));
  std::vector<int64_t> slab_start(static_cast<size_t>(slabs), -1);
  parallel_chunks(0, nz, slabs, threads, [&](int64_t c, int64_t z0, int64_t z1) {
    if (z0 >= z1) return;
    slab_start[static_cast<size_t>(c)] = z0;
    for (int64_t z = z0; z < z1; ++z) {
      for (int64_t y = 0; y < ny; ++y) merge_row(y, z, z > z0 ? 2 : 0);
      if (((z - z0) & 31) == 31) interrupter.check();
    }
  });
  for (int64_t z0 : slab_start)
    if (z0 > 0)
      for (int64_t y = 0; y < ny; ++y) merge_row(y, z0, 1);
  return std::move(uf).release();
}

// Statistics of one component (integer sums: exact and independent of how the voxels were visited).
struct ComponentInfo {
  int64_t voxels = 0, lo[3] = {0, 0, 0}, hi[3] = {0, 0, 0}, sum[3] = {0, 0, 0};
  int64_t first = 0;  // linear index of its first voxel in raster order (block-wise ordering)
};

// Adds run [a, b] of row (y, z) to `c`.
inline void add_run(ComponentInfo& c, int64_t a, int64_t b, int64_t y, int64_t z) {
  const int64_t len = b - a + 1;
  if (c.voxels == 0) {
    c.lo[0] = a; c.hi[0] = b;
    c.lo[1] = c.hi[1] = y;
    c.lo[2] = c.hi[2] = z;
  } else {
    c.lo[0] = std::min(c.lo[0], a);
    c.hi[0] = std::max(c.hi[0], b);
    c.lo[1] = std::min(c.lo[1], y);
    c.hi[1] = std::max(c.hi[1], y);
    c.lo[2] = std::min(c.lo[2], z);
    c.hi[2] = std::max(c.hi[2], z);
  }
  c.voxels += len;
  c.sum[0] += (a + b) * len / 2;
  c.sum[1] += y * len;
  c.sum[2] += z * len;
}

// Labels of components given in raster order of their first voxels: size descending, ties in that
// order; min_size, min_fraction and keep_largest applied. Fills `order` and `count`; returns label_of
// (0 = removed). `warning` names the largest removed component when it holds at least a tenth of the
// largest one's voxels: a network cut in two by the threshold loses half of itself silently otherwise.
std::vector<uint32_t> label_components(const std::vector<ComponentInfo>& comps, const ComponentOptions& o,
                                       std::vector<size_t>& order, uint32_t& count, std::string& warning) {
  order.resize(comps.size());
  std::iota(order.begin(), order.end(), size_t{0});
  std::stable_sort(order.begin(), order.end(), [&](size_t a, size_t b) { return comps[a].voxels > comps[b].voxels; });
  std::vector<uint32_t> label_of(comps.size(), 0);
  const int64_t largest = comps.empty() ? 0 : comps[order.front()].voxels;
  const double fraction_floor = o.min_fraction * static_cast<double>(largest);
  uint32_t next = 0;
  int64_t dropped = 0, dropped_large = 0, dropped_voxels = 0;
  for (size_t k : order) {
    const int64_t v = comps[k].voxels;
    const bool keep = v >= o.min_size && static_cast<double>(v) >= fraction_floor && !(o.keep_largest && next >= 1);
    if (!keep) {
      ++dropped;
      dropped_voxels += v;
      if (10 * v >= largest && largest > 0) {
        if (dropped_large == 0) {
          warning = "removed a component of " + std::to_string(v) + " voxels, " +
                    std::to_string(static_cast<int>(100.0 * static_cast<double>(v) / static_cast<double>(largest) + 0.5)) +
                    " % of the largest (" + std::to_string(largest) + " voxels)";
        }
        ++dropped_large;
      }
      continue;
    }
    if (next == UINT32_MAX) throw InputError("connected_components: more than 2^32 - 1 components");
    label_of[k] = ++next;
  }
  if (dropped_large > 0) {
    if (dropped_large > 1) warning += " and " + std::to_string(dropped_large - 1) + " more of at least a tenth of it";
    auto count_of = [](int64_t n, const char* what) {
      return std::to_string(n) + " " + what + (n == 1 ? "" : "s");
    };
    warning += "; " + count_of(dropped, "component") + " with " + count_of(dropped_voxels, "voxel") +
               " removed in all by " +
               (o.keep_largest ? std::string("keep_largest") : o.min_fraction > 0 ? "min_fraction" : "min_size") +
               ". If they are parts of the network (cut apart by the threshold or the volume's border), keep them "
               "with min_fraction (e.g. 0.05) instead of keep_largest";
  }
  count = next;
  return label_of;
}

// The component table (label, voxels, volume, bounding box, centroid) of the kept components.
Table component_table(const std::vector<ComponentInfo>& comps, const std::vector<size_t>& order,
                      const std::vector<uint32_t>& label_of, const Grid& grid) {
  const Vec3 sp = grid.spacing, org = grid.origin;
  std::vector<int64_t> lab, vox, bb[6];
  std::vector<double> vol, cen[3];
  for (size_t k : order) {
    const uint32_t l = label_of[k];
    if (!l) continue;
    const ComponentInfo& c = comps[k];
    lab.push_back(l);
    vox.push_back(c.voxels);
    vol.push_back(static_cast<double>(c.voxels) * sp[0] * sp[1] * sp[2]);
    for (int a = 0; a < 3; ++a) {
      bb[a].push_back(c.lo[a]);
      bb[3 + a].push_back(c.hi[a]);
      cen[a].push_back(org[a] + sp[a] * static_cast<double>(c.sum[a]) / static_cast<double>(c.voxels));
    }
  }
  Table table;
  table.add("label", lab).add("voxels", vox).add("volume", vol, units::power(grid.unit, 3));
  const char* names[6] = {"bbox_min_x", "bbox_min_y", "bbox_min_z", "bbox_max_x", "bbox_max_y", "bbox_max_z"};
  for (int a = 0; a < 6; ++a) table.add(names[a], bb[a], "voxels");
  table.add("centroid_x", cen[0], grid.unit).add("centroid_y", cen[1], grid.unit).add("centroid_z", cen[2], grid.unit);
  return table;
}

void check_connectivity(int connectivity) {
  if (connectivity != 6 && connectivity != 18 && connectivity != 26)
    throw InputError("connectivity must be 6, 18 or 26, got " + std::to_string(connectivity));
}

}  // namespace

namespace {
// The kept mask goes to `mask_out` (the input's own buffer for connected_components_in_place: it is
// read only before, by extract_runs) or, when null, to res.mask.
ComponentsResult components_impl(const VolumeU8& mask, const ComponentOptions& o, uint8_t* mask_out) {
  check_connectivity(static_cast<int>(o.connectivity));
  if (mask.nx() >= (int64_t{1} << 31) - 1) throw InputError("connected_components: nx must be < 2^31 - 1");
  const int64_t ny = mask.ny(), nz = mask.nz();
  const Runs r = extract_runs(mask, o.threads);
  o.interrupter.check(0.2);
  const auto nruns = static_cast<int64_t>(r.x0.size());
  std::vector<int64_t> parent = union_runs(r, ny, nz, static_cast<int>(o.connectivity), o.threads, o.interrupter);
  o.interrupter.check(0.5);
  // parent[i] <= i, so one forward pass resolves every run to its root (the component's first run).
  std::vector<int64_t> comp(static_cast<size_t>(nruns));
  std::vector<ComponentInfo> comps;
  for (int64_t i = 0; i < nruns; ++i) {
    const auto si = static_cast<size_t>(i);
    const int64_t p = parent[si];
    if (p == i) {
      comp[si] = static_cast<int64_t>(comps.size());
      comps.emplace_back();
    } else {
      comp[si] = comp[static_cast<size_t>(p)];
    }
    parent[si] = parent[static_cast<size_t>(p)];
  }
  // Per-component statistics (integer sums: exact and order independent).
  for (int64_t row = 0; row < ny * nz; ++row) {
    const int64_t y = row % ny, z = row / ny;
    for (int64_t i = r.row_start[static_cast<size_t>(row)]; i < r.row_start[static_cast<size_t>(row + 1)]; ++i) {
      const auto si = static_cast<size_t>(i);
      add_run(comps[static_cast<size_t>(comp[si])], r.x0[si], r.x1[si] - 1, y, z);
    }
  }
  // Order: size descending, ties by first voxel in raster order (= order of the root runs).
  std::vector<size_t> order;
  uint32_t next = 0;
  std::string warning;
  const std::vector<uint32_t> label_of = label_components(comps, o, order, next, warning);
  o.interrupter.check(0.7);
  ComponentsResult res;
  if (o.labels) res.labels = VolumeU32::uninitialized(mask.grid());
  if (!mask_out) {
    res.mask = VolumeU8::uninitialized(mask.grid());
    mask_out = res.mask.data();
  }
  const int64_t nx = mask.nx();
  parallel_for(0, ny * nz, o.threads, [&](int64_t b, int64_t e) {
    for (int64_t row = b; row < e; ++row) {
      uint32_t* L = o.labels ? res.labels.data() + row * nx : nullptr;
      uint8_t* M = mask_out + row * nx;
      if (L) std::fill_n(L, nx, 0u);
      std::fill_n(M, nx, uint8_t{0});
      for (int64_t i = r.row_start[static_cast<size_t>(row)]; i < r.row_start[static_cast<size_t>(row + 1)]; ++i) {
        const auto si = static_cast<size_t>(i);
        const uint32_t l = label_of[static_cast<size_t>(comp[si])];
        if (!l) continue;
        if (L) std::fill(L + r.x0[si], L + r.x1[si], l);
        std::fill(M + r.x0[si], M + r.x1[si], uint8_t{1});
      }
    }
  }, 64);
  res.count = next;
  res.warning = std::move(warning);
  res.table = component_table(comps, order, label_of, mask.grid());
  o.interrupter.check(1.0);
  return res;
}
}  // namespace

ComponentsResult connected_components(const VolumeU8& mask, const ComponentOptions& o) {
  return components_impl(mask, o, nullptr);
}

ComponentsResult connected_components_in_place(VolumeU8& mask, const ComponentOptions& o) {
  return components_impl(mask, o, mask.data());
}

// ---------------------------------------------------------------- block-wise (out-of-core)
namespace {

// Components of the object (or of the background) of a mask in memory or on disk, found block by
// block: inside every block by union-find over runs as in memory, each piece with an id local to its
// block (1-based, written to `work`; its global id is offset[block] + local - 1, pieces numbered in
// block order), its statistics in global coordinates and whether it touches a face of the array;
// then the pieces that touch across block faces, edges and corners (per connectivity) are united.
// Two passes over the blocks. When distributing (skel/distributed.hpp) each rank does its own
// blocks of both passes; the pieces and the union lists are exchanged, so every rank ends with the
// same ids and roots as one process.
struct Provisional {
  std::vector<ComponentInfo> info;  // per piece
  std::vector<uint8_t> border;      // per piece: a voxel on a face of the array
  std::vector<int64_t> root;        // per piece: its component's smallest piece id
  std::vector<int64_t> offset;      // per block (z, y, x order): global id of its first piece
  Dims count{0, 0, 0};              // blocks along x, y, z
  // Global id of the piece with local id `local` (> 0) of block (bx, by, bz).
  [[nodiscard]] int64_t global(int64_t bx, int64_t by, int64_t bz, uint64_t local) const {
    return offset[static_cast<size_t>((bz * count[1] + by) * count[0] + bx)] + static_cast<int64_t>(local) - 1;
  }
};

// The pieces of one block: its runs united inside the block; piece[i] is the 0-based local id of
// run i's piece, pieces numbered in the order of their first run (the smallest run id is the root,
// so the numbering is the same for any thread count and when the block is read again).
struct BlockRuns {
  Runs runs;
  std::vector<int64_t> piece;
  int64_t pieces = 0;
};
BlockRuns block_runs(const VolumeU8& m, int conn, bool background, int threads) {
  if (m.size() < (int64_t{1} << 16)) threads = 1;  // small blocks: not worth the tasks
  BlockRuns br;
  br.runs = extract_runs(m, threads, background);
  std::vector<int64_t> parent = union_runs(br.runs, m.ny(), m.nz(), conn, threads, Interrupter());
  br.piece.resize(parent.size());
  for (size_t i = 0; i < parent.size(); ++i) {
    const auto p = static_cast<size_t>(parent[i]);
    if (p == i) br.piece[i] = br.pieces++;
    else br.piece[i] = br.piece[p];
    parent[i] = parent[p];
  }
  return br;
}

// A run of piece voxels on one face of a block, in face coordinates: the face is a (u, v) plane (x
// faces: u = y, v = z; y faces: u = x, v = z; z faces: u = x, v = y); voxels u0 <= u < u1 of face row
// v belong to piece `id` (local, 1-based). A block keeps its six faces (x low, x high, y low, y high,
// z low, z high), sorted by (v, u0): all that is needed to unite pieces across block borders, since
// every voxel next to a block lies on a face of the neighbouring block.
struct FaceRun {
  int64_t v;
  int32_t u0, u1;
  uint64_t id;
};
using Faces = std::array<std::vector<FaceRun>, 6>;

Faces block_faces(const BlockRuns& br, const Dims& size) {
  Faces f;
  const Runs& r = br.runs;
  const int64_t sx = size[0], sy = size[1], sz = size[2];
  for (int64_t row = 0; row < sy * sz; ++row) {
    const int64_t y = row % sy, z = row / sy;
    for (int64_t i = r.row_start[static_cast<size_t>(row)]; i < r.row_start[static_cast<size_t>(row + 1)]; ++i) {
      const auto si = static_cast<size_t>(i);
      const uint64_t id = static_cast<uint64_t>(br.piece[si]) + 1;
      const int32_t a = r.x0[si], b = r.x1[si];
      if (a == 0) f[0].push_back({z, static_cast<int32_t>(y), static_cast<int32_t>(y + 1), id});
      if (b == sx) f[1].push_back({z, static_cast<int32_t>(y), static_cast<int32_t>(y + 1), id});
      if (y == 0) f[2].push_back({z, a, b, id});
      if (y == sy - 1) f[3].push_back({z, a, b, id});
      if (z == 0) f[4].push_back({y, a, b, id});
      if (z == sz - 1) f[5].push_back({y, a, b, id});
    }
  }
  // Rows come in (z, y) order: x faces and y faces are sorted by (v = z, u) already; z faces by (v = y, u).
  return f;
}

// Local id (1-based) of the piece at face point (u, v), 0 for none.
uint64_t face_id(const std::vector<FaceRun>& face, int64_t u, int64_t v) {
  auto it = std::upper_bound(face.begin(), face.end(), std::pair<int64_t, int64_t>{v, u},
                             [](const std::pair<int64_t, int64_t>& p, const FaceRun& e) {
                               return p.first < e.v || (p.first == e.v && p.second < e.u0);
                             });
  if (it == face.begin()) return 0;
  --it;
  return it->v == v && u < it->u1 ? it->id : 0;
}

struct BlockPieces {
  std::vector<ComponentInfo> info;
  std::vector<uint8_t> border;
  Faces faces;
};

std::string pack_pieces(const std::map<int64_t, BlockPieces>& pieces) {
  std::string s;
  auto put = [&](const void* p, size_t n) { s.append(static_cast<const char*>(p), n); };
  for (const auto& [k, bp] : pieces) {
    const int64_t n = static_cast<int64_t>(bp.info.size());
    put(&k, sizeof k);
    put(&n, sizeof n);
    put(bp.info.data(), bp.info.size() * sizeof(ComponentInfo));
    put(bp.border.data(), bp.border.size());
    for (const auto& f : bp.faces) {
      const int64_t m = static_cast<int64_t>(f.size());
      put(&m, sizeof m);
      put(f.data(), f.size() * sizeof(FaceRun));
    }
  }
  return s;
}

void unpack_pieces(const std::string& s, std::map<int64_t, BlockPieces>& pieces) {
  size_t pos = 0;
  auto get = [&](void* p, size_t n) {
    if (pos + n > s.size()) throw Error("components: truncated piece list from another rank");
    if (n == 0) return;  // p is the data() of an empty vector, maybe null: memcpy(nullptr, ..., 0) is undefined
    std::memcpy(p, s.data() + pos, n);
    pos += n;
  };
  while (pos < s.size()) {
    int64_t k = 0, n = 0;
    get(&k, sizeof k);
    get(&n, sizeof n);
    BlockPieces& bp = pieces[k];
    bp.info.resize(static_cast<size_t>(n));
    bp.border.resize(static_cast<size_t>(n));
    get(bp.info.data(), bp.info.size() * sizeof(ComponentInfo));
    get(bp.border.data(), bp.border.size());
    for (auto& f : bp.faces) {
      int64_t m = 0;
      get(&m, sizeof m);
      f.resize(static_cast<size_t>(m));
      get(f.data(), f.size() * sizeof(FaceRun));
    }
  }
}

// Pass 1 over the blocks: the pieces of every block (statistics in global coordinates, whether they
// touch a face of the array, and the block's six faces), held in memory — no volume is written.
// Then, in memory, the pieces that touch across block faces, edges and corners (per connectivity)
// are united. Pass 2 (the caller's) reads each block again and labels it from block_runs().
Provisional provisional_components(const DataObject& mask, const Grid& g, int conn, bool background,
                                   const BlockLayout& layout, int threads, const std::function<void()>& block_done) {
  const Dims n = layout.count();
  auto linear = [&](const Block& b) { return (b.index[2] * n[1] + b.index[1]) * n[0] + b.index[0]; };
  std::map<int64_t, BlockPieces> pieces;
  auto pass = [&](const Block& b) {
    const VolumeU8 m = read_mask_block(mask, b.begin, b.size, "input 'mask'");
    const BlockRuns br = block_runs(m, conn, background, threads);
    const Runs& r = br.runs;
    BlockPieces& bp = pieces[linear(b)];
    bp.info.resize(static_cast<size_t>(br.pieces));
    bp.border.assign(static_cast<size_t>(br.pieces), 0);
    for (int64_t row = 0; row < b.size[1] * b.size[2]; ++row) {
      const int64_t gy = b.begin[1] + row % b.size[1], gz = b.begin[2] + row / b.size[1];
      const bool face_row = gy == 0 || gz == 0 || gy == g.dims[1] - 1 || gz == g.dims[2] - 1;
      for (int64_t i = r.row_start[static_cast<size_t>(row)]; i < r.row_start[static_cast<size_t>(row + 1)]; ++i) {
        const auto si = static_cast<size_t>(i);
        const auto id = static_cast<size_t>(br.piece[si]);
        const int64_t x0 = b.begin[0] + r.x0[si], x1 = b.begin[0] + r.x1[si];
        if (bp.info[id].voxels == 0) bp.info[id].first = g.index(x0, gy, gz);
        add_run(bp.info[id], x0, x1 - 1, gy, gz);
        if (face_row || x0 == 0 || x1 == g.dims[0]) bp.border[id] = 1;
      }
    }
    bp.faces = block_faces(br, b.size);
    block_done();
    // With --resume the block's pieces and faces are its payload (a kept block gives them back).
    return distributing() || current_block_journal() == nullptr ? std::string() : pack_pieces({{linear(b), bp}});
  };
  if (distributing()) {
    for_each_owned_block(layout, Interrupter(), "components", [&](const Block& b) { (void)pass(b); });
    const std::vector<std::string> all = exchange(pack_pieces(pieces));
    pieces.clear();
    for (const auto& s : all) unpack_pieces(s, pieces);
  } else {  // resumable per block (--resume)
    ResumablePass resumable;
    int64_t index = 0;
    for (int64_t bz = 0; bz < n[2]; ++bz)
      for (int64_t by = 0; by < n[1]; ++by)
        for (int64_t bx = 0; bx < n[0]; ++bx, ++index) {
          if (const std::string* p = resumable.kept(index)) {
            unpack_pieces(*p, pieces);
            block_done();
            continue;
          }
          resumable.commit(index, pass(layout.at(bx, by, bz)));
        }
  }
  Provisional pv;
  pv.count = n;
  pv.offset.assign(static_cast<size_t>(layout.total()), 0);
  for (int64_t k = 0; k < layout.total(); ++k) {
    pv.offset[static_cast<size_t>(k)] = static_cast<int64_t>(pv.info.size());
    const auto it = pieces.find(k);
    if (it == pieces.end()) continue;
    pv.info.insert(pv.info.end(), it->second.info.begin(), it->second.info.end());
    pv.border.insert(pv.border.end(), it->second.border.begin(), it->second.border.end());
  }
  UnionFind uf(static_cast<int64_t>(pv.info.size()));
  std::vector<std::array<int, 3>> steps;
  for (int dz = -1; dz <= 1; ++dz)
    for (int dy = -1; dy <= 1; ++dy)
      for (int dx = -1; dx <= 1; ++dx) {
        const int k = std::abs(dx) + std::abs(dy) + std::abs(dz);
        if (k > 0 && (k == 1 || (k == 2 && conn >= 18) || conn == 26)) steps.push_back({dx, dy, dz});
      }
  // The local id of global voxel q, which lies in block c next to another block: q is on a face of c.
  auto id_of = [&](const Block& c, const BlockPieces& cp, int64_t x, int64_t y, int64_t z) -> uint64_t {
    const int64_t lx = x - c.begin[0], ly = y - c.begin[1], lz = z - c.begin[2];
    if (lx == 0) return face_id(cp.faces[0], ly, lz);
    if (lx == c.size[0] - 1) return face_id(cp.faces[1], ly, lz);
    if (ly == 0) return face_id(cp.faces[2], lx, lz);
    if (ly == c.size[1] - 1) return face_id(cp.faces[3], lx, lz);
    if (lz == 0) return face_id(cp.faces[4], lx, ly);
    if (lz == c.size[2] - 1) return face_id(cp.faces[5], lx, ly);
    return 0;  // not reached: a voxel next to another block lies on a face
  };
  for (int64_t bz = 0; bz < n[2]; ++bz)
    for (int64_t by = 0; by < n[1]; ++by)
      for (int64_t bx = 0; bx < n[0]; ++bx) {
        const Block a = layout.at(bx, by, bz);
        const auto ia = pieces.find(linear(a));
        if (ia == pieces.end()) continue;
        for (int f = 0; f < 6; ++f)
          for (const FaceRun& e : ia->second.faces[static_cast<size_t>(f)]) {
            const int64_t ga = pv.global(bx, by, bz, e.id);
            for (int64_t u = e.u0; u < e.u1; ++u) {
              // The face point (u, v) in global coordinates.
              int64_t x = 0, y = 0, z = 0;
              if (f < 2) {
                x = a.begin[0] + (f == 0 ? 0 : a.size[0] - 1), y = a.begin[1] + u, z = a.begin[2] + e.v;
              } else if (f < 4) {
                x = a.begin[0] + u, y = a.begin[1] + (f == 2 ? 0 : a.size[1] - 1), z = a.begin[2] + e.v;
              } else {
                x = a.begin[0] + u, y = a.begin[1] + e.v, z = a.begin[2] + (f == 4 ? 0 : a.size[2] - 1);
              }
              for (const auto& d : steps) {
                const int64_t qx = x + d[0], qy = y + d[1], qz = z + d[2];
                if (qx < 0 || qy < 0 || qz < 0 || qx >= g.dims[0] || qy >= g.dims[1] || qz >= g.dims[2]) continue;
                if (qx >= a.begin[0] && qy >= a.begin[1] && qz >= a.begin[2] && qx < a.begin[0] + a.size[0] &&
                    qy < a.begin[1] + a.size[1] && qz < a.begin[2] + a.size[2])
                  continue;  // inside this block: united by block_runs
                const int64_t cx = qx / layout.block[0], cy = qy / layout.block[1], cz = qz / layout.block[2];
                const auto ic = pieces.find((cz * n[1] + cy) * n[0] + cx);
                if (ic == pieces.end()) continue;
                if (const uint64_t q = id_of(layout.at(cx, cy, cz), ic->second, qx, qy, qz))
                  uf.unite(ga, pv.global(cx, cy, cz, q));
              }
            }
          }
      }
  pieces.clear();
  uf.flatten();
  pv.root = std::move(uf).release();
  return pv;
}

void check_block_volume(const ChunkedVolume& v, const Grid& g, const char* type, const char* what) {
  if (v.dims() != g.dims || v.type_id() != type)
    throw Error(std::string(what) + ": an on-disk " + type + " volume with the mask's grid is needed");
}

}  // namespace

BlockComponentsResult connected_components_blocks(const DataObject& mask, const ChunkedVolume& labels,
                                                  const ChunkedVolume& kept, const ComponentOptions& o,
                                                  const Dims& block) {
  const int conn = static_cast<int>(o.connectivity);
  check_connectivity(conn);
  const Grid& g = any_volume_grid(mask, "input 'mask'");
  check_block_volume(labels, g, type_ids::volume_u32, "connected_components_blocks: labels");
  check_block_volume(kept, g, type_ids::volume_u8, "connected_components_blocks: mask");
  const BlockLayout layout(g.dims, block, 0);
  const Dims n = layout.count();
  const int64_t total = 2 * layout.total();
  int64_t done = 0;
  report_blocks(o.interrupter, "components", 0, total);
  auto block_done = [&] { report_blocks(o.interrupter, "components", ++done, total); };
  const Provisional pv = provisional_components(mask, g, conn, false, layout, o.threads, block_done);
  const std::vector<ComponentInfo>& info = pv.info;
  const std::vector<int64_t>& root = pv.root;
  // Components = roots, statistics merged, ordered by first voxel, then labelled as in memory.
  std::vector<int64_t> index_of_root(info.size(), -1);
  std::vector<ComponentInfo> comps;
  for (size_t i = 0; i < info.size(); ++i) {
    const auto r = static_cast<size_t>(root[i]);
    if (index_of_root[r] < 0) {
      index_of_root[r] = static_cast<int64_t>(comps.size());
      comps.push_back(info[i]);
      continue;
    }
    ComponentInfo& c = comps[static_cast<size_t>(index_of_root[r])];
    const ComponentInfo& e = info[i];
    for (int a = 0; a < 3; ++a) {
      c.lo[a] = std::min(c.lo[a], e.lo[a]);
      c.hi[a] = std::max(c.hi[a], e.hi[a]);
      c.sum[a] += e.sum[a];
    }
    c.voxels += e.voxels;
    c.first = std::min(c.first, e.first);
  }
  std::vector<size_t> by_first(comps.size());
  std::iota(by_first.begin(), by_first.end(), size_t{0});
  std::sort(by_first.begin(), by_first.end(), [&](size_t a, size_t b) { return comps[a].first < comps[b].first; });
  std::vector<ComponentInfo> ordered(comps.size());
  std::vector<size_t> rank(comps.size());
  for (size_t k = 0; k < by_first.size(); ++k) {
    ordered[k] = comps[by_first[k]];
    rank[by_first[k]] = k;
  }
  std::vector<size_t> order;
  uint32_t count = 0;
  std::string warning;
  const std::vector<uint32_t> label_of = label_components(ordered, o, order, count, warning);
  std::vector<uint32_t> label_of_provisional(info.size());
  for (size_t i = 0; i < info.size(); ++i)
    label_of_provisional[i] = label_of[rank[static_cast<size_t>(index_of_root[static_cast<size_t>(root[i])])]];
  // Final labels and the mask of the kept components (each rank its blocks when distributing).
  auto label_block = [&](const Block& b) {
    const VolumeU8 m = read_mask_block(mask, b.begin, b.size, "input 'mask'");
    const BlockRuns br = block_runs(m, conn, false, o.threads);
    const Runs& r = br.runs;
    VolumeU32 l(m.grid(), 0u);
    VolumeU8 k(m.grid(), 0);
    const int64_t sx = b.size[0];
    for (int64_t row = 0; row < b.size[1] * b.size[2]; ++row)
      for (int64_t i = r.row_start[static_cast<size_t>(row)]; i < r.row_start[static_cast<size_t>(row + 1)]; ++i) {
        const auto si = static_cast<size_t>(i);
        const uint32_t lab = label_of_provisional[static_cast<size_t>(
            pv.global(b.index[0], b.index[1], b.index[2], static_cast<uint64_t>(br.piece[si]) + 1))];
        if (!lab) continue;
        std::fill(l.data() + row * sx + r.x0[si], l.data() + row * sx + r.x1[si], lab);
        std::fill(k.data() + row * sx + r.x0[si], k.data() + row * sx + r.x1[si], uint8_t{1});
      }
    labels.write(l, b.begin);
    kept.write(k, b.begin);
    block_done();
  };
  if (distributing()) {
    for_each_owned_block(layout, Interrupter(), "components", label_block);
  } else {  // resumable per block (--resume): reads the work volume, which no later pass changes
    ResumablePass pass;
    int64_t index = 0;
    for (int64_t bz = 0; bz < n[2]; ++bz)
      for (int64_t by = 0; by < n[1]; ++by)
        for (int64_t bx = 0; bx < n[0]; ++bx, ++index) {
          if (pass.kept(index)) {
            block_done();
            continue;
          }
          label_block(layout.at(bx, by, bz));
          pass.commit(index);
        }
  }
  BlockComponentsResult res;
  res.count = count;
  res.warning = std::move(warning);
  res.table = component_table(ordered, order, label_of, g);
  return res;
}

namespace {

// Runs of the object (or background) united with `connectivity`; every run points at its root
// (parent[i] = root) and border[root] = 1 when the component has a voxel on an array face.
struct RootedRuns {
  Runs runs;
  std::vector<int64_t> root;
  std::vector<uint8_t> border;
};
RootedRuns rooted_runs(const VolumeU8& mask, int connectivity, bool background, int threads,
                       const Interrupter& interrupter) {
  check_connectivity(connectivity);
  if (mask.nx() >= (int64_t{1} << 31) - 1) throw InputError("components: nx must be < 2^31 - 1");
  const int64_t nx = mask.nx(), ny = mask.ny(), nz = mask.nz();
  RootedRuns rr;
  rr.runs = extract_runs(mask, threads, background);
  interrupter.check(0.3);
  rr.root = union_runs(rr.runs, ny, nz, connectivity, threads, interrupter);
  interrupter.check(0.8);
  // parent[i] <= i: one forward pass takes every run to its root; a root collects the border flag.
  const Runs& r = rr.runs;
  rr.border.assign(r.x0.size(), 0);
  for (int64_t row = 0; row < ny * nz; ++row) {
    const int64_t y = row % ny, z = row / ny;
    const bool face_row = y == 0 || z == 0 || y == ny - 1 || z == nz - 1;
    for (int64_t i = r.row_start[static_cast<size_t>(row)]; i < r.row_start[static_cast<size_t>(row + 1)]; ++i) {
      const auto si = static_cast<size_t>(i);
      const int64_t root = rr.root[static_cast<size_t>(rr.root[si])];
      rr.root[si] = root;
      if (face_row || r.x0[si] == 0 || r.x1[si] == nx) rr.border[static_cast<size_t>(root)] = 1;
    }
  }
  return rr;
}

}  // namespace

ComponentCount count_components(const VolumeU8& mask, int connectivity, bool background, int threads,
                                const Interrupter& interrupter) {
  ComponentCount c;
  const RootedRuns rr = rooted_runs(mask, connectivity, background, threads, interrupter);
  for (size_t i = 0; i < rr.root.size(); ++i) {
    if (rr.root[i] != static_cast<int64_t>(i)) continue;
    ++c.components;
    c.touching_border += rr.border[i];
  }
  interrupter.check(1.0);
  return c;
}

VolumeU8 fill_cavities(const VolumeU8& mask, int64_t* filled, int threads) {
  // Background 6-components without a voxel on an array face are cavities: their runs become object.
  const RootedRuns rr = rooted_runs(mask, 6, true, threads, {});
  VolumeU8 out(mask.grid(), 0);
  const uint8_t* m = mask.data();
  const int64_t nx = mask.nx(), rows = mask.ny() * mask.nz();
  std::vector<int64_t> row_filled(static_cast<size_t>(rows), 0);
  parallel_for(0, rows, threads, [&](int64_t b, int64_t e) {
    for (int64_t row = b; row < e; ++row) {
      uint8_t* o = out.data() + row * nx;
      for (int64_t x = 0; x < nx; ++x) o[x] = m[row * nx + x] != 0;
      const Runs& r = rr.runs;
      for (int64_t i = r.row_start[static_cast<size_t>(row)]; i < r.row_start[static_cast<size_t>(row + 1)]; ++i) {
        const auto si = static_cast<size_t>(i);
        if (rr.border[static_cast<size_t>(rr.root[si])]) continue;
        std::fill(o + r.x0[si], o + r.x1[si], uint8_t{1});
        row_filled[static_cast<size_t>(row)] += r.x1[si] - r.x0[si];
      }
    }
  }, 64);
  if (filled) {
    int64_t f = 0;
    for (int64_t v : row_filled) f += v;
    *filled = f;
  }
  return out;
}

int64_t fill_cavities_blocks(const DataObject& mask, const ChunkedVolume& out, const Dims& block, int threads,
                             const Interrupter& interrupter) {
  const Grid& g = any_volume_grid(mask, "input 'mask'");
  check_block_volume(out, g, type_ids::volume_u8, "fill_cavities_blocks: output");
  const BlockLayout layout(g.dims, block, 0);
  const int64_t total = 2 * layout.total();
  int64_t done = 0;
  report_blocks(interrupter, "fill_cavities", 0, total);
  auto block_done = [&] { report_blocks(interrupter, "fill_cavities", ++done, total); };
  // Background 6-components (pieces united across blocks); a component touching a face is no cavity.
  const Provisional pv = provisional_components(mask, g, 6, true, layout, threads, block_done);
  std::vector<uint8_t> open(pv.info.size(), 0);
  for (size_t i = 0; i < pv.info.size(); ++i)
    if (pv.border[i]) open[static_cast<size_t>(pv.root[i])] = 1;
  int64_t filled = 0;
  const Dims n = layout.count();
  // Fills the cavities of block b into `out`; returns the voxels filled.
  auto fill_block = [&](const Block& b) {
    const int64_t bx = b.index[0], by = b.index[1], bz = b.index[2];
    int64_t here = 0;
    VolumeU8 m = read_mask_block(mask, b.begin, b.size, "input 'mask'");
        const BlockRuns br = block_runs(m, 6, true, threads);
        const Runs& r = br.runs;
        for (uint8_t& v : m) v = v != 0;
        for (int64_t row = 0; row < b.size[1] * b.size[2]; ++row)
          for (int64_t i = r.row_start[static_cast<size_t>(row)]; i < r.row_start[static_cast<size_t>(row + 1)]; ++i) {
            const auto si = static_cast<size_t>(i);
            const int64_t piece = pv.global(bx, by, bz, static_cast<uint64_t>(br.piece[si]) + 1);
            if (open[static_cast<size_t>(pv.root[static_cast<size_t>(piece)])]) continue;
            std::fill(m.data() + row * b.size[0] + r.x0[si], m.data() + row * b.size[0] + r.x1[si], uint8_t{1});
            here += r.x1[si] - r.x0[si];
          }
    out.write(m, b.begin);
    return here;
  };
  if (distributing()) {  // skelflow-mpi: each rank fills its blocks of the shared output
    for_each_owned_block(layout, Interrupter(), "fill_cavities", [&](const Block& b) {
      filled += fill_block(b);
      block_done();
    });
    return sum_over_ranks(filled);
  }
  ResumablePass pass;  // per block (--resume), each committing its filled count
  int64_t index = 0;
  for (int64_t bz = 0; bz < n[2]; ++bz)
    for (int64_t by = 0; by < n[1]; ++by)
      for (int64_t bx = 0; bx < n[0]; ++bx, ++index) {
        if (const std::string* p = pass.kept(index)) {
          filled += payload_as<int64_t>(*p);
          block_done();
          continue;
        }
        const int64_t here = fill_block(layout.at(bx, by, bz));
        filled += here;
        pass.commit(index, payload_of(here));
        block_done();
      }
  return filled;
}

}  // namespace skel::segmentation
