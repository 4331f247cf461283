// Distance ordered homotopic thinning (thesis §2.3.1, Algorithms 1 and 2) with a bucket priority
// queue, the bit-parallel simple-voxel test, directional sub-iterations and end-point importance.
#include "thinning/thinning.hpp"

#include <algorithm>
#include <array>
#include <atomic>
#include <bit>
#include <cmath>
#include <cstring>
#include <memory>
#include <type_traits>
#include <unordered_set>
#include <vector>

#include "skel/big_vector.hpp"
#include "skel/parallel.hpp"
#include "analysis/topology.hpp"
#include "thinning/local_topology.hpp"

namespace skel::thinning {
namespace {

// Voxel state bits, kept in the output volume while thinning runs. kQueued: in the queue or a
// candidate of the running sub-iteration; kVisited: skeleton component search after thinning.
constexpr uint8_t kObject = 1, kQueued = 2, kVisited = 4, kLocked = 8, kBorder = 16;
// A 26-neighbour was removed since the voxel's sub-iteration directions were cached (smooth variant).
constexpr uint8_t kDirty = 32;
// Smooth-variant queue entries may carry the voxel's cached sub-iteration directions (bits 56..61)
// and a validity bit (62) above the voxel index (< 2^56).
constexpr uint64_t kIndexMask = (uint64_t{1} << 56) - 1, kCacheValid = uint64_t{1} << 62;

// Direction masks of fig. 2.17 for the 26 neighbour directions v.
struct DirectionMasks {
  std::array<uint32_t, 26> strict_bg{};  // neighbours t + w with w in the closed octant face of v
  std::array<uint32_t, 26> weak_bg{};    // neighbour t + v only
  std::array<uint32_t, 26> obj{};        // neighbour t - v
  std::array<uint32_t, 26> dirs{};       // sub-iteration directions of v
};

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

const DirectionMasks& direction_masks() {
  static const DirectionMasks m = make_direction_masks();
  return m;
}

// Queue entries looked ahead when prefetching the state and priorities they will touch (the check,
// flag and removal loops walk the level bucket in queue order; its voxels are scattered).
constexpr int64_t kAhead = 8;  // (flag loop: 2 x kAhead)

// Sub-iteration order: up, down, north, south, east, west (+z, -z, +y, -y, +x, -x).
constexpr std::array<int, 6> kDirectionOrder = {4, 5, 2, 3, 0, 1};

int choose_subiteration(uint32_t x, int64_t iteration) {
  for (int k = 0; k < 6; ++k) {
    const int d = kDirectionOrder[static_cast<size_t>((iteration + k) % 6)];
    if (x & (1u << d)) return d;
  }
  return -1;
}

// Order-preserving unsigned keys for priority values.
template <class T>
uint64_t order_key(T v) {
  if constexpr (std::is_floating_point_v<T>) {
    const double d = static_cast<double>(v) == 0.0 ? 0.0 : static_cast<double>(v);  // -0 == +0
    const uint64_t b = std::bit_cast<uint64_t>(d);
    return (b & (uint64_t{1} << 63)) ? ~b : (b | (uint64_t{1} << 63));
  } else if constexpr (std::is_signed_v<T>) {
    return static_cast<uint64_t>(static_cast<int64_t>(v)) ^ (uint64_t{1} << 63);
  } else {
    return static_cast<uint64_t>(v);
  }
}

// A set of distinct 64-bit keys (open addressing; repeated keys are cheap).
class KeySet {
public:
  void insert(uint64_t k) {
    if (has_last_ && k == last_) return;
    has_last_ = true;
    last_ = k;
    size_t h = slot(k);
    while (used_[h]) {
      if (table_[h] == k) return;
      h = (h + 1) & (table_.size() - 1);
    }
    used_[h] = 1;
    table_[h] = k;
    if (++count_ * 2 > table_.size()) grow();
  }
  void append_to(std::vector<uint64_t>& out) const {
    for (size_t j = 0; j < table_.size(); ++j)
      if (used_[j]) out.push_back(table_[j]);
  }

private:
  [[nodiscard]] size_t slot(uint64_t k) const {
    return static_cast<size_t>((k * 0x9E3779B97F4A7C15ull) >> 20) & (table_.size() - 1);
  }
  void grow() {
    std::vector<uint64_t> keys;
    append_to(keys);
    table_.assign(table_.size() * 4, 0);
    used_.assign(used_.size() * 4, 0);
    for (uint64_t k : keys) {
      size_t h = slot(k);
      while (used_[h]) h = (h + 1) & (table_.size() - 1);
      used_[h] = 1;
      table_[h] = k;
    }
  }
  std::vector<uint64_t> table_ = std::vector<uint64_t>(256, 0);
  std::vector<char> used_ = std::vector<char>(256, 0);
  size_t count_ = 0;
  bool has_last_ = false;
  uint64_t last_ = 0;
};

// Maps priority values of object voxels to dense integer levels 0..count-1: the rank of the value
// among the distinct values; integer priorities with a small range use value - min directly.
template <class T>
class Levels {
public:
  // `all`: the distinct keys of the object voxels' priorities (any order; sorted here).
  Levels(const T* pr, std::vector<uint64_t> all) : pr_(pr) {
    std::sort(all.begin(), all.end());
    all.erase(std::unique(all.begin(), all.end()), all.end());
    if (all.empty()) return;
    count_ = static_cast<int64_t>(all.size());
    if constexpr (std::is_integral_v<T>) {
      const uint64_t range = all.back() - all.front();
      if (range < (uint64_t{1} << 22) && range <= 4 * static_cast<uint64_t>(all.size()) + 4096) {
        direct_ = true;
        min_key_ = all.front();
        count_ = static_cast<int64_t>(range + 1);
        return;
      }
    }
    size_t cap = 16;
    while (cap < 2 * all.size()) cap *= 2;
    keys_.assign(cap, 0);
    ranks_.assign(cap, -1);
    for (size_t r = 0; r < all.size(); ++r) {
      size_t h = slot(all[r]);
      while (ranks_[h] >= 0) h = (h + 1) & (cap - 1);
      keys_[h] = all[r];
      ranks_[h] = static_cast<int32_t>(r);
    }
  }
  [[nodiscard]] int64_t count() const { return count_; }
  [[nodiscard]] uint64_t bytes() const { return keys_.size() * 12; }
  // Level of object voxel i, from its priority (hash of the distinct values; no per-voxel array:
  // measured faster than building one).
  [[nodiscard]] uint32_t level(int64_t i) const { return level_from_priority(i); }
  [[nodiscard]] uint32_t level_from_priority(int64_t i) const {
    const uint64_t k = order_key(pr_[i]);
    if (direct_) return static_cast<uint32_t>(k - min_key_);
    size_t h = slot(k);
    while (keys_[h] != k) h = (h + 1) & (keys_.size() - 1);
    return static_cast<uint32_t>(ranks_[h]);
  }

private:
  [[nodiscard]] size_t slot(uint64_t k) const {
    return static_cast<size_t>((k * 0x9E3779B97F4A7C15ull) >> 17) & (keys_.size() - 1);
  }
  const T* pr_;
  bool direct_ = false;
  uint64_t min_key_ = 0;
  int64_t count_ = 0;
  std::vector<uint64_t> keys_;
  std::vector<int32_t> ranks_;
};

// The thinning state: voxel flags in `st` (the output buffer), neighbour offsets, local tests.
class Thinner {
public:
  Thinner(uint8_t* st, Dims dims, int end_point_length)
      : st_(st), nx_(dims[0]), ny_(dims[1]), nz_(dims[2]), l_(end_point_length) {
    int k = 0;
    for (int dz = -1; dz <= 1; ++dz)
      for (int dy = -1; dy <= 1; ++dy)
        for (int dx = -1; dx <= 1; ++dx) {
          if (dx == 0 && dy == 0 && dz == 0) continue;
          off_[static_cast<size_t>(k)] = dx + nx_ * (dy + ny_ * dz);
          d_[static_cast<size_t>(k)] = {dx, dy, dz};
          ++k;
        }
    f6_ = {1, -1, nx_, -nx_, nx_ * ny_, -nx_ * ny_};
    for (int r = 0; r < 9; ++r) row_[static_cast<size_t>(r)] = nx_ * ((r % 3 - 1) + ny_ * (r / 3 - 1));
  }

