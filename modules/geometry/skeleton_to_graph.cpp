#include "geometry/skeleton_to_graph.hpp"

#include <algorithm>
#include <bit>
#include <cmath>
#include <cstring>
#include <functional>
#include <map>
#include <numeric>
#include <set>
#include <unordered_map>

#include "geometry/skeleton_to_graph_phases.hpp"
#include "skel/block_journal.hpp"
#include "skel/distributed.hpp"
#include "skel/error.hpp"
#include "skel/out_of_core.hpp"
#include "skel/parallel.hpp"
#include "skel/union_find.hpp"

namespace skel::geometry {

namespace {

constexpr int kPairs = 28;

struct PairTable {
  std::array<std::array<int, 2>, kPairs> pairs{};
  std::array<std::array<int, 8>, 8> index{};
  PairTable() {
    int p = 0;
    for (int a = 0; a < 8; ++a)
      for (int b = a + 1; b < 8; ++b) {
        pairs[p] = {a, b};
        index[a][b] = index[b][a] = p;
        ++p;
      }
  }
};
const PairTable& pair_table() {
  static const PairTable t;
  return t;
}

// Rank of a set of GF(2) vectors (edge masks) given as a reduced basis; returns true if `v` was
// independent and was added.
bool add_to_basis(std::vector<uint32_t>& basis, uint32_t v) {
  for (uint32_t b : basis) v = std::min(v, v ^ b);
  if (v == 0) return false;
  basis.push_back(v);
  std::sort(basis.begin(), basis.end(), std::greater<>());
  return true;
}

DualCubeEntry build_entry(int config) {
  const auto& pt = pair_table();
  DualCubeEntry e;
  const int nv = std::popcount(static_cast<unsigned>(config));
  auto fg = [&](int k) { return (config >> k & 1) != 0; };
  // 1-cells (fig. 3.6).
  for (int p = 0; p < kPairs; ++p) {
    const int a = pt.pairs[p][0], b = pt.pairs[p][1];
    if (!fg(a) || !fg(b)) continue;
    const int d = a ^ b;
    const int bits = std::popcount(static_cast<unsigned>(d));
    bool add = false;
    if (bits == 1) {
      add = true;
    } else if (bits == 2) {
      const int lo = d & -d, hi = d ^ lo;
      add = !fg(a ^ lo) && !fg(a ^ hi);
    } else {
      add = nv == 2;
    }
    if (add) e.edges |= 1u << p;
  }
  // Reduced dual cube: corner 0, its three edges and three faces, and the interior. A 1-cell belongs
  // to it iff it is not contained in a face or edge with some coordinate fixed at 1, i.e. iff the
  // two corners share no coordinate equal to 1.
  for (int p = 0; p < kPairs; ++p)
    if ((e.edges >> p & 1) && (pt.pairs[p][0] & pt.pairs[p][1]) == 0) e.reduced_edges |= 1u << p;
  // Simple cycles of the 1-skeleton (as edge masks), found by DFS from their smallest vertex.
  std::set<uint32_t> cycle_set;
  std::vector<int> path;
  std::function<void(int, int, uint32_t)> dfs = [&](int start, int v, uint32_t used) {
    for (int w = 0; w < 8; ++w) {
      if (w == v || !fg(w)) continue;
      const int p = pt.index[v][w];
      if (!(e.edges >> p & 1) || (used >> p & 1)) continue;
      if (w == start) {
        if (path.size() >= 3) cycle_set.insert(used | 1u << p);
        continue;
      }
      if (w < start || std::find(path.begin(), path.end(), w) != path.end()) continue;
      path.push_back(w);
      dfs(start, w, used | 1u << p);
      path.pop_back();
    }
  };
  for (int s = 0; s < 8; ++s) {
    if (!fg(s)) continue;
    path = {s};
    dfs(s, s, 0);
  }
  std::vector<uint32_t> cycles(cycle_set.begin(), cycle_set.end());
  std::stable_sort(cycles.begin(), cycles.end(), [](uint32_t a, uint32_t b) {
    return std::popcount(a) < std::popcount(b);
  });
  // Components of the 1-skeleton, for the rank of the cycle space (E - V + C).
  std::array<int, 8> comp{};
  for (int k = 0; k < 8; ++k) comp[k] = k;
  auto root = [&](int k) {
    while (comp[k] != k) k = comp[k];
    return k;
  };
  for (int p = 0; p < kPairs; ++p)
    if (e.edges >> p & 1) comp[root(pt.pairs[p][0])] = root(pt.pairs[p][1]);
  int ncomp = 0;
  for (int k = 0; k < 8; ++k)
    if (fg(k) && root(k) == k) ++ncomp;
  const int ne = std::popcount(e.edges);
  const int rank_needed = ne - nv + ncomp;
  // 2-cells: shortest cycles first; all cycles of one length that are independent of the shorter
  // ones are attached together (symmetry), until the cycle space is spanned.
  std::vector<uint32_t> basis;
  size_t i = 0;
  while (i < cycles.size() && static_cast<int>(basis.size()) < rank_needed) {
    const int len = std::popcount(cycles[i]);
    size_t j = i;
    while (j < cycles.size() && std::popcount(cycles[j]) == len) ++j;
    const std::vector<uint32_t> shorter = basis;
    for (size_t c = i; c < j; ++c) {
      std::vector<uint32_t> test = shorter;
      if (!add_to_basis(test, cycles[c])) continue;
      add_to_basis(basis, cycles[c]);
      DualCubeCell2 cell;
      cell.edges = cycles[c];
      for (int p = 0; p < kPairs; ++p)
        if (cycles[c] >> p & 1) cell.vertices |= static_cast<uint8_t>(1u << pt.pairs[p][0] | 1u << pt.pairs[p][1]);
      for (int f = 0; f < 6 && cell.face < 0; ++f) {
        const int axis = f / 2, side = f % 2;
        bool on = true;
        for (int k = 0; k < 8; ++k)
          if ((cell.vertices >> k & 1) && ((k >> axis & 1) != side)) on = false;
        if (on) cell.face = static_cast<int8_t>(f);
      }
      e.cells2.push_back(cell);
    }
    i = j;
  }
  e.euler = nv - ne + static_cast<int>(e.cells2.size());
  e.cell3 = e.euler == 2;
  return e;
}

// 27-neighbourhood position of offset (dx, dy, dz) in {-1, 0, 1}^3.
inline int nb_pos(int dx, int dy, int dz) { return (dx + 1) + 3 * (dy + 1) + 9 * (dz + 1); }

struct Accessor {
  const uint8_t* data;
  int64_t nx, ny, nz;
  [[nodiscard]] bool fg(int64_t x, int64_t y, int64_t z) const {
    return x >= 0 && y >= 0 && z >= 0 && x < nx && y < ny && z < nz && data[x + nx * (y + ny * z)] != 0;
  }
  // 27-neighbourhood of (x, y, z) as a mask, bit nb_pos(dx, dy, dz).
  [[nodiscard]] uint32_t neighbourhood(int64_t x, int64_t y, int64_t z) const {
    uint32_t m = 0;
    if (x >= 1 && y >= 1 && z >= 1 && x + 1 < nx && y + 1 < ny && z + 1 < nz) {
      const uint8_t* p = data + (x - 1) + nx * ((y - 1) + ny * (z - 1));
      int bit = 0;
      for (int dz = 0; dz < 3; ++dz)
        for (int dy = 0; dy < 3; ++dy)
          for (int dx = 0; dx < 3; ++dx, ++bit)
            if (p[dx + nx * (dy + ny * dz)]) m |= 1u << bit;
      return m;
    }
    int bit = 0;
    for (int dz = -1; dz <= 1; ++dz)
      for (int dy = -1; dy <= 1; ++dy)
        for (int dx = -1; dx <= 1; ++dx, ++bit)
          if (fg(x + dx, y + dy, z + dz)) m |= 1u << bit;
    return m;
  }
};

// Configuration of the dual cube in which the voxel with 27-neighbourhood `hood` is corner k (the
// cube's lowest corner lies at the voxel minus the bits of k).
inline int cube_config(uint32_t hood, int k) {
  const int ox = -(k & 1), oy = -(k >> 1 & 1), oz = -(k >> 2 & 1);
  int cfg = 0;
  for (int j = 0; j < 8; ++j)
    if (hood >> nb_pos(ox + (j & 1), oy + (j >> 1 & 1), oz + (j >> 2 & 1)) & 1) cfg |= 1 << j;
  return cfg;
}

ManifoldType classify_voxel(uint32_t hood, const std::vector<DualCubeEntry>& table) {
  const auto& pt = pair_table();
  uint32_t nb = 0;
  std::array<int, 27> count2{};
  std::array<uint32_t, 16> faces_seen{};
  int nfaces = 0;
  bool any2 = false, three = false;
  for (int c = 0; c < 8; ++c) {
    // v is corner k of the cube with lowest corner v - bits(k).
    const int k = c;
    const int ox = -(k & 1), oy = -(k >> 1 & 1), oz = -(k >> 2 & 1);
    const DualCubeEntry& t = table[cube_config(hood, k)];
    auto corner_pos = [&](int j) { return nb_pos(ox + (j & 1), oy + (j >> 1 & 1), oz + (j >> 2 & 1)); };
    for (int j = 0; j < 8; ++j)
      if (j != k && (t.edges >> pt.index[k][j] & 1)) nb |= 1u << corner_pos(j);
    bool in2 = false;
    for (const auto& cell : t.cells2) {
      if (!(cell.vertices >> k & 1)) continue;
      in2 = true;
      if (cell.face >= 0) {
        uint32_t key = 0;
        for (int j = 0; j < 8; ++j)
          if (cell.vertices >> j & 1) key |= 1u << corner_pos(j);
        bool seen = false;
        for (int f = 0; f < nfaces; ++f) seen = seen || faces_seen[f] == key;
        if (seen) continue;
        faces_seen[nfaces++] = key;
      }
      for (int j = 0; j < 8; ++j)
        if (j != k && (cell.edges >> pt.index[k][j] & 1)) ++count2[corner_pos(j)];
    }
    any2 = any2 || in2;
    three = three || (t.cell3 && in2);
  }
  const int n1 = std::popcount(nb);
  if (n1 == 0) return ManifoldType::point;
  int bare = 0, one = 0, two = 0, more = 0;
  for (int p = 0; p < 27; ++p) {
    if (!(nb >> p & 1)) continue;
    if (count2[p] == 0) ++bare;
    else if (count2[p] == 1) ++one;
    else if (count2[p] == 2) ++two;
    else ++more;
  }
  if (!any2) {
    if (n1 == 2) return ManifoldType::line;
    if (n1 == 1) return ManifoldType::line_end;
    return ManifoldType::line_junction;
  }
  if (!three && bare == 0 && more == 0) {
    if (one == 0) return ManifoldType::surface;
    if (one == 2) return ManifoldType::surface_edge;
  }
  return bare > 0 ? ManifoldType::line_junction : ManifoldType::junction;
}

// Sorted linear indices of the object voxels (deterministic for any thread count).
std::vector<int64_t> object_voxels(const VolumeU8& v, int threads, const Interrupter& intr) {
  const int64_t nz = v.nz(), slice = v.nx() * v.ny();
  const int64_t chunks = std::min<int64_t>(std::max<int64_t>(nz, 1), 256);
  std::vector<std::vector<int64_t>> parts(chunks);
  parallel_chunks(0, nz, chunks, threads, [&](int64_t c, int64_t z0, int64_t z1) {
    const uint8_t* d = v.data();
    for (int64_t i = z0 * slice; i < z1 * slice; ++i)
      if (d[i]) parts[c].push_back(i);
    intr.check();
  });
  std::vector<int64_t> out;
  size_t total = 0;
  for (auto& p : parts) total += p.size();
  out.reserve(total);
  for (auto& p : parts) out.insert(out.end(), p.begin(), p.end());
  return out;
}

}  // namespace

std::array<int, 2> dual_cube_pair(int p) { return pair_table().pairs[p]; }

const std::vector<DualCubeEntry>& dual_cube_table() {
  static const std::vector<DualCubeEntry> table = [] {
    std::vector<DualCubeEntry> t;
    t.reserve(256);
    for (int c = 0; c < 256; ++c) t.push_back(build_entry(c));
    return t;
  }();
  return table;
}

VolumeU8 classify_manifold(const VolumeU8& skeleton, int threads, const Interrupter& interrupter) {
  const auto& table = dual_cube_table();
  const auto voxels = object_voxels(skeleton, threads, interrupter);
  VolumeU8 out(skeleton.grid(), 0);
  const Accessor acc{skeleton.data(), skeleton.nx(), skeleton.ny(), skeleton.nz()};
  const int64_t n = static_cast<int64_t>(voxels.size());
  parallel_for(0, n, threads, [&](int64_t b, int64_t e) {
    for (int64_t i = b; i < e; ++i) {
      const int64_t idx = voxels[i];
      const int64_t x = idx % acc.nx, y = idx / acc.nx % acc.ny, z = idx / (acc.nx * acc.ny);
      out[idx] = static_cast<uint8_t>(classify_voxel(acc.neighbourhood(x, y, z), table));
    }
    interrupter.check();
  }, 4096);
  return out;
}

void smooth_edges(SpatialGraph& graph, int passes, int kernel) {
  if (passes <= 0 || kernel < 3) return;
  const int half = kernel / 2;
  const double sigma = std::max(1.0, kernel / 4.0);
  std::vector<double> w(half + 1);
  for (int i = 0; i <= half; ++i) w[i] = std::exp(-0.5 * i * i / (sigma * sigma));
  std::vector<Vec3> tmp;
  for (auto& edge : graph.edges) {
    auto& p = edge.points;
    const int64_t n = static_cast<int64_t>(p.size());
    if (n < 3) continue;
    for (int pass = 0; pass < passes; ++pass) {
      tmp = p;
      for (int64_t i = 1; i + 1 < n; ++i) {
        const int64_t h = std::min<int64_t>({half, i, n - 1 - i});
        Vec3 acc{0, 0, 0};
        double ws = 0.0;
        for (int64_t d = -h; d <= h; ++d) {
          const double wd = w[std::abs(d)];
          for (int a = 0; a < 3; ++a) acc[a] += wd * tmp[i + d][a];
          ws += wd;
        }
        for (int a = 0; a < 3; ++a) p[i][a] = acc[a] / ws;
      }
    }
  }
}
namespace detail {

SkeletonVoxels collect_voxels(const VolumeU8& skeleton, int threads, const Interrupter& intr) {
  SkeletonVoxels sv;
  sv.grid = skeleton.grid();
  sv.vox = object_voxels(skeleton, threads, intr);
  const Accessor acc{skeleton.data(), skeleton.nx(), skeleton.ny(), skeleton.nz()};
  const int64_t nx = acc.nx, nxy = acc.nx * acc.ny;
  const int64_t n = sv.size();
  sv.hood.resize(static_cast<size_t>(n));
  parallel_for(0, n, threads, [&](int64_t b, int64_t e) {
    for (int64_t i = b; i < e; ++i) {
      const int64_t idx = sv.vox[i];
      sv.hood[i] = acc.neighbourhood(idx % nx, idx / nx % acc.ny, idx / nxy);
    }
    intr.check();
  }, 4096);
  return sv;
}

SkeletonVoxels collect_voxels_blocks(const DataObject& skeleton, const Dims& block, const DataObject* distance,
                                     double scale, const Interrupter& intr) {
  const Grid& grid = any_volume_grid(skeleton, "input 'skeleton'");
  if (skeleton.type_id() != type_ids::volume_u8)
    throw InputError("input 'skeleton': expected " + std::string(type_ids::volume_u8) + ", got " + skeleton.type_id());
  if (distance != nullptr) {
    const Grid& dg = any_volume_grid(*distance, "input 'distance'");
    if (dg.dims != grid.dims)
      throw InputError("input 'distance': dims " + std::to_string(dg.dims[0]) + "x" + std::to_string(dg.dims[1]) + "x" +
                       std::to_string(dg.dims[2]) + " differ from the skeleton's " + std::to_string(grid.dims[0]) +
                       "x" + std::to_string(grid.dims[1]) + "x" + std::to_string(grid.dims[2]));
  }
  const int64_t nx = grid.dims[0], nxy = grid.dims[0] * grid.dims[1];
  std::vector<int64_t> vox;
  std::vector<uint32_t> hood;
  std::vector<double> rad;
  const BlockLayout layout(grid.dims, block, 1);
  // Resumable per block (--resume): a block commits the voxels it gathered (index, neighbourhood,
  // radius: 20 bytes per skeleton voxel), and a block kept from an earlier run adds them back.
  const bool journaled = current_block_journal() != nullptr;
  // The voxels gathered from index `first` on, as a block's payload (also what a rank sends for
  // each of its blocks when the ranks share the blocks).
  auto packed = [&](size_t first) {
    const auto n = static_cast<uint64_t>(vox.size() - first);
    std::string p(reinterpret_cast<const char*>(&n), sizeof n);
    p.append(reinterpret_cast<const char*>(vox.data() + first), n * sizeof(int64_t));
    p.append(reinterpret_cast<const char*>(hood.data() + first), n * sizeof(uint32_t));
    if (distance != nullptr) p.append(reinterpret_cast<const char*>(rad.data() + first), n * sizeof(double));
    return p;
  };
  auto gathered = [&](size_t first) { return journaled ? packed(first) : std::string(); };
  auto add_gathered = [&](const Block&, const std::string& p) {
    uint64_t n = 0;
    const size_t per = sizeof(int64_t) + sizeof(uint32_t) + (distance != nullptr ? sizeof(double) : 0);
    if (p.size() < sizeof n || (std::memcpy(&n, p.data(), sizeof n), p.size() != sizeof n + n * per))
      throw Error("resume journal: a skeleton_to_graph block's payload has " + std::to_string(p.size()) + " bytes");
    const char* at = p.data() + sizeof n;
    const size_t first = vox.size();
    vox.resize(first + n);
    hood.resize(first + n);
    std::memcpy(vox.data() + first, at, n * sizeof(int64_t));
    at += n * sizeof(int64_t);
    std::memcpy(hood.data() + first, at, n * sizeof(uint32_t));
    at += n * sizeof(uint32_t);
    if (distance != nullptr) {
      rad.resize(first + n);
      std::memcpy(rad.data() + first, at, n * sizeof(double));
    }
  };
  auto gather = [&](const Block& b) {
    // The block with a one-voxel halo (clipped to the grid, where the in-core accessor sees
    // background too): every interior voxel's 27-neighbourhood is the one of the whole volume.
    const VolumeU8 v = read_block<uint8_t>(skeleton, b.outer_begin, b.outer_size, "input 'skeleton'");
    const Accessor acc{v.data(), v.nx(), v.ny(), v.nz()};
    const size_t first = vox.size();
    for (int64_t z = 0; z < b.size[2]; ++z)
      for (int64_t y = 0; y < b.size[1]; ++y)
        for (int64_t x = 0; x < b.size[0]; ++x) {
          const int64_t lx = x + b.begin[0] - b.outer_begin[0], ly = y + b.begin[1] - b.outer_begin[1],
                        lz = z + b.begin[2] - b.outer_begin[2];
          if (v(lx, ly, lz) == 0) continue;
          vox.push_back((b.begin[0] + x) + nx * (b.begin[1] + y) + nxy * (b.begin[2] + z));
          hood.push_back(acc.neighbourhood(lx, ly, lz));
        }
    if (distance == nullptr || vox.size() == first) return gathered(first);
    visit_voxel_type(distance->type_id(), "input 'distance'", [&](auto tag) {
      using T = decltype(tag);
      const Volume<T> d = read_block<T>(*distance, b.begin, b.size, "input 'distance'");
      for (size_t k = first; k < vox.size(); ++k) {
        const int64_t idx = vox[k];
        const int64_t x = idx % nx - b.begin[0], y = idx / nx % grid.dims[1] - b.begin[1], z = idx / nxy - b.begin[2];
        rad.push_back(static_cast<double>(d(x, y, z)) * scale);
      }
    });
    return gathered(first);
  };
  if (distributing()) {
    // skelflow-mpi: each rank gathers its blocks; every rank adds every block's voxels in block
    // order, so the gathered voxels (and the graph built from them on every rank) are one process's.
    const Dims c = layout.count();
    auto block_at = [&](int64_t i) { return layout.at(i % c[0], (i / c[0]) % c[1], i / (c[0] * c[1])); };
    std::vector<double> costs(static_cast<size_t>(layout.total()));
    for (int64_t i = 0; i < layout.total(); ++i) {
      const Block b = block_at(i);
      costs[static_cast<size_t>(i)] = static_cast<double>(b.size[0] * b.size[1] * b.size[2]);
    }
    int64_t mine = 0;
    const std::vector<std::string> all = exchange_owned_items(layout.total(), costs, [&](int64_t i) {
      const size_t first = vox.size();
      (void)gather(block_at(i));
      std::string p = packed(first);
      vox.resize(first);
      hood.resize(first);
      if (distance != nullptr) rad.resize(first);
      report_blocks(intr, "skeleton_to_graph", ++mine, layout.total());
      return p;
    });
    for (int64_t i = 0; i < layout.total(); ++i) add_gathered(block_at(i), all[static_cast<size_t>(i)]);
  } else {
    for_each_block_resumable(layout, intr, "skeleton_to_graph", gather, add_gathered);
  }
  // Blocks come in block order; the phases want raster order (ids ascending by linear index).
  std::vector<int64_t> order(vox.size());
  std::iota(order.begin(), order.end(), int64_t{0});
  std::sort(order.begin(), order.end(), [&](int64_t a, int64_t b) { return vox[a] < vox[b]; });
  SkeletonVoxels sv;
  sv.grid = grid;
  sv.vox.resize(vox.size());
  sv.hood.resize(vox.size());
  for (size_t k = 0; k < order.size(); ++k) {
    sv.vox[k] = vox[order[k]];
    sv.hood[k] = hood[order[k]];
  }
  if (distance != nullptr) {
    sv.rad.resize(vox.size());
    for (size_t k = 0; k < order.size(); ++k) sv.rad[k] = rad[order[k]];
  }
  return sv;
}

void classify_voxels(SkeletonVoxels& sv, int threads, const Interrupter& intr) {
  const auto& table = dual_cube_table();
  const std::vector<uint32_t>& hood = sv.hood;
  const int64_t n = sv.size();
  std::vector<uint8_t>& cls = sv.cls;
  cls.resize(n);
  parallel_for(0, n, threads, [&](int64_t b, int64_t e) {
    for (int64_t i = b; i < e; ++i) cls[i] = static_cast<uint8_t>(classify_voxel(hood[i], table));
    intr.check();
  }, 4096);
}

void connect_one_cells(SkeletonVoxels& sv, int threads, const Interrupter& intr) {
  const auto& table = dual_cube_table();
  const int64_t nx = sv.grid.dims[0], ny = sv.grid.dims[1], nxy = nx * ny;
  const std::vector<int64_t>& vox = sv.vox;
  const int64_t n = sv.size();
  auto id_from = [&](int64_t i, int64_t idx) { return sv.id_from(i, idx); };
  const int64_t chunks = std::clamp<int64_t>(n / 4096, 1, 256);
  std::vector<std::vector<std::array<int64_t, 2>>> part_edges(chunks);
  const auto& pt = pair_table();
  parallel_chunks(0, n, chunks, threads, [&](int64_t c, int64_t b, int64_t e) {
    auto& out = part_edges[c];
    for (int64_t i = b; i < e; ++i) {
      const int64_t idx = vox[i];
      const int64_t x = idx % nx, y = idx / nx % ny, z = idx / nxy;
      for (int k = 0; k < 8; ++k) {
        const int64_t cx = x - (k & 1), cy = y - (k >> 1 & 1), cz = z - (k >> 2 & 1);
        const int cfg = cube_config(sv.hood[i], k);
        if (std::countr_zero(static_cast<unsigned>(cfg)) != k) continue;
        uint32_t m = table[cfg].reduced_edges;
        while (m) {
          const int p = std::countr_zero(m);
          m &= m - 1;
          const int a = pt.pairs[p][0], bb = pt.pairs[p][1];
          const int64_t ia = (cx + (a & 1)) + nx * ((cy + (a >> 1 & 1)) + ny * (cz + (a >> 2 & 1)));
          const int64_t ib = (cx + (bb & 1)) + nx * ((cy + (bb >> 1 & 1)) + ny * (cz + (bb >> 2 & 1)));
          out.push_back({id_from(i, ia), id_from(i, ib)});
        }
      }
    }
    intr.check();
  });
  // CSR adjacency between voxel ids.
  std::vector<int64_t> off(n + 1, 0);
  for (const auto& pe : part_edges)
    for (const auto& ed : pe) {
      ++off[ed[0] + 1];
      ++off[ed[1] + 1];
    }
  for (int64_t i = 0; i < n; ++i) off[i + 1] += off[i];
  std::vector<int64_t> adj(off[n]);
  {
    std::vector<int64_t> fill(off.begin(), off.end() - 1);
    for (const auto& pe : part_edges)
      for (const auto& ed : pe) {
        adj[fill[ed[0]]++] = ed[1];
        adj[fill[ed[1]]++] = ed[0];
      }
  }
  sv.off = std::move(off);
  sv.adj = std::move(adj);
}

void read_radius(SkeletonVoxels& sv, const DataObject& distance, double scale) {
  const int64_t n = sv.size();
  sv.rad.resize(n);
  visit_volume(distance, "distance", [&](const auto& d) {
    for (int64_t i = 0; i < n; ++i) sv.rad[i] = static_cast<double>(d[sv.vox[i]]) * scale;
  });
}

std::vector<int64_t> collapse_junctions(const SkeletonVoxels& sv) {
  const int64_t n = sv.size();
  const std::vector<int64_t>& off = sv.off;
  const std::vector<int64_t>& adj = sv.adj;
  auto is_line = [&](int64_t i) { return sv.is_line(i); };
  UnionFind collapsed(n);
  for (int64_t i = 0; i < n; ++i) {
    if (is_line(i)) continue;
    for (int64_t a = off[i]; a < off[i + 1]; ++a) {
      const int64_t j = adj[a];
      if (is_line(j)) continue;
      collapsed.unite(i, j);
    }
  }
  collapsed.flatten();  // every voxel points at its root (the smallest id of its node)
  return std::move(collapsed).release();
}

GraphBuild make_nodes(const SkeletonVoxels& sv, std::vector<int64_t>& parent, bool with_radius) {
  const int64_t n = sv.size();
  const std::vector<uint8_t>& cls = sv.cls;
  const std::vector<double>& rad = sv.rad;
  auto is_node_voxel = [&](int64_t i) { return sv.is_node_voxel(i); };
  auto pos = [&](int64_t i) { return sv.position(i); };
  GraphBuild b;
  b.with_radius = with_radius;
  SpatialGraph& g = b.graph;
  g.source_grid = sv.grid;
  g.unit = g.source_grid.unit;
  std::vector<int64_t>& node_of = b.node_of;
  node_of.assign(n, -1);
  std::vector<Vec3> sum;
  std::vector<int64_t> members;
  std::vector<double>& node_rad = b.node_rad;
  std::vector<int32_t>& node_kind = b.node_kind;
  for (int64_t i = 0; i < n; ++i) {
    if (!is_node_voxel(i)) continue;
    const int64_t r = parent[i];
    if (node_of[r] < 0) {
      node_of[r] = static_cast<int64_t>(sum.size());
      sum.push_back({0, 0, 0});
      members.push_back(0);
      node_rad.push_back(0.0);
      node_kind.push_back(0);
    }
    const int64_t nd = node_of[r];
    node_of[i] = nd;
    const Vec3 p = pos(i);
    for (int a = 0; a < 3; ++a) sum[nd][a] += p[a];
    ++members[nd];
    if (with_radius) node_rad[nd] = std::max(node_rad[nd], rad[i]);
    node_kind[nd] = std::max<int32_t>(node_kind[nd], cls[i]);
  }
  for (size_t nd = 0; nd < sum.size(); ++nd) {
    const double m = static_cast<double>(members[nd]);
    g.add_node({sum[nd][0] / m, sum[nd][1] / m, sum[nd][2] / m});
  }
  return b;
}

void trace_chains(const SkeletonVoxels& sv, GraphBuild& b) {
  const int64_t n = sv.size();
  const std::vector<int64_t>& off = sv.off;
  const std::vector<int64_t>& adj = sv.adj;
  const std::vector<double>& rad = sv.rad;
  const bool with_radius = b.with_radius;
  auto is_node_voxel = [&](int64_t i) { return sv.is_node_voxel(i); };
  auto pos = [&](int64_t i) { return sv.position(i); };
  SpatialGraph& g = b.graph;
  const std::vector<int64_t>& node_of = b.node_of;
  const std::vector<double>& node_rad = b.node_rad;
  std::vector<uint8_t>& visited = b.visited;
  visited.assign(n, 0);
  std::vector<Vec3>& pts = b.pts;
  std::vector<float>& prad = b.prad;
  auto emit = [&](int64_t n0, int64_t n1) { b.emit(n0, n1); };
  for (int64_t i = 0; i < n; ++i) {
    if (!is_node_voxel(i)) continue;
    const int64_t ni = node_of[i];
    for (int64_t a = off[i]; a < off[i + 1]; ++a) {
      const int64_t j = adj[a];
      if (is_node_voxel(j)) {
        if (node_of[j] == ni || ni > node_of[j]) continue;
        pts = {g.positions[ni], g.positions[node_of[j]]};
        prad = {static_cast<float>(node_rad[ni]), static_cast<float>(node_rad[node_of[j]])};
        emit(ni, node_of[j]);
        continue;
      }
      if (visited[j]) continue;
      pts = {g.positions[ni]};
      prad = {static_cast<float>(node_rad[ni])};
      int64_t prev = i, cur = j;
      while (!is_node_voxel(cur)) {
        visited[cur] = 1;
        pts.push_back(pos(cur));
        if (with_radius) prad.push_back(static_cast<float>(rad[cur]));
        const int64_t nb0 = adj[off[cur]], nb1 = adj[off[cur] + 1];
        const int64_t next = nb0 == prev ? nb1 : nb0;
        prev = cur;
        cur = next;
      }
      pts.push_back(g.positions[node_of[cur]]);
      prad.push_back(static_cast<float>(node_rad[node_of[cur]]));
      emit(ni, node_of[cur]);
    }
  }
}

void tunnel_loops(const SkeletonVoxels& sv, GraphBuild& b) {
  const auto& table = dual_cube_table();
  const auto& pt = pair_table();
  const int64_t nx = sv.grid.dims[0], ny = sv.grid.dims[1], nxy = nx * ny;
  const int64_t n = sv.size();
  const std::vector<int64_t>& vox = sv.vox;
  const std::vector<uint8_t>& cls = sv.cls;
  const std::vector<int64_t>& off = sv.off;
  const std::vector<int64_t>& adj = sv.adj;
  const std::vector<double>& rad = sv.rad;
  const bool with_radius = b.with_radius;
  auto is_line = [&](int64_t i) { return sv.is_line(i); };
  auto id_from = [&](int64_t i, int64_t idx) { return sv.id_from(i, idx); };
  auto pos = [&](int64_t i) { return sv.position(i); };
  SpatialGraph& g = b.graph;
  const std::vector<int64_t>& node_of = b.node_of;
  const std::vector<double>& node_rad = b.node_rad;
  std::vector<Vec3>& pts = b.pts;
  std::vector<float>& prad = b.prad;
  auto emit = [&](int64_t n0, int64_t n1) { b.emit(n0, n1); };
    std::vector<std::vector<int64_t>> comp_members(g.positions.size());
    for (int64_t i = 0; i < n; ++i)
      if (!is_line(i) && cls[i] != static_cast<uint8_t>(ManifoldType::point)) comp_members[node_of[i]].push_back(i);
    for (size_t nd = 0; nd < comp_members.size(); ++nd) {
      const auto& mem = comp_members[nd];
      if (mem.size() < 4) continue;  // three voxels cannot surround a tunnel
      std::unordered_map<int64_t, int64_t> local;  // voxel id -> local index
      for (size_t k = 0; k < mem.size(); ++k) local.emplace(mem[k], static_cast<int64_t>(k));
      std::vector<std::array<int64_t, 2>> ce;  // internal 1-cells (local ids, a < b)
      std::unordered_map<int64_t, int64_t> ce_index;
      for (size_t k = 0; k < mem.size(); ++k)
        for (int64_t a = off[mem[k]]; a < off[mem[k] + 1]; ++a) {
          auto it = local.find(adj[a]);
          if (it == local.end() || it->second <= static_cast<int64_t>(k)) continue;
          ce_index.emplace(static_cast<int64_t>(k) * static_cast<int64_t>(mem.size()) + it->second,
                           static_cast<int64_t>(ce.size()));
          ce.push_back({static_cast<int64_t>(k), it->second});
        }
      const int64_t ec = static_cast<int64_t>(ce.size()), vc = static_cast<int64_t>(mem.size());
      if (ec - vc + 1 <= 0 || ec > 4096) continue;
      const size_t words = static_cast<size_t>((ec + 63) / 64);
      // GF(2) basis with pivots (highest set bit), seeded with the boundaries of the 2-cells whose
      // vertices all lie in the component.
      std::vector<std::vector<uint64_t>> basis;
      std::vector<int64_t> pivot;
      auto top_bit = [&](const std::vector<uint64_t>& v) -> int64_t {
        for (size_t w = words; w-- > 0;)
          if (v[w]) return static_cast<int64_t>(w * 64 + 63 - static_cast<size_t>(std::countl_zero(v[w])));
        return -1;
      };
      auto reduce_add = [&](std::vector<uint64_t> v) {
        for (;;) {
          const int64_t t = top_bit(v);
          if (t < 0) return false;
          auto it = std::find(pivot.begin(), pivot.end(), t);
          if (it == pivot.end()) {
            basis.push_back(std::move(v));
            pivot.push_back(t);
            return true;
          }
          const auto& b = basis[static_cast<size_t>(it - pivot.begin())];
          for (size_t w = 0; w < words; ++w) v[w] ^= b[w];
        }
      };
      auto edge_bit = [&](int64_t a, int64_t b) -> int64_t {
        if (a > b) std::swap(a, b);
        auto it = ce_index.find(a * vc + b);
        return it == ce_index.end() ? -1 : it->second;
      };
      // The dual cubes around the component's voxels with their configurations (from the
      // neighbourhood of a voxel that is one of their corners).
      std::map<std::array<int64_t, 3>, int> cubes;
      for (int64_t id : mem) {
        const int64_t idx = vox[id];
        const int64_t x = idx % nx, y = idx / nx % ny, z = idx / nxy;
        for (int k = 0; k < 8; ++k)
          cubes.emplace(std::array<int64_t, 3>{x - (k & 1), y - (k >> 1 & 1), z - (k >> 2 & 1)}, cube_config(sv.hood[id], k));
      }
      for (const auto& [c, cfg] : cubes) {
        const DualCubeEntry& t = table[cfg];
        for (const auto& cell : t.cells2) {
          std::array<int64_t, 8> corner{};
          bool inside = true;
          for (int j = 0; j < 8 && inside; ++j) {
            if (!(cell.vertices >> j & 1)) continue;
            const int64_t gi = (c[0] + (j & 1)) + nx * ((c[1] + (j >> 1 & 1)) + ny * (c[2] + (j >> 2 & 1)));
            auto it = local.find(id_from(0, gi));
            inside = it != local.end() && vox[it->first] == gi;
            if (inside) corner[j] = it->second;
          }
          if (!inside) continue;
          std::vector<uint64_t> v(words, 0);
          for (int p = 0; p < 28; ++p)
            if (cell.edges >> p & 1) {
              const int64_t bit = edge_bit(corner[pt.pairs[p][0]], corner[pt.pairs[p][1]]);
              v[bit / 64] ^= uint64_t{1} << (bit % 64);
            }
          reduce_add(std::move(v));
        }
      }
      // Breadth-first spanning tree; each non-tree edge closes a fundamental cycle.
      std::vector<int64_t> par(vc, -2), depth(vc, 0);
      std::vector<int64_t> queue{0};
      par[0] = -1;
      for (size_t h = 0; h < queue.size(); ++h) {
        const int64_t u = queue[h];
        for (int64_t a = off[mem[u]]; a < off[mem[u] + 1]; ++a) {
          auto it = local.find(adj[a]);
          if (it == local.end() || par[it->second] != -2) continue;
          par[it->second] = u;
          depth[it->second] = depth[u] + 1;
          queue.push_back(it->second);
        }
      }
      for (int64_t e = 0; e < ec; ++e) {
        const int64_t a = ce[e][0], b = ce[e][1];
        if (par[a] == b || par[b] == a) continue;
        std::vector<uint64_t> v(words, 0);
        v[e / 64] ^= uint64_t{1} << (e % 64);
        std::vector<int64_t> up{a}, down{b};
        int64_t x = a, y = b;
        while (x != y) {
          if (depth[x] >= depth[y]) {
            const int64_t bit = edge_bit(x, par[x]);
            v[bit / 64] ^= uint64_t{1} << (bit % 64);
            x = par[x];
            up.push_back(x);
          } else {
            const int64_t bit = edge_bit(y, par[y]);
            v[bit / 64] ^= uint64_t{1} << (bit % 64);
            y = par[y];
            down.push_back(y);
          }
        }
        if (!reduce_add(std::move(v))) continue;
        // Loop edge: node, a ... common ancestor ... b, node.
        const int64_t nid = static_cast<int64_t>(nd);
        pts = {g.positions[nid]};
        prad = {static_cast<float>(node_rad[nid])};
        down.pop_back();
        std::reverse(down.begin(), down.end());
        up.insert(up.end(), down.begin(), down.end());
        for (int64_t l : up) {
          pts.push_back(pos(mem[l]));
          if (with_radius) prad.push_back(static_cast<float>(rad[mem[l]]));
        }
        pts.push_back(g.positions[nid]);
        prad.push_back(static_cast<float>(node_rad[nid]));
        emit(nid, nid);
      }
    }
}

void isolated_loops(const SkeletonVoxels& sv, GraphBuild& b) {
  const int64_t n = sv.size();
  const std::vector<uint8_t>& cls = sv.cls;
  const std::vector<int64_t>& off = sv.off;
  const std::vector<int64_t>& adj = sv.adj;
  const std::vector<double>& rad = sv.rad;
  const bool with_radius = b.with_radius;
  auto is_node_voxel = [&](int64_t i) { return sv.is_node_voxel(i); };
  auto pos = [&](int64_t i) { return sv.position(i); };
  SpatialGraph& g = b.graph;
  std::vector<double>& node_rad = b.node_rad;
  std::vector<int32_t>& node_kind = b.node_kind;
  std::vector<uint8_t>& visited = b.visited;
  std::vector<Vec3>& pts = b.pts;
  std::vector<float>& prad = b.prad;
  auto emit = [&](int64_t n0, int64_t n1) { b.emit(n0, n1); };
  for (int64_t i = 0; i < n; ++i) {
    if (is_node_voxel(i) || visited[i]) continue;
    const int64_t nd = g.add_node(pos(i));
    node_rad.push_back(with_radius ? rad[i] : 0.0);
    node_kind.push_back(cls[i]);
    visited[i] = 1;
    pts = {pos(i)};
    prad = {static_cast<float>(node_rad[nd])};
    int64_t prev = i, cur = adj[off[i]];
    while (cur != i) {
      visited[cur] = 1;
      pts.push_back(pos(cur));
      if (with_radius) prad.push_back(static_cast<float>(rad[cur]));
      const int64_t nb0 = adj[off[cur]], nb1 = adj[off[cur] + 1];
      const int64_t next = nb0 == prev ? nb1 : nb0;
      prev = cur;
      cur = next;
    }
    pts.push_back(pos(i));
    prad.push_back(static_cast<float>(node_rad[nd]));
    emit(nd, nd);
  }
}

}  // namespace detail

namespace {

// Phases 1-4 on gathered voxels (sv.rad set when with_radius), node labels and attributes, smoothing.
SpatialGraph graph_from_voxels(detail::SkeletonVoxels& sv, bool with_radius, const SkeletonToGraphOptions& options,
                               const Interrupter& intr) {
  const int threads = options.threads;
  detail::classify_voxels(sv, threads, intr);  // 1.
  intr.check(0.4);
  detail::connect_one_cells(sv, threads, intr);  // 2.
  intr.check(0.6);
  std::vector<int64_t> parent = detail::collapse_junctions(sv);  // 3.
  detail::GraphBuild b = detail::make_nodes(sv, parent, with_radius);
  intr.check(0.7);
  detail::trace_chains(sv, b);  // 4.
  detail::tunnel_loops(sv, b);
  detail::isolated_loops(sv, b);
  intr.check(0.9);

  SpatialGraph g = std::move(b.graph);
  auto& kind = g.ensure_node_label("kind");
  for (size_t nd = 0; nd < kind.size(); ++nd) kind[nd] = b.node_kind[nd];
  if (with_radius) {
    auto& nr = g.ensure_node_attribute("radius");
    for (size_t nd = 0; nd < nr.size(); ++nd) nr[nd] = static_cast<float>(b.node_rad[nd]);
    g.point_attributes["radius"] = std::move(b.point_rad);
  }
  smooth_edges(g, options.smooth_passes, options.smooth_kernel);
  return g;
}

void check_kernel(const SkeletonToGraphOptions& options) {
  if (options.smooth_passes > 0 && options.smooth_kernel < 3)
    throw InputError("parameter 'smooth_kernel': expected >= 3 points, got " +
                     std::to_string(options.smooth_kernel));
}

}  // namespace

SkeletonGraphResult skeleton_to_graph(const VolumeU8& skeleton, const DataObject* distance,
                                      const SkeletonToGraphOptions& options) {
  const Grid& grid = skeleton.grid();
  if (distance != nullptr) {
    const Grid& dg = volume_grid(*distance, "distance");
    if (dg.dims != grid.dims)
      throw InputError("input 'distance': dims " + std::to_string(dg.dims[0]) + "x" +
                       std::to_string(dg.dims[1]) + "x" + std::to_string(dg.dims[2]) +
                       " differ from the skeleton's " + std::to_string(grid.dims[0]) + "x" +
                       std::to_string(grid.dims[1]) + "x" + std::to_string(grid.dims[2]));
  }
  check_kernel(options);
  const Interrupter& intr = options.interrupter;
  detail::SkeletonVoxels sv = detail::collect_voxels(skeleton, options.threads, intr.sub(0.0, 0.2));
  const bool with_radius = distance != nullptr;
  if (with_radius) detail::read_radius(sv, *distance, options.radius_scale);
  SkeletonGraphResult result;
  result.graph = graph_from_voxels(sv, with_radius, options, intr);
  if (options.want_manifold) {
    result.manifold = VolumeU8(grid, 0);
    for (int64_t i = 0; i < sv.size(); ++i) result.manifold[sv.vox[i]] = sv.cls[i];
  }
  intr.check(1.0);
  return result;
}

SpatialGraph skeleton_to_graph_blocks(const DataObject& skeleton, const DataObject* distance, const Dims& block,
                                      const SkeletonToGraphOptions& options, const ChunkedVolume* manifold) {
  check_kernel(options);
  const Interrupter& intr = options.interrupter;
  detail::SkeletonVoxels sv =
      detail::collect_voxels_blocks(skeleton, block, distance, options.radius_scale, intr.sub(0.0, 0.2));
  SpatialGraph g = graph_from_voxels(sv, distance != nullptr, options, intr);
  if (manifold != nullptr) {
    if (manifold->dims() != sv.grid.dims || manifold->type_id() != type_ids::volume_u8)
      throw Error("skeleton_to_graph_blocks: the manifold volume must be uint8 on the skeleton's grid");
    // Voxel ids grouped by block (counting sort), then each block written once.
    const BlockLayout layout(sv.grid.dims, block);
    const Dims c = layout.count();
    const int64_t nx = sv.grid.dims[0], ny = sv.grid.dims[1];
    auto block_of = [&](int64_t idx) {
      const int64_t x = idx % nx, y = idx / nx % ny, z = idx / (nx * ny);
      return x / layout.block[0] + c[0] * (y / layout.block[1] + c[1] * (z / layout.block[2]));
    };
    std::vector<int64_t> start(static_cast<size_t>(layout.total()) + 1, 0);
    for (int64_t v : sv.vox) ++start[static_cast<size_t>(block_of(v)) + 1];
    for (size_t k = 1; k < start.size(); ++k) start[k] += start[k - 1];
    std::vector<int64_t> ids(sv.vox.size());
    {
      std::vector<int64_t> fill(start.begin(), start.end() - 1);
      for (int64_t i = 0; i < sv.size(); ++i) ids[static_cast<size_t>(fill[static_cast<size_t>(block_of(sv.vox[i]))]++)] = i;
    }
    auto write_block = [&](const Block& b) {
      const int64_t k = block_of(b.begin[0] + nx * (b.begin[1] + ny * b.begin[2]));
      VolumeU8 out(manifold->box_grid(b.begin, b.size), 0);
      for (int64_t a = start[static_cast<size_t>(k)]; a < start[static_cast<size_t>(k) + 1]; ++a) {
        const int64_t i = ids[static_cast<size_t>(a)], idx = sv.vox[i];
        out(idx % nx - b.begin[0], idx / nx % ny - b.begin[1], idx / (nx * ny) - b.begin[2]) = sv.cls[i];
      }
      manifold->write(out, b.begin);
    };
    // skelflow-mpi: each rank writes its blocks of the shared manifold volume.
    if (distributing()) for_each_owned_block(layout, intr.sub(0.9, 1.0), "skeleton_to_graph manifold", write_block);
    else for_each_block_resumable(layout, intr.sub(0.9, 1.0), "skeleton_to_graph manifold", write_block);
  }
  intr.check(1.0);
  return g;
}

}  // namespace skel::geometry
