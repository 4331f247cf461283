// Y_t, the geodesic plate skeleton of 2-cells (cells.hpp): the phases of geodesic.boundary_distance
// (nearest points, buckets by base point, breadth-first searches over L) with the distances kept per
// 2-cell instead of their maximum per voxel.
#include "geodesic/cells.hpp"

#include <algorithm>
#include <atomic>
#include <bit>
#include <memory>
#include <mutex>
#include <string>
#include <vector>

#include "geodesic/geodesic_phases.hpp"
#include "skel/error.hpp"
#include "skel/parallel.hpp"

namespace skel::geodesic {

using namespace detail;

namespace {

// The considered 2-cells of the object voxel at padded position `pos`: f(face bit, base of the other side).
template <class F>
void for_each_face(const Prepared& P, int64_t pos, F&& f) {
  const int64_t offs[3] = {1, P.dom.BX, P.dom.plane};
  for (int a = 0; a < 3; ++a) {
    f(2 * a, P.base_of(pos - offs[a]));
    if (!P.obj.test(pos + offs[a])) f(2 * a + 1, static_cast<uint32_t>(P.layer.rank(pos + offs[a])));
  }
}

}  // namespace

PlateCellsResult plate_cells(const VolumeU8& mask, const PlateCellsOptions& opt) {
  mask.grid().validate();
  if (opt.threshold < 1 || opt.threshold > 1000000)
    throw InputError("threshold: must be in [1, 10^6], got " + std::to_string(opt.threshold));
  const auto t = static_cast<uint32_t>(opt.threshold);
  PlateCellsResult r{GridCells(mask.grid()), VolumeU8(mask.grid(), 0), {}};
  auto& st = r.stats;
  if (mask.size() == 0) return r;
  Prepared P(mask.dims());
  prepare(mask, P, opt.threads, opt.interrupter.sub(0.0, 0.3), true);
  st.object_voxels = P.k;
  st.layer_voxels = P.nl;
  if (P.k == 0) return r;
  const Buckets B = bucket_by_base(P);
  opt.interrupter.check(0.35);

  // Bases with work, in L order; each bucket is handled by one worker, which writes the face bits of
  // its voxels (each voxel is in exactly one bucket).
  std::vector<uint32_t> bases;
  for (int64_t l = 0; l < P.nl; ++l)
    if (B.has_work(static_cast<uint32_t>(l))) bases.push_back(static_cast<uint32_t>(l));
  std::mutex pool_mutex;
  std::vector<std::unique_ptr<Scratch>> pool;
  std::atomic<int64_t> searches{0}, visited{0}, done{0};
  uint8_t* faces = r.faces.data();
  const Domain& D = P.dom;
  auto mask_index = [&](int64_t pos) {
    const int64_t z = pos / D.plane, rem = pos % D.plane;
    return mask.index(rem % D.BX - 2, rem / D.BX - 2, z - 2);
  };
  const auto nb = static_cast<int64_t>(bases.size());
  parallel_for(0, nb, opt.threads, [&](int64_t b0, int64_t b1) {
    std::unique_ptr<Scratch> S;
    {
      std::lock_guard lock(pool_mutex);
      if (!pool.empty()) {
        S = std::move(pool.back());
        pool.pop_back();
      }
    }
    if (!S) S = std::make_unique<Scratch>(static_cast<size_t>(P.nl), 0);
    std::vector<uint32_t> targets, want, wd, dist;
    std::vector<int64_t> want_pos;
    for (int64_t bi = b0; bi < b1; ++bi) {
      const uint32_t a = bases[static_cast<size_t>(bi)];
      targets.clear();
      for (uint32_t m = B.begin(a), me = B.end(a); m < me; ++m)
        for_each_face(P, B.member(m, P.lpos(a)), [&](int, uint32_t c) {
          if (std::find(targets.begin(), targets.end(), c) == targets.end()) targets.push_back(c);
        });
      // Distances: 0 to itself, kNone (no path: >= t) to another component of L, else searched to t.
      dist.assign(targets.size(), kNone);
      want.clear();
      for (size_t i = 0; i < targets.size(); ++i) {
        if (targets[i] == a) dist[i] = 0;
        else if (P.lcomp[targets[i]] == P.lcomp[a]) want.push_back(targets[i]);
      }
      if (!want.empty()) {
        want_pos.clear();
        for (uint32_t c : want) want_pos.push_back(P.lpos(c));
        visited += own_bfs(P, *S, a, P.lpos(a), t, want, want_pos, wd);
        ++searches;
        for (size_t j = 0; j < want.size(); ++j)
          dist[static_cast<size_t>(std::find(targets.begin(), targets.end(), want[j]) - targets.begin())] = wd[j];
      }
      for (uint32_t m = B.begin(a), me = B.end(a); m < me; ++m) {
        uint8_t bits = 0;
        for_each_face(P, B.member(m, P.lpos(a)), [&](int bit, uint32_t c) {
          const uint32_t d = dist[static_cast<size_t>(std::find(targets.begin(), targets.end(), c) - targets.begin())];
          if (d == kNone || d >= t) bits = static_cast<uint8_t>(bits | (1u << bit));
        });
        faces[mask_index(B.member(m, P.lpos(a)))] = bits;
      }
      if ((++done & 4095) == 0) opt.interrupter.check(0.35 + 0.55 * static_cast<double>(done.load()) / static_cast<double>(nb));
    }
    std::lock_guard lock(pool_mutex);
    pool.push_back(std::move(S));
  }, 64);
  st.searches = searches.load();
  st.visited = visited.load();
  const uint64_t scratch_bytes = static_cast<uint64_t>(pool.size()) * (static_cast<uint64_t>(P.nl) + 64);
  st.bytes = std::max(P.prepare_bytes, P.obj.bytes() + P.layer.bytes() + P.b.size() * 4 + P.lcomp.size() * 4 +
                                           P.lcoord.size() * sizeof(Coord) + B.bytes() +
                                           bases.size() * 4 + scratch_bytes);
  opt.interrupter.check(0.9);

  // Y_t: every selected 2-cell with its closure (four 1-cells, four 0-cells).
  GridCells& y = r.cells;
  for (int64_t z = 0; z < mask.nz(); ++z)
    for (int64_t yy = 0; yy < mask.ny(); ++yy)
      for (int64_t x = 0; x < mask.nx(); ++x) {
        const uint8_t bits = faces[mask.index(x, yy, z)];
        if (!bits) continue;
        for (int bit = 0; bit < 6; ++bit) {
          if (!((bits >> bit) & 1)) continue;
          ++st.selected_faces;
          const int a = bit / 2;
          int64_t k[3] = {2 * x + 1, 2 * yy + 1, 2 * z + 1};
          k[a] += (bit & 1) ? 1 : -1;
          const int u = (a + 1) % 3, v = (a + 2) % 3;
          for (int du = -1; du <= 1; ++du)
            for (int dv = -1; dv <= 1; ++dv) {
              int64_t c[3] = {k[0], k[1], k[2]};
              c[u] += du;
              c[v] += dv;
              y.set(c[0], c[1], c[2], true);
            }
        }
      }
  opt.interrupter.check(1.0);
  return r;
}

}  // namespace skel::geodesic