  [[nodiscard]] uint32_t neighbourhood(int64_t i) const {
    if (st_[i] & kBorder) return neighbourhood_slow(i);
    const uint8_t* p = st_ + i;
    uint32_t nb = 0;
    for (int k = 0; k < 26; ++k) nb |= static_cast<uint32_t>(p[off_[static_cast<size_t>(k)]] & kObject) << k;
    return nb;
  }

  // Prefetch hints for the nine rows of the 3x3x3 neighbourhood of i: state (and priority) bytes.
  // Addresses are formed as integers: rows of a voxel on an array face may lie outside the arrays,
  // which a prefetch ignores.
  template <class P>
  void prefetch(int64_t i, const P* pv) const {
    for (const int64_t r : row_) {
      __builtin_prefetch(address(st_, i + r - 1), 1);
      __builtin_prefetch(address(pv, i + r - 1), 0);
    }
  }
  void prefetch_state(int64_t i) const {
    for (const int64_t r : row_) __builtin_prefetch(address(st_, i + r - 1), 0);
  }
  template <class P>
  static const void* address(const P* base, int64_t i) {
    return reinterpret_cast<const void*>(reinterpret_cast<uintptr_t>(base) + static_cast<uintptr_t>(i) * sizeof(P));
  }

  // Object neighbours of i as indices (returns count).
  int neighbours(int64_t i, int64_t* out) const {
    int c = 0;
    if (st_[i] & kBorder) {
      int64_t x, y, z;
      decode(i, x, y, z);
      for (int k = 0; k < 26; ++k) {
        const auto& d = d_[static_cast<size_t>(k)];
        const int64_t a = x + d[0], b = y + d[1], e = z + d[2];
        if (a < 0 || b < 0 || e < 0 || a >= nx_ || b >= ny_ || e >= nz_) continue;
        const int64_t j = i + off_[static_cast<size_t>(k)];
        if (st_[j] & kObject) out[c++] = j;
      }
    } else {
      for (int k = 0; k < 26; ++k) {
        const int64_t j = i + off_[static_cast<size_t>(k)];
        if (st_[j] & kObject) out[c++] = j;
      }
    }
    return c;
  }

