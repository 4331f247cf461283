// Connected components by union-find over runs (maximal x-intervals of object voxels): runs are
// extracted per row in parallel, rows are merged with their backward neighbour rows inside z-slabs in
// parallel (each slab owns a contiguous range of run ids), slab borders are merged afterwards, and
// the final labels are canonical (size descending, ties by first voxel in raster order), so they do
// not depend on the slab split or the thread count.
#include <algorithm>
#include <numeric>
#include <vector>

#include "segmentation/segmentation.hpp"
#include "skel/error.hpp"
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

void check_connectivity(int connectivity) {
  if (connectivity != 6 && connectivity != 18 && connectivity != 26)
    throw InputError("connectivity must be 6, 18 or 26, got " + std::to_string(connectivity));
}

}  // namespace

ComponentsResult connected_components(const VolumeU8& mask, const ComponentOptions& o) {
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
  struct Info {
    int64_t voxels = 0, lo[3], hi[3], sum[3] = {0, 0, 0};
  };
  std::vector<Info> comps;
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
      Info& c = comps[static_cast<size_t>(comp[si])];
      const int64_t a = r.x0[si], b = r.x1[si] - 1, len = b - a + 1;
      if (c.voxels == 0) {
        c.lo[0] = a; c.hi[0] = b;
        c.lo[1] = c.hi[1] = y;
        c.lo[2] = c.hi[2] = z;
      } else {
        c.lo[0] = std::min(c.lo[0], a);
        c.hi[0] = std::max(c.hi[0], b);
        c.lo[1] = std::min(c.lo[1], y);
        c.hi[1] = std::max(c.hi[1], y);
        c.hi[2] = std::max(c.hi[2], z);
      }
      c.voxels += len;
      c.sum[0] += (a + b) * len / 2;
      c.sum[1] += y * len;
      c.sum[2] += z * len;
    }
  }
  // Order: size descending, ties by first voxel in raster order (= order of the root runs).
  std::vector<size_t> order(comps.size());
  std::iota(order.begin(), order.end(), size_t{0});
  std::stable_sort(order.begin(), order.end(), [&](size_t a, size_t b) { return comps[a].voxels > comps[b].voxels; });
  std::vector<uint32_t> label_of(comps.size(), 0);
  uint32_t next = 0;
  for (size_t k : order) {
    if (comps[k].voxels < o.min_size) continue;
    if (o.keep_largest && next >= 1) continue;
    if (next == UINT32_MAX) throw InputError("connected_components: more than 2^32 - 1 components");
    label_of[k] = ++next;
  }
  o.interrupter.check(0.7);
  ComponentsResult res;
  res.labels = VolumeU32::uninitialized(mask.grid());
  res.mask = VolumeU8::uninitialized(mask.grid());
  const int64_t nx = mask.nx();
  parallel_for(0, ny * nz, o.threads, [&](int64_t b, int64_t e) {
    for (int64_t row = b; row < e; ++row) {
      uint32_t* L = res.labels.data() + row * nx;
      uint8_t* M = res.mask.data() + row * nx;
      std::fill_n(L, nx, 0u);
      std::fill_n(M, nx, uint8_t{0});
      for (int64_t i = r.row_start[static_cast<size_t>(row)]; i < r.row_start[static_cast<size_t>(row + 1)]; ++i) {
        const auto si = static_cast<size_t>(i);
        const uint32_t l = label_of[static_cast<size_t>(comp[si])];
        if (!l) continue;
        std::fill(L + r.x0[si], L + r.x1[si], l);
        std::fill(M + r.x0[si], M + r.x1[si], uint8_t{1});
      }
    }
  }, 64);
  res.count = next;
  const Vec3 sp = mask.spacing(), org = mask.origin();
  std::vector<int64_t> lab, vox, bb[6];
  std::vector<double> vol, cen[3];
  for (size_t k : order) {
    const uint32_t l = label_of[k];
    if (!l) continue;
    const Info& c = comps[k];
    lab.push_back(l);
    vox.push_back(c.voxels);
    vol.push_back(static_cast<double>(c.voxels) * sp[0] * sp[1] * sp[2]);
    for (int a = 0; a < 3; ++a) {
      bb[a].push_back(c.lo[a]);
      bb[3 + a].push_back(c.hi[a]);
      cen[a].push_back(org[a] + sp[a] * static_cast<double>(c.sum[a]) / static_cast<double>(c.voxels));
    }
  }
  res.table.add("label", lab).add("voxels", vox).add("volume", vol, units::power(mask.unit(), 3));
  const char* names[6] = {"bbox_min_x", "bbox_min_y", "bbox_min_z", "bbox_max_x", "bbox_max_y", "bbox_max_z"};
  for (int a = 0; a < 6; ++a) res.table.add(names[a], bb[a], "voxels");
  res.table.add("centroid_x", cen[0], mask.unit()).add("centroid_y", cen[1], mask.unit()).add("centroid_z", cen[2], mask.unit());
  o.interrupter.check(1.0);
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

}  // namespace skel::segmentation
