// Distance ordered homotopic thinning (thesis §2.3.1, Algorithms 1 and 2) with a bucket priority
// queue, the bit-parallel simple-voxel test, directional sub-iterations and end-point importance.
// The phases are declared in thinning_phases.hpp.
#include "thinning/thinning.hpp"

#include <algorithm>
#include <array>
#include <atomic>
#include <bit>
#include <cmath>
#include <cstring>
#include <memory>
#include <type_traits>
#include <vector>

#include "analysis/topology.hpp"
#include "skel/big_vector.hpp"
#include "skel/parallel.hpp"
#include "thinning/local_topology.hpp"
#include "thinning/thinning_phases.hpp"

namespace skel::thinning {
namespace detail {
namespace {

DirectionMasks make_direction_masks() {
  DirectionMasks m;
  int k = 0;
  for (int dz = -1; dz <= 1; ++dz)
    for (int dy = -1; dy <= 1; ++dy)
      for (int dx = -1; dx <= 1; ++dx) {
        if (dx == 0 && dy == 0 && dz == 0) continue;
        const int v[3] = {dx, dy, dz};
        for (int wz = -1; wz <= 1; ++wz)
          for (int wy = -1; wy <= 1; ++wy)
            for (int wx = -1; wx <= 1; ++wx) {
              if (wx == 0 && wy == 0 && wz == 0) continue;
              const int w[3] = {wx, wy, wz};
              bool inside = true;
              for (int a = 0; a < 3; ++a) inside = inside && (w[a] == 0 || w[a] == v[a]);
              if (inside) m.strict_bg[static_cast<size_t>(k)] |= 1u << neighbour_bit(wx, wy, wz);
            }
        m.weak_bg[static_cast<size_t>(k)] = 1u << neighbour_bit(dx, dy, dz);
        m.obj[static_cast<size_t>(k)] = 1u << neighbour_bit(-dx, -dy, -dz);
        for (int a = 0; a < 3; ++a) {
          if (v[a] > 0) m.dirs[static_cast<size_t>(k)] |= 1u << (2 * a);
          if (v[a] < 0) m.dirs[static_cast<size_t>(k)] |= 1u << (2 * a + 1);
        }
        ++k;
      }
  return m;
}

}  // namespace

const DirectionMasks& direction_masks() {
  static const DirectionMasks m = make_direction_masks();
  return m;
}

template <class T>
std::vector<PlaneScan> scan_planes(const VolumeU8& mask, const T* pv, const VolumeU8* locked, uint8_t* st,
                                   int threads) {
  const int64_t nx = mask.nx(), ny = mask.ny(), nz = mask.nz();
  const uint8_t* m = mask.data();
  const uint8_t* lk = locked ? locked->data() : nullptr;
  // In place (thin_doht_in_place: the state is the mask's own buffer): the scan below reads the
  // mask's neighbours, so the state is written afterwards, by a second pass over the rows that gives
  // the same bytes as the one-pass scan writes.
  const bool in_place = st == m;
  if (static_cast<uint64_t>(nx) * static_cast<uint64_t>(ny) > (uint64_t{1} << 32))
    throw InputError("mask: planes of " + std::to_string(nx) + "x" + std::to_string(ny) +
                     " voxels exceed 2^32; thinning needs nx * ny <= 2^32");
  std::vector<PlaneScan> planes(static_cast<size_t>(nz));
  parallel_chunks(0, nz, nz, threads, [&](int64_t, int64_t z0, int64_t z1) {
    for (int64_t z = z0; z < z1; ++z) {
      PlaneScan& pl = planes[static_cast<size_t>(z)];
      pl.base = nx * ny * z;
      // uint8 priorities (distance.chamfer with `narrow`): the plane's distinct values as 256 bits,
      // into the key set once per plane instead of a hash probe per voxel.
      [[maybe_unused]] uint64_t seen8[4] = {0, 0, 0, 0};
      for (int64_t y = 0; y < ny; ++y) {
        const int64_t row = nx * (y + ny * z);
        const bool edge_row = y == 0 || z == 0 || y == ny - 1 || z == nz - 1;
        const uint8_t* mr = m + row;
        uint8_t* sr = st + row;
        if (!in_place) std::memset(sr, 0, static_cast<size_t>(nx));
        for (int64_t x = 0; x < nx; ++x) {
          if (x + 8 <= nx) {  // skip background eight voxels at a time
            uint64_t w;
            std::memcpy(&w, mr + x, 8);
            if (w == 0) {
              x += 7;
              continue;
            }
          }
          if (!mr[x]) continue;
          const int64_t i = row + x;
          const bool edge = edge_row || x == 0 || x == nx - 1;
          uint8_t s = kObject;
          if (lk && lk[i]) s |= kLocked;
          if (!in_place) sr[x] = s;
          ++pl.objects;
          const T v = pv[i];
          if constexpr (std::is_floating_point_v<T>) {
            if (std::isnan(v)) {
              pl.nan = true;
              continue;
            }
          }
          if constexpr (std::is_same_v<T, uint8_t>) seen8[v >> 6] |= uint64_t{1} << (v & 63);
          else pl.keys.insert(order_key(v));
          if (s & kLocked) continue;
          const bool boundary = edge || !(m[i - 1] && m[i + 1] && m[i - nx] && m[i + nx] && m[i - nx * ny] && m[i + nx * ny]);
          if (boundary) pl.boundary.push_back(static_cast<uint32_t>(i - pl.base));
        }
        if (in_place) continue;
        if (edge_row) {
          for (int64_t x = 0; x < nx; ++x) sr[x] |= kBorder;
        } else {
          sr[0] |= kBorder;
          sr[nx - 1] |= kBorder;
        }
      }
      if constexpr (std::is_same_v<T, uint8_t>)
        for (int w = 0; w < 4; ++w)
          for (uint64_t b = seen8[w]; b != 0; b &= b - 1)
            pl.keys.insert(order_key(static_cast<T>(64 * w + std::countr_zero(b))));
    }
  });
  if (in_place) {
    parallel_chunks(0, nz, nz, threads, [&](int64_t, int64_t z0, int64_t z1) {
      for (int64_t z = z0; z < z1; ++z)
        for (int64_t y = 0; y < ny; ++y) {
          const int64_t row = nx * (y + ny * z);
          const bool edge_row = y == 0 || z == 0 || y == ny - 1 || z == nz - 1;
          uint8_t* sr = st + row;
          const uint8_t* lr = lk ? lk + row : nullptr;
          for (int64_t x = 0; x < nx; ++x) {
            uint8_t s = sr[x] ? kObject : uint8_t{0};
            if (s && lr && lr[x]) s |= kLocked;
            sr[x] = s;
          }
          if (edge_row) {
            for (int64_t x = 0; x < nx; ++x) sr[x] |= kBorder;
          } else {
            sr[0] |= kBorder;
            sr[nx - 1] |= kBorder;
          }
        }
    });
  }
  return planes;
}

std::vector<uint64_t> gather_keys(const std::vector<PlaneScan>& planes, int64_t& object_voxels) {
  std::vector<uint64_t> all_keys;
  for (const PlaneScan& pl : planes) {
    if (pl.nan) throw InputError("priority: NaN at an object voxel; expected finite values");
    object_voxels += pl.objects;
    pl.keys.append_to(all_keys);
  }
  return all_keys;
}

// Fixed chunks of planes (independent of the thread count) count their boundary voxels per level;
// each chunk then writes its entries at its offset in every level, in the same order a sequential
// push in raster order would give. The per-chunk histograms cost chunks x levels counters, so with
// very many distinct priorities fewer chunks are used (one = the sequential order).
template <class T, class E>
void fill_initial_queue(std::vector<PlaneScan>& planes, const Levels<T>& levels, uint8_t* st, int64_t nz, int threads,
                        BucketQueue<E>& q) {
  int64_t boundary_total = 0;
  for (const PlaneScan& pl : planes) boundary_total += static_cast<int64_t>(pl.boundary.size());
  const int64_t nlev = levels.count();
  int64_t chunks = std::min<int64_t>(nz, 4 * effective_threads(threads));
  while (chunks > 1 && chunks * nlev > std::max<int64_t>(boundary_total, int64_t{1} << 16)) chunks /= 2;
  std::vector<std::vector<int64_t>> hist(static_cast<size_t>(chunks));
  // The level of each boundary voxel is computed twice (histogram, then placement) instead of stored:
  // the fill is the peak of a dense object's thinning (most object voxels are boundary voxels).
  parallel_chunks(0, nz, chunks, threads, [&](int64_t c, int64_t z0, int64_t z1) {
    auto& h = hist[static_cast<size_t>(c)];
    h.assign(static_cast<size_t>(nlev), 0);
    for (int64_t z = z0; z < z1; ++z) {
      const auto& b = planes[static_cast<size_t>(z)].boundary;
      const int64_t base = planes[static_cast<size_t>(z)].base;
      for (const uint32_t o : b) {
        const int64_t i = base + o;
        st[i] |= kQueued;
        ++h[levels.level(i)];
      }
    }
  });
  // hist[c][v] becomes chunk c's write offset in level v.
  for (int64_t v = 0; v < nlev; ++v) {
    int64_t sum = 0;
    for (auto& h : hist) {
      const int64_t n = h[static_cast<size_t>(v)];
      h[static_cast<size_t>(v)] = sum;
      sum += n;
    }
    q.bucket[static_cast<size_t>(v)].resize(static_cast<size_t>(sum));
  }
  parallel_chunks(0, nz, chunks, threads, [&](int64_t c, int64_t z0, int64_t z1) {
    auto& h = hist[static_cast<size_t>(c)];
    for (int64_t z = z0; z < z1; ++z) {
      auto& b = planes[static_cast<size_t>(z)].boundary;
      const int64_t base = planes[static_cast<size_t>(z)].base;
      for (const uint32_t o : b) {
        const int64_t i = base + o;
        const uint32_t l = levels.level(i);
        q.bucket[l][static_cast<size_t>(h[l]++)] = static_cast<E>(i);
      }
      std::vector<uint32_t>().swap(b);
    }
  });
  q.size = q.peak = boundary_total;
  q.lowest = 0;
}

template <class T, class E>
inline void Removal<T, E>::remove(int64_t t) {
  remove_with(t, (st_[t] & kBorder) ? 0u : th_.neighbourhood(t));
}

template <class T, class E>
inline void Removal<T, E>::remove_with(int64_t t, uint32_t word) {
  uint8_t* const st = st_;
  const bool border = st[t] & kBorder;
  st[t] &= kBorder;
  ++stats_.removed;
  auto touch = [&](int64_t s) {
    const uint8_t b = st[s];
    if (!(b & kObject)) return;
    if (b & (kQueued | kLocked)) {
      st[s] = b | kDirty;
      return;
    }
    st[s] = b | kDirty | kQueued;
    push(levels_.level(s), s);
  };
  if (border) {
    int64_t nbr[26];
    const int c = th_.neighbours(t, nbr);
    for (int k = 0; k < c; ++k) touch(nbr[k]);
  } else {
    // The object neighbours only: the bits of the neighbourhood word, in the order of off_ (and of
    // neighbours()).
    for (uint32_t nb = word; nb != 0; nb &= nb - 1) {
      const int64_t s = t + th_.off_[static_cast<size_t>(std::countr_zero(nb))];
      const uint8_t b = st[s];  // an object voxel: its bit is set
      const bool fresh = !(b & (kQueued | kLocked));
      st[s] = static_cast<uint8_t>(b | kDirty | (fresh ? kQueued : 0));
      if (fresh) push(levels_.level(s), s);
    }
  }
}

template <class T, class E>
void Removal<T, E>::progress() {
  if (stats_.tests >= next_check_) {
    next_check_ = stats_.tests + kProgressTests;
    irq_.check(0.08 + 0.82 * std::min(1.0, static_cast<double>(stats_.removed) / total_));
  }
}

template <class T, class E>
void Removal<T, E>::run_basic() {
  uint8_t* const st = st_;
  BucketQueue<E>& q = q_;
  while (q.settle()) {
    const size_t lv = static_cast<size_t>(q.lowest);
    const int64_t t = static_cast<int64_t>(q.bucket[lv][q.head[lv]++]);
    --q.size;
    st[t] &= static_cast<uint8_t>(~kQueued);
    ++stats_.tests;
    uint32_t nb = 0;
    if (th_.deletable(t, nb)) remove_with(t, nb);
    progress();
  }
}

template <class T, class E>
void Removal<T, E>::take_level(size_t lv, BigVector<E>& tv, BigVector<uint8_t>& tc) {
  // Take the whole bucket (swap, no copy); entries pushed at this level meanwhile go to the emptied
  // bucket, which reuses the previous level's buffer.
  BucketQueue<E>& q = q_;
  tv.clear();
  tc.clear();
  std::swap(tv, q.bucket[lv]);
  std::swap(tc, q.cache[lv]);
  // The bucket starts from an empty buffer (tv's old one is freed): the same-level pushes of this
  // sub-iteration are few; a second buffer as large as the level would be the removal's peak.
  BigVector<E>().swap(q.bucket[lv]);
  BigVector<uint8_t>().swap(q.cache[lv]);
  const auto h = static_cast<std::ptrdiff_t>(q.head[lv]);
  if (h > 0) {
    tv.erase(tv.begin(), tv.begin() + h);
    if (!tc.empty()) tc.erase(tc.begin(), tc.begin() + h);
  }
  q.head[lv] = 0;
  q.size -= static_cast<int64_t>(tv.size());
  q.taken_peak = std::max(q.taken_peak, static_cast<int64_t>(tv.size()));
}

template <class T, class E>
int64_t Removal<T, E>::check(const BigVector<E>& tv, const BigVector<uint8_t>& tc, BigVector<uint8_t>& dirs) const {
  const uint8_t* const st = st_;
  const Thinner& th = th_;
  const int64_t nt = static_cast<int64_t>(tv.size());
  const uint8_t* const cached = tc.empty() ? nullptr : tc.data();
  std::atomic<int64_t> fresh{0};
  // Blocks of kBlock entries in two passes: the neighbourhood words first (each prefetches the simple
  // test's cache slot of its word), then the simple tests, so the slots' cache misses overlap.
  constexpr int64_t kBlock = 32;
  auto check_range = [&](int64_t b, int64_t e) {
    int64_t tested = 0;
    int64_t pending[kBlock];
    uint32_t words[kBlock];
    for (int64_t b0 = b; b0 < e; b0 += kBlock) {
      const int64_t b1 = std::min(e, b0 + kBlock);
      int np = 0;
      for (int64_t j = b0; j < b1; ++j) {
        if (j + kAhead < e) {  // prefetch: the state of a voxel checked soon, its rows if uncached
          const int64_t a = static_cast<int64_t>(tv[static_cast<size_t>(j + kAhead)]);
          if (cached && (cached[j + kAhead] & kCacheValid)) __builtin_prefetch(st + a, 0);  // a voxel index: in range
          else th.prefetch_state(a);
        }
        const int64_t t = static_cast<int64_t>(tv[static_cast<size_t>(j)]);
        if (cached && (cached[j] & kCacheValid) && !(st[t] & kDirty)) {
          dirs[static_cast<size_t>(j)] = static_cast<uint8_t>(cached[j] & 63u);
          continue;
        }
        ++tested;
        uint32_t nb = 0;
        if (!th.gather(t, nb)) continue;
        __builtin_prefetch(th.simple_slot(nb), 0);
        pending[np] = j;
        words[np] = nb;
        ++np;
      }
      for (int k = 0; k < np; ++k) {
        const int64_t j = pending[k];
        dirs[static_cast<size_t>(j)] =
            static_cast<uint8_t>(th.deletable_directions(static_cast<int64_t>(tv[static_cast<size_t>(j)]), words[k]));
      }
    }
    fresh.fetch_add(tested, std::memory_order_relaxed);
  };
  if (nt >= 8192 && threads_ != 1) parallel_for(0, nt, threads_, check_range, 2048);
  else check_range(0, nt);
  return fresh.load();
}

template <class T, class E>
uint32_t Removal<T, E>::flag(BigVector<E>& tv, BigVector<uint8_t>& dirs, int64_t nt, int64_t& nc_out) {
  // Branch-free. Candidates keep kQueued while the removals of the recheck run (their removed
  // neighbours must not queue them again); the re-queued ones keep it afterwards.
  uint8_t* const st = st_;
  uint32_t x_set = 0;
  int64_t nc = 0;
  for (int64_t j = 0; j < nt; ++j) {
    if (j + 2 * kAhead < nt) __builtin_prefetch(st + static_cast<int64_t>(tv[static_cast<size_t>(j + 2 * kAhead)]), 1);
    const E t = tv[static_cast<size_t>(j)];
    const uint8_t d = dirs[static_cast<size_t>(j)];
    st[t] = static_cast<uint8_t>((st[t] & ~(kQueued | kDirty)) | (d != 0 ? kQueued : 0));
    x_set |= d;
    tv[static_cast<size_t>(nc)] = t;
    dirs[static_cast<size_t>(nc)] = d;
    nc += d != 0;
  }
  x_set &= 63u;
  nc_out = nc;
  return x_set;
}

template <class T, class E>
void Removal<T, E>::recheck(BigVector<E>& tv, BigVector<uint8_t>& dirs, int64_t nc, uint32_t chosen, uint32_t lv) {
  uint8_t* const st = st_;
  const Thinner& th = th_;
  BucketQueue<E>& q = q_;
  // The bucket is empty here (take_level emptied it; check and flag push nothing).
  requeue_lv_ = lv;
  requeue_w_ = 0;
  fresh_pos_.clear();
  bool cached = false;
  for (int64_t j = 0; j < nc; ++j) {
    if (j + kAhead < nc) {  // prefetch the neighbourhood of a voxel that will be removed soon
      if (dirs[static_cast<size_t>(j + kAhead)] & chosen)
        th.prefetch(static_cast<int64_t>(tv[static_cast<size_t>(j + kAhead)]), pv_);
    }
    const uint8_t d = dirs[static_cast<size_t>(j)];
    const E te = tv[static_cast<size_t>(j)];
    const int64_t t = static_cast<int64_t>(te);
    if (d & chosen) {
      st[t] &= static_cast<uint8_t>(~kQueued);
      // Unchanged neighbourhood since the parallel check (and not an end point): still deletable.
      if (!(d & 64u) && !(st[t] & kDirty)) {
        remove(t);
        continue;
      }
      ++stats_.tests;
      uint32_t nb = 0;
      if (th.deletable(t, nb)) remove_with(t, nb);
    } else {
      // Re-queued in place (requeue_w_ <= j): end points are never cached.
      const uint8_t c = (d & 64u) ? uint8_t{0} : static_cast<uint8_t>(kCacheValid | (d & 63u));
      cached |= c != 0;
      tv[static_cast<size_t>(requeue_w_)] = te;
      dirs[static_cast<size_t>(requeue_w_)] = c;
      ++requeue_w_;
    }
  }
  requeue_lv_ = ~0u;
  // Merge from the back: fresh entry k (bucket position k) goes after the first fresh_pos_[k]
  // re-queued ones.
  const int64_t w = requeue_w_, f = static_cast<int64_t>(fresh_pos_.size());
  auto& bucket = q.bucket[lv];
  grow_releasing(tv, static_cast<size_t>(w + f));
  tv.resize(static_cast<size_t>(w + f));
  if (cached) {
    grow_releasing(dirs, static_cast<size_t>(w + f));
    dirs.resize(static_cast<size_t>(w + f));
  }
  int64_t i = w - 1, out = w + f - 1;
  for (int64_t k = f - 1; k >= 0; --k) {
    const int64_t pos = static_cast<int64_t>(fresh_pos_[static_cast<size_t>(k)]);
    while (i >= pos) {
      tv[static_cast<size_t>(out)] = tv[static_cast<size_t>(i)];
      if (cached) dirs[static_cast<size_t>(out)] = dirs[static_cast<size_t>(i)];
      --out;
      --i;
    }
    tv[static_cast<size_t>(out)] = bucket[static_cast<size_t>(k)];
    if (cached) dirs[static_cast<size_t>(out)] = 0;
    --out;
  }
  bucket.clear();
  std::swap(tv, bucket);
  if (cached) std::swap(dirs, q.cache[lv]);
  q.size += w;
  q.peak = std::max(q.peak, q.size);
}

template <class T, class E>
void Removal<T, E>::run_smooth() {
  BigVector<E> tv;
  BigVector<uint8_t> tc, dirs;
  int64_t iteration = 0;
  while (true) {
    ++iteration;
    bool found = false;
    while (!found && q_.settle()) {
      const size_t lv = static_cast<size_t>(q_.lowest);
      take_level(lv, tv, tc);
      const int64_t nt = static_cast<int64_t>(tv.size());
      dirs.assign(tv.size(), 0);
      stats_.tests += check(tv, tc, dirs);
      int64_t nc = 0;
      const uint32_t x_set = flag(tv, dirs, nt, nc);
      if (x_set == 0) continue;  // nothing deletable at this level: next level
      found = true;
      ++stats_.sub_iterations;
      const uint32_t chosen = 1u << choose_subiteration(x_set, iteration);
      // Sequential rechecking of the chosen sub-iteration; others are re-queued.
      recheck(tv, dirs, nc, chosen, static_cast<uint32_t>(lv));
      progress();
    }
    if (!found) break;
  }
}

std::vector<int64_t> collect_skeleton(const uint8_t* st, const Dims& dims, int threads) {
  const int64_t nx = dims[0], ny = dims[1], nz = dims[2];
  // Per plane in raster order.
  std::vector<std::vector<int64_t>> found(static_cast<size_t>(nz));
  parallel_chunks(0, nz, nz, threads, [&](int64_t, int64_t z0, int64_t z1) {
    for (int64_t z = z0; z < z1; ++z)
      for (int64_t i = nx * ny * z, e = nx * ny * (z + 1); i < e; ++i) {
        static_assert(kObject == 1);  // bit 0 of each byte
        if (i + 32 <= e) {  // skip 32 voxels at a time without kObject
          uint64_t w[4];
          std::memcpy(w, st + i, 32);
          if (((w[0] | w[1] | w[2] | w[3]) & 0x0101010101010101ull) == 0) {
            i += 31;
            continue;
          }
        }
        if (i + 8 <= e) {  // then eight
          uint64_t w;
          std::memcpy(&w, st + i, 8);
          if ((w & 0x0101010101010101ull) == 0) {
            i += 7;
            continue;
          }
        }
        if (st[i] & kObject) found[static_cast<size_t>(z)].push_back(i);
      }
  });
  std::vector<int64_t> skel;
  for (auto& f : found) {
    skel.insert(skel.end(), f.begin(), f.end());
    std::vector<int64_t>().swap(f);
  }
  return skel;
}

void count_skeleton(const Thinner& th, uint8_t* st, const std::vector<int64_t>& skel, const Dims& dims,
                    int end_point_length, ThinningStatistics& stats) {
  const int64_t nx = dims[0], ny = dims[1], nz = dims[2];
  constexpr uint32_t kFace6 = (1u << neighbour_bit(1, 0, 0)) | (1u << neighbour_bit(-1, 0, 0)) |
                              (1u << neighbour_bit(0, 1, 0)) | (1u << neighbour_bit(0, -1, 0)) |
                              (1u << neighbour_bit(0, 0, 1)) | (1u << neighbour_bit(0, 0, -1));
  std::vector<int64_t> comp, stack;
  // One depth-first walk per 26-component; each voxel's neighbourhood word gives its counts and the
  // walk's next voxels (bit k: neighbour k of off_).
  for (int64_t s0 : skel) {
    if (st[s0] & kVisited) continue;
    comp.clear();
    st[s0] |= kVisited;
    stack.push_back(s0);
    bool anchored = false;
    while (!stack.empty()) {
      const int64_t i = stack.back();
      stack.pop_back();
      comp.push_back(i);
      const uint8_t si = st[i];
      const uint32_t nb = th.neighbourhood(i);
      const int c = std::popcount(nb);
      ++stats.skeleton_voxels;
      if (si & kLocked) {
        ++stats.locked_voxels;
        anchored = true;
      } else {
        if (c == 1 && is_simple_direct(nb)) ++stats.kept_end_points;
        if (!(si & kBorder) && (nb & kFace6) == kFace6) ++stats.interior_voxels;
      }
      if (c == 1 && end_point_length > 0) anchored = true;
      for (uint32_t m = nb; m != 0; m &= m - 1) {
        const int64_t j = i + th.off_[static_cast<size_t>(std::countr_zero(m))];
        if (!(st[j] & kVisited)) {
          st[j] |= kVisited;
          stack.push_back(j);
        }
      }
    }
    if (anchored || comp.size() < 2) continue;
    int64_t lo[3] = {nx, ny, nz}, hi[3] = {-1, -1, -1};
    for (int64_t i : comp) {
      int64_t p[3];
      th.decode(i, p[0], p[1], p[2]);
      for (int a = 0; a < 3; ++a) {
        lo[a] = std::min(lo[a], p[a]);
        hi[a] = std::max(hi[a], p[a]);
      }
    }
    VolumeU8 sub(Dims{hi[0] - lo[0] + 1, hi[1] - lo[1] + 1, hi[2] - lo[2] + 1}, 0);
    for (int64_t i : comp) {
      int64_t p[3];
      th.decode(i, p[0], p[1], p[2]);
      sub(p[0] - lo[0], p[1] - lo[1], p[2] - lo[2]) = 1;
    }
    const analysis::TopologyNumbers tn = analysis::topology(sub, {.threads = 1, .interrupter = {}});
    if (tn.components == 1 && tn.cavities == 0 && tn.tunnels == 0) {
      ++stats.stuck_components;
      stats.stuck_voxels += static_cast<int64_t>(comp.size());
    }
  }
}

void finish_state(uint8_t* st, const std::vector<int64_t>& skel, const Dims& dims, int threads) {
  for (int64_t i : skel) st[i] = 1;
  const int64_t nx = dims[0], ny = dims[1], nz = dims[2];
  // Only voxels on the array faces can still carry flags (kBorder) besides the skeleton.
  parallel_chunks(0, nz, nz, threads, [&](int64_t, int64_t z0, int64_t z1) {
    for (int64_t z = z0; z < z1; ++z) {
      const bool face_plane = z == 0 || z == nz - 1;
      for (int64_t y = 0; y < ny; ++y) {
        uint8_t* row = st + nx * (y + ny * z);
        if (face_plane || y == 0 || y == ny - 1) {
          for (int64_t x = 0; x < nx; ++x) row[x] &= kObject;
        } else {
          row[0] &= kObject;
          row[nx - 1] &= kObject;
        }
      }
    }
  });
}

// Explicit instantiations for the priority types of visit_volume (the tests call the phases).
#define SKEL_THINNING_PHASES(T)                                                                              \
  template std::vector<PlaneScan> scan_planes<T>(const VolumeU8&, const T*, const VolumeU8*, uint8_t*, int); \
  template void fill_initial_queue<T, uint32_t>(std::vector<PlaneScan>&, const Levels<T>&, uint8_t*, int64_t, \
                                                int, BucketQueue<uint32_t>&);                                \
  template void fill_initial_queue<T, uint64_t>(std::vector<PlaneScan>&, const Levels<T>&, uint8_t*, int64_t, \
                                                int, BucketQueue<uint64_t>&);                                \
  template class Removal<T, uint32_t>;                                                                       \
  template class Removal<T, uint64_t>;
SKEL_THINNING_PHASES(uint8_t)
SKEL_THINNING_PHASES(uint16_t)
SKEL_THINNING_PHASES(uint32_t)
SKEL_THINNING_PHASES(uint64_t)
SKEL_THINNING_PHASES(int32_t)
SKEL_THINNING_PHASES(float)
SKEL_THINNING_PHASES(double)
#undef SKEL_THINNING_PHASES

}  // namespace detail

namespace {

using namespace detail;

// `state`: where the state and then the skeleton go; null: a new volume (res.skeleton), else the
// mask's own buffer (thin_doht_in_place; res.skeleton stays empty).
template <class T, class E>
ThinningResult thin_impl(const VolumeU8& mask, const Volume<T>& priority, const VolumeU8* locked,
                         const ThinningOptions& opt, uint8_t* state) {
  ThinningResult res;
  ThinningStatistics& stats = res.stats;
  if (!state) {
    res.skeleton = VolumeU8::uninitialized(mask.grid());
    state = res.skeleton.data();
  }
  uint8_t* st = state;
  const T* pv = priority.data();
  const int threads = opt.threads;
  const Interrupter& irq = opt.interrupter;

  std::vector<PlaneScan> planes = scan_planes(mask, pv, locked, st, threads);
  std::vector<uint64_t> all_keys = gather_keys(planes, stats.object_voxels);
  irq.check(0.04);

  std::vector<int64_t> skel;
  if (stats.object_voxels > 0) {
    Levels<T> levels(pv, std::move(all_keys));
    stats.priority_levels = levels.count();
    Thinner th(st, mask.dims(), opt.end_point_length);
    BucketQueue<E> q(levels.count());
    fill_initial_queue(planes, levels, st, mask.nz(), threads, q);
    irq.check(0.08);

    Removal<T, E> removal(st, th, levels, q, pv, stats, threads, irq);
    if (opt.variant == ThinningVariant::Basic) removal.run_basic();
    else removal.run_smooth();
    stats.bytes = q.peak_bytes() + levels.bytes();
    irq.check(0.9);

    skel = collect_skeleton(st, mask.dims(), threads);
    count_skeleton(th, st, skel, mask.dims(), opt.end_point_length, stats);
  }
  finish_state(st, skel, mask.dims(), threads);
  irq.check(1.0);
  return res;
}

}  // namespace

uint32_t thinning_directions(uint32_t nb) { return detail::directions_of(nb); }

namespace {
ThinningResult thin_checked(const VolumeU8& mask, const DataObject& priority, const VolumeU8* locked,
                            const ThinningOptions& options, uint8_t* state, int entry_bytes = 0) {
  if (options.end_point_length < 0)
    throw InputError("end_point_length: expected >= 0, got " + std::to_string(options.end_point_length));
  const Grid& pg = volume_grid(priority, "priority");
  auto dims_text = [](const Dims& d) {
    return std::to_string(d[0]) + "x" + std::to_string(d[1]) + "x" + std::to_string(d[2]);
  };
  if (pg.dims != mask.dims())
    throw InputError("priority: dims " + dims_text(pg.dims) + " differ from the mask's " + dims_text(mask.dims()));
  if (locked && locked->dims() != mask.dims())
    throw InputError("locked: dims " + dims_text(locked->dims()) + " differ from the mask's " +
                     dims_text(mask.dims()));
  // 4-byte queue entries (voxel indices) where every index fits, else 8.
  if (entry_bytes == 0) entry_bytes = queue_entry_bytes(mask.dims());
  if (entry_bytes == 4 && queue_entry_bytes(mask.dims()) != 4)
    throw Error("thin_doht: 4-byte queue entries cannot index " + dims_text(mask.dims()) + " voxels");
  return visit_volume(priority, "priority", [&](const auto& pv) {
    using T = typename std::decay_t<decltype(pv)>::value_type;
    if (entry_bytes == 4) return thin_impl<T, uint32_t>(mask, pv, locked, options, state);
    return thin_impl<T, uint64_t>(mask, pv, locked, options, state);
  });
}
}  // namespace

ThinningResult detail::thin_doht_with_entries(const VolumeU8& mask, const DataObject& priority, const VolumeU8* locked,
                                              const ThinningOptions& options, int entry_bytes) {
  if (entry_bytes != 4 && entry_bytes != 8) throw Error("thin_doht_with_entries: entry_bytes must be 4 or 8");
  return thin_checked(mask, priority, locked, options, nullptr, entry_bytes);
}

ThinningResult thin_doht(const VolumeU8& mask, const DataObject& priority, const VolumeU8* locked,
                         const ThinningOptions& options) {
  return thin_checked(mask, priority, locked, options, nullptr);
}

ThinningResult thin_doht_in_place(VolumeU8& mask, const DataObject& priority, const VolumeU8* locked,
                                  const ThinningOptions& options) {
  if (locked && locked->data() == mask.data()) throw Error("thin_doht_in_place: `locked` is the mask itself");
  return thin_checked(mask, priority, locked, options, mask.data());
}

}  // namespace skel::thinning