  // Deletable in the current object: simple and not a kept end point. Returns the neighbourhood
  // word through `nb_out` for callers that need the sub-iteration directions.
  bool deletable(int64_t i, uint32_t& nb_out) const {
    if (!(st_[i] & kBorder)) {
      const uint8_t* p = st_ + i;
      if (p[f6_[0]] & p[f6_[1]] & p[f6_[2]] & p[f6_[3]] & p[f6_[4]] & p[f6_[5]] & kObject) return false;
    }
    const uint32_t nb = neighbourhood(i);
    nb_out = nb;
    if (!simple(nb)) return false;
    if (l_ > 0 && std::popcount(nb) == 1 && importance(i) > l_) return false;
    return true;
  }

  // The exact simple test behind a small direct-mapped cache of recent answers (thinning meets the
  // same configurations over and over). Each slot packs the 26-bit configuration, a valid bit and
  // the answer in one relaxed atomic word, so the parallel check may share it; only speed depends
  // on its contents, never the answer.
  [[nodiscard]] bool simple(uint32_t nb) const {
    std::atomic<uint32_t>& slot = cache_[(nb * 0x9E3779B1u) >> (32 - kCacheBits)];
    const uint32_t c = slot.load(std::memory_order_relaxed);
    if ((c & ((1u << 27) - 1)) == (nb | (1u << 26))) return (c >> 27) & 1u;
    const bool r = is_simple_direct(nb);
    slot.store(nb | (1u << 26) | (static_cast<uint32_t>(r) << 27), std::memory_order_relaxed);
    return r;
  }

  // Importance of the local end point i (thesis §2.3.1): the number of voxels p_0 = i, p_1, ... that
  // are local end points in turn, each after removing its predecessors; counted up to l + 1.
  [[nodiscard]] int importance(int64_t i) const {
    int n = 0;
    int64_t prev = -1, cur = i;
    int64_t nbr[26];
    while (true) {
      const int c = neighbours(cur, nbr);
      int64_t next = -1;
      int count = 0;
      for (int k = 0; k < c; ++k)
        if (nbr[k] != prev) {
          ++count;
          next = nbr[k];
        }
      if (count != 1) return n;
      if (++n > l_) return n;
      prev = cur;
      cur = next;
    }
  }

  void decode(int64_t i, int64_t& x, int64_t& y, int64_t& z) const {
    x = i % nx_;
    y = (i / nx_) % ny_;
    z = i / (nx_ * ny_);
  }

  [[nodiscard]] uint32_t neighbourhood_slow(int64_t i) const {
    int64_t x, y, z;
    decode(i, x, y, z);
    uint32_t nb = 0;
    for (int k = 0; k < 26; ++k) {
      const auto& d = d_[static_cast<size_t>(k)];
      const int64_t a = x + d[0], b = y + d[1], e = z + d[2];
      if (a < 0 || b < 0 || e < 0 || a >= nx_ || b >= ny_ || e >= nz_) continue;
      nb |= static_cast<uint32_t>(st_[i + off_[static_cast<size_t>(k)]] & kObject) << k;
    }
    return nb;
  }

  uint8_t* st_;
  int64_t nx_, ny_, nz_;
  int l_;
  std::array<int64_t, 26> off_{};
  std::array<std::array<int, 3>, 26> d_{};
  std::array<int64_t, 6> f6_{};
  std::array<int64_t, 9> row_{};  // index offsets of the nine rows of the 3x3x3 neighbourhood
  static constexpr int kCacheBits = 15;
  std::unique_ptr<std::atomic<uint32_t>[]> cache_{new std::atomic<uint32_t>[size_t{1} << kCacheBits]()};
};

// Bucket queue over dense levels; FIFO inside a bucket.
struct BucketQueue {
  std::vector<BigVector<int64_t>> bucket;
  std::vector<size_t> head;
  int64_t lowest = 0;
  int64_t size = 0, peak = 0;
  uint64_t extra_bytes = 0;  // working buffers outside the buckets (smooth variant)
  explicit BucketQueue(int64_t levels) : bucket(static_cast<size_t>(levels)), head(static_cast<size_t>(levels), 0) {}
  void push(uint32_t level, int64_t i) {
    bucket[level].push_back(i);
    if (static_cast<int64_t>(level) < lowest) lowest = level;
    peak = std::max(peak, ++size);
  }
  [[nodiscard]] uint64_t capacity_bytes() const {
    uint64_t b = extra_bytes + bucket.capacity() * sizeof(bucket[0]) + head.capacity() * sizeof(size_t);
    for (const auto& v : bucket) b += v.capacity() * sizeof(int64_t);
    return b;
  }
  // Advances `lowest` to the first non-empty bucket; false if the queue is empty.
  bool settle() {
    const int64_t n = static_cast<int64_t>(bucket.size());
    while (lowest < n) {
      auto& b = bucket[static_cast<size_t>(lowest)];
      if (head[static_cast<size_t>(lowest)] < b.size()) return true;
      // Keep the capacity: levels are revisited (smooth variant); nothing is freed before the end, so
      // the final capacities are the peak queue memory (reported in the statistics).
      b.clear();
      head[static_cast<size_t>(lowest)] = 0;
      ++lowest;
    }
    return false;
  }
};

template <class T>
ThinningResult thin_impl(const VolumeU8& mask, const Volume<T>& priority, const VolumeU8* locked,
                         const ThinningOptions& opt) {
  ThinningResult res;
  ThinningStatistics& stats = res.stats;
  const int64_t nx = mask.nx(), ny = mask.ny(), nz = mask.nz();
  res.skeleton = VolumeU8::uninitialized(mask.grid());
  uint8_t* st = res.skeleton.data();
  const uint8_t* m = mask.data();
  const uint8_t* lk = locked ? locked->data() : nullptr;
  const int threads = opt.threads;
  const Interrupter& irq = opt.interrupter;

  // One pass over z-planes (fixed chunks, so the result does not depend on threads): state flags,
  // distinct priority keys of object voxels, and the initial queue (object voxels with a background
  // 6-neighbour, unlocked) in raster order.
  struct Plane {
    int64_t objects = 0;
    bool nan = false;
    KeySet keys;
    std::vector<int64_t> boundary;
  };
  std::vector<Plane> planes(static_cast<size_t>(nz));
  const T* pv = priority.data();
  parallel_chunks(0, nz, nz, threads, [&](int64_t, int64_t z0, int64_t z1) {
    for (int64_t z = z0; z < z1; ++z) {
      Plane& pl = planes[static_cast<size_t>(z)];
      for (int64_t y = 0; y < ny; ++y) {
        const int64_t row = nx * (y + ny * z);
        const bool edge_row = y == 0 || z == 0 || y == ny - 1 || z == nz - 1;
        const uint8_t* mr = m + row;
        uint8_t* sr = st + row;
        std::memset(sr, 0, static_cast<size_t>(nx));
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
          sr[x] = s;
          ++pl.objects;
          const T v = pv[i];
          if constexpr (std::is_floating_point_v<T>) {
            if (std::isnan(v)) {
              pl.nan = true;
              continue;
            }
          }
          pl.keys.insert(order_key(v));
          if (s & kLocked) continue;
          const bool boundary = edge || !(m[i - 1] && m[i + 1] && m[i - nx] && m[i + nx] && m[i - nx * ny] && m[i + nx * ny]);
          if (boundary) pl.boundary.push_back(i);
        }
        if (edge_row) {
          for (int64_t x = 0; x < nx; ++x) sr[x] |= kBorder;
        } else {
          sr[0] |= kBorder;
          sr[nx - 1] |= kBorder;
        }
      }
    }
  });
  std::vector<uint64_t> all_keys;
  for (const Plane& pl : planes) {
    if (pl.nan) throw InputError("priority: NaN at an object voxel; expected finite values");
    stats.object_voxels += pl.objects;
    pl.keys.append_to(all_keys);
  }
  irq.check(0.04);

  if (stats.object_voxels > 0) {
    Levels<T> levels(pv, std::move(all_keys));
    stats.priority_levels = levels.count();
    Thinner th(st, mask.dims(), opt.end_point_length);
    // Initial queue: boundary voxels in raster order within each level, buckets sized exactly. Fixed
    // chunks of planes (independent of the thread count) count their boundary voxels per level; each
    // chunk then writes its entries at its offset in every level, in the same order a sequential
    // push in raster order would give. The per-chunk histograms cost chunks x levels counters, so
    // with very many distinct priorities fewer chunks are used (one = the sequential order).
    BucketQueue q(levels.count());
    {
      int64_t boundary_total = 0;
      for (const Plane& pl : planes) boundary_total += static_cast<int64_t>(pl.boundary.size());
      const int64_t nlev = levels.count();
      int64_t chunks = std::min<int64_t>(nz, 4 * effective_threads(threads));
      while (chunks > 1 && chunks * nlev > std::max<int64_t>(boundary_total, int64_t{1} << 16)) chunks /= 2;
      std::vector<std::vector<int64_t>> hist(static_cast<size_t>(chunks));
      std::vector<std::vector<uint32_t>> plane_levels(static_cast<size_t>(nz));
      parallel_chunks(0, nz, chunks, threads, [&](int64_t c, int64_t z0, int64_t z1) {
        auto& h = hist[static_cast<size_t>(c)];
        h.assign(static_cast<size_t>(nlev), 0);
        for (int64_t z = z0; z < z1; ++z) {
          const auto& b = planes[static_cast<size_t>(z)].boundary;
          auto& l = plane_levels[static_cast<size_t>(z)];
          l.resize(b.size());
          for (size_t j = 0; j < b.size(); ++j) {
            st[b[j]] |= kQueued;
            l[j] = levels.level(b[j]);
            ++h[l[j]];
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
          auto& l = plane_levels[static_cast<size_t>(z)];
          for (size_t j = 0; j < b.size(); ++j) q.bucket[l[j]][static_cast<size_t>(h[l[j]]++)] = b[j];
          std::vector<int64_t>().swap(b);
          std::vector<uint32_t>().swap(l);
        }
      });
      q.size = q.peak = boundary_total;
    }
    q.lowest = 0;
    irq.check(0.08);

    int64_t nbr[26];
    auto remove = [&](int64_t t) {
      const bool border = st[t] & kBorder;
      st[t] &= kBorder;
      ++stats.removed;
      auto touch = [&](int64_t s) {
        const uint8_t b = st[s];
        if (!(b & kObject)) return;
        if (b & (kQueued | kLocked)) {
          st[s] = b | kDirty;
          return;
        }
        st[s] = b | kDirty | kQueued;
        q.push(levels.level(s), s);
      };
      if (border) {
        const int c = th.neighbours(t, nbr);
        for (int k = 0; k < c; ++k) touch(nbr[k]);
      } else {
        for (const int64_t o : th.off_) touch(t + o);  // same order as neighbours()
      }
    };
    const double total = static_cast<double>(stats.object_voxels);
    int64_t next_check = stats.tests + (int64_t{1} << 21);
    auto progress = [&] {
      if (stats.tests >= next_check) {
        next_check = stats.tests + (int64_t{1} << 21);
        irq.check(0.08 + 0.82 * std::min(1.0, static_cast<double>(stats.removed) / total));
      }
    };

    if (opt.variant == ThinningVariant::Basic) {
      while (q.settle()) {
        const size_t lv = static_cast<size_t>(q.lowest);
        const int64_t t = q.bucket[lv][q.head[lv]++];
        --q.size;
        st[t] &= static_cast<uint8_t>(~kQueued);
        ++stats.tests;
        uint32_t nb = 0;
        if (th.deletable(t, nb)) remove(t);
        progress();
      }
    } else {
      const DirectionMasks& dm = direction_masks();
      BigVector<int64_t> tv;
      BigVector<uint8_t> dirs;
      int64_t iteration = 0;
      while (true) {
        ++iteration;
        bool found = false;
        while (!found && q.settle()) {
          const size_t lv = static_cast<size_t>(q.lowest);
          // Take the whole bucket (swap, no copy); entries pushed at this level meanwhile go to the
          // emptied bucket, which reuses the previous level's buffer.
          tv.clear();
          std::swap(tv, q.bucket[lv]);
          if (q.head[lv] > 0) tv.erase(tv.begin(), tv.begin() + static_cast<std::ptrdiff_t>(q.head[lv]));
          q.head[lv] = 0;
          q.size -= static_cast<int64_t>(tv.size());
          const int64_t nt = static_cast<int64_t>(tv.size());
          dirs.assign(tv.size(), 0);
          // First, parallel check (reads the state only). A re-queued candidate whose neighbourhood
          // did not change since its last check (no kDirty) keeps its cached directions.
          std::atomic<int64_t> fresh{0};
          auto check = [&](int64_t b, int64_t e) {
            int64_t tested = 0;
            for (int64_t j = b; j < e; ++j) {
              if (j + kAhead < e) {  // prefetch: the state of a voxel checked soon, its rows if uncached
                const uint64_t ahead = static_cast<uint64_t>(tv[static_cast<size_t>(j + kAhead)]);
                const int64_t a = static_cast<int64_t>(ahead & kIndexMask);
                if (ahead & kCacheValid) __builtin_prefetch(st + a, 0);  // a is a voxel index: in range
                else th.prefetch_state(a);
              }
              const uint64_t entry = static_cast<uint64_t>(tv[static_cast<size_t>(j)]);
              const int64_t t = static_cast<int64_t>(entry & kIndexMask);
              if ((entry & kCacheValid) && !(st[t] & kDirty)) {
                dirs[static_cast<size_t>(j)] = static_cast<uint8_t>((entry >> 56) & 63u);
                continue;
              }
              ++tested;
              uint32_t nb = 0;
              if (!th.deletable(t, nb)) continue;
              uint32_t d = 0;
              for (int k = 0; k < 26; ++k)
                if ((nb & dm.strict_bg[static_cast<size_t>(k)]) == 0 && (nb & dm.obj[static_cast<size_t>(k)]))
                  d |= dm.dirs[static_cast<size_t>(k)];
              if (d == 0)
                for (int k = 0; k < 26; ++k)
                  if ((nb & dm.weak_bg[static_cast<size_t>(k)]) == 0 && (nb & dm.obj[static_cast<size_t>(k)]))
                    d |= dm.dirs[static_cast<size_t>(k)];
              if (d == 0) d = 63u;
              // End points depend on voxels beyond the 26-neighbourhood: never cached (bit 6).
              if (std::popcount(nb) == 1) d |= 64u;
              dirs[static_cast<size_t>(j)] = static_cast<uint8_t>(d);
            }
            fresh.fetch_add(tested, std::memory_order_relaxed);
          };
          if (nt >= 8192 && threads != 1) parallel_for(0, nt, threads, check, 2048);
          else check(0, nt);
          stats.tests += fresh.load();
          // Flags (branch-free), and the candidates compacted to the front of tv with their directions
          // in bits 56..62, in queue order. Candidates keep kQueued while the removals below run (their
          // removed neighbours must not queue them again); the re-queued ones keep it afterwards.
          uint32_t x_set = 0;
          int64_t nc = 0;
          for (int64_t j = 0; j < nt; ++j) {
            if (j + 2 * kAhead < nt)
              __builtin_prefetch(st + (static_cast<uint64_t>(tv[static_cast<size_t>(j + 2 * kAhead)]) & kIndexMask), 1);
            const uint64_t t = static_cast<uint64_t>(tv[static_cast<size_t>(j)]) & kIndexMask;
            const uint8_t d = dirs[static_cast<size_t>(j)];
            st[t] = static_cast<uint8_t>((st[t] & ~(kQueued | kDirty)) | (d != 0 ? kQueued : 0));
            x_set |= d;
            tv[static_cast<size_t>(nc)] = static_cast<int64_t>(t | (static_cast<uint64_t>(d) << 56));
            nc += d != 0;
          }
          x_set &= 63u;
          if (x_set == 0) continue;  // nothing deletable at this level: next level
          found = true;
          ++stats.sub_iterations;
          const uint32_t chosen = 1u << choose_subiteration(x_set, iteration);
          // Sequential rechecking of the chosen sub-iteration; others are re-queued.
          for (int64_t j = 0; j < nc; ++j) {
            if (j + kAhead < nc) {  // prefetch the neighbourhood of a voxel that will be removed soon
              const uint64_t ahead = static_cast<uint64_t>(tv[static_cast<size_t>(j + kAhead)]);
              if ((ahead >> 56) & chosen) th.prefetch(static_cast<int64_t>(ahead & kIndexMask), pv);
            }
            const uint64_t entry = static_cast<uint64_t>(tv[static_cast<size_t>(j)]);
            const uint8_t d = static_cast<uint8_t>(entry >> 56);
            const int64_t t = static_cast<int64_t>(entry & kIndexMask);
            if (d & chosen) {
              st[t] &= static_cast<uint8_t>(~kQueued);
              // Unchanged neighbourhood since the parallel check (and not an end point): still deletable.
              if (!(d & 64u) && !(st[t] & kDirty)) {
                remove(t);
                continue;
              }
              ++stats.tests;
              uint32_t nb = 0;
              if (th.deletable(t, nb)) remove(t);
            } else {
              const uint64_t cache = (d & 64u) ? 0 : (kCacheValid | (static_cast<uint64_t>(d & 63u) << 56));
              q.push(static_cast<uint32_t>(lv), static_cast<int64_t>(static_cast<uint64_t>(t) | cache));
            }
          }
          progress();
        }
        if (!found) break;
      }
      q.extra_bytes = tv.capacity() * 8 + dirs.capacity();
    }
    stats.bytes = q.capacity_bytes() + levels.bytes();
    irq.check(0.9);

    // Skeleton voxels, collected per plane in raster order.
    std::vector<std::vector<int64_t>> found(static_cast<size_t>(nz));
    parallel_chunks(0, nz, nz, threads, [&](int64_t, int64_t z0, int64_t z1) {
      for (int64_t z = z0; z < z1; ++z)
        for (int64_t i = nx * ny * z, e = nx * ny * (z + 1); i < e; ++i)
          if (st[i] & kObject) found[static_cast<size_t>(z)].push_back(i);
    });
    std::vector<int64_t> skel;
    for (auto& f : found) {
      skel.insert(skel.end(), f.begin(), f.end());
      std::vector<int64_t>().swap(f);
    }
    for (int64_t i : skel) {
      ++stats.skeleton_voxels;
      if (st[i] & kLocked) {
        ++stats.locked_voxels;
        continue;
      }
      const uint32_t nb = th.neighbourhood(i);
      if (std::popcount(nb) == 1 && is_simple_direct(nb)) ++stats.kept_end_points;
      if (!(st[i] & kBorder)) {
        const uint8_t* p = st + i;
        if (p[1] & p[-1] & p[nx] & p[-nx] & p[nx * ny] & p[-nx * ny] & kObject) ++stats.interior_voxels;
      }
    }

    // Stuck (fig. 2.23) components: contractible, more than one voxel, no kept end point, no lock.
    std::vector<int64_t> comp, stack;
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
        if (st[i] & kLocked) anchored = true;
        const int c = th.neighbours(i, nbr);
        if (c == 1 && opt.end_point_length > 0) anchored = true;
        for (int k = 0; k < c; ++k)
          if (!(st[nbr[k]] & kVisited)) {
            st[nbr[k]] |= kVisited;
            stack.push_back(nbr[k]);
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
    for (int64_t i : skel) st[i] = 1;
  }
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
  irq.check(1.0);
  return res;
}

}  // namespace

uint32_t thinning_directions(uint32_t nb) {
  const DirectionMasks& dm = direction_masks();
  uint32_t d = 0;
  for (int k = 0; k < 26; ++k)
    if ((nb & dm.strict_bg[static_cast<size_t>(k)]) == 0 && (nb & dm.obj[static_cast<size_t>(k)]))
      d |= dm.dirs[static_cast<size_t>(k)];
  if (d == 0)
    for (int k = 0; k < 26; ++k)
      if ((nb & dm.weak_bg[static_cast<size_t>(k)]) == 0 && (nb & dm.obj[static_cast<size_t>(k)]))
        d |= dm.dirs[static_cast<size_t>(k)];
  return d;
}

ThinningResult thin_doht(const VolumeU8& mask, const DataObject& priority, const VolumeU8* locked,
                         const ThinningOptions& options) {
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
  return visit_volume(priority, "priority",
                      [&](const auto& pv) { return thin_impl(mask, pv, locked, options); });
}

}  // namespace skel::thinning
