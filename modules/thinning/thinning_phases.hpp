#pragma once
// The phases of distance ordered homotopic thinning (thin_doht, thesis §2.3.1), for thinning.cpp and
// its tests. Not part of the module's API: names and signatures follow the implementation.
//
// thin_doht runs, in order:
//   1. scan_planes: voxel state flags, the distinct priority keys, the boundary voxels per z-plane;
//   2. Levels: priorities ranked into dense integer levels (the buckets of the queue);
//   3. fill_initial_queue: the boundary voxels in raster order within each level;
//   4. Removal::run_basic (Algorithm 1) or Removal::run_smooth (Algorithm 2: per level, a parallel
//      check, the choice of a sub-iteration direction and a sequential recheck);
//   5. collect_skeleton, count_skeleton (kept end points, locked and interior voxels, and the
//      fig. 2.23 components, in one walk), finish_state (flags back to 0/1).
// The per-voxel steps (Thinner, Levels::level, candidate_directions, Removal::remove) are defined
// here, inline, so that the compiler may inline them into the loops of the phases. gcc 12 keeps some
// as calls (Thinner::neighbourhood, deletable, Removal::remove_with); forcing them inline
// measured no faster (bench/RESULTS.md, "A parallel `flag`").
#include <algorithm>
#include <array>
#include <atomic>
#include <bit>
#include <cstdint>
#include <cstring>
#include <memory>
#include <type_traits>
#include <vector>
#if defined(__SSE2__)
#include <emmintrin.h>
#endif

#include "skel/big_vector.hpp"
#include "skel/interrupter.hpp"
#include "skel/volume.hpp"
#include "thinning/cube_word.hpp"
#include "thinning/local_topology.hpp"
#include "thinning/thinning.hpp"

namespace skel::thinning::detail {

// Voxel state bits, kept in the output volume while thinning runs. kQueued: in the queue or a
// candidate of the running sub-iteration; kVisited: skeleton component search after thinning.
constexpr uint8_t kObject = 1, kQueued = 2, kVisited = 4, kLocked = 8, kBorder = 16;
// A 26-neighbour was removed since the voxel's sub-iteration directions were cached (smooth variant).
constexpr uint8_t kDirty = 32;
// Queue entries are voxel indices: uint32_t where every index fits (volumes of at most 2^32 voxels),
// else uint64_t (queue_entry_bytes). The smooth variant's cached sub-iteration directions of a
// re-queued candidate live beside the entry, in a byte array of its bucket: bits 0..5 the
// directions, kCacheValid set.
constexpr uint8_t kCacheValid = 128;

// Bytes per queue entry for a volume of these dims: 4 if every voxel index is below 2^32, else 8.
inline int queue_entry_bytes(const Dims& dims) {
  const uint64_t n = static_cast<uint64_t>(dims[0]) * static_cast<uint64_t>(dims[1]) * static_cast<uint64_t>(dims[2]);
  return n <= (uint64_t{1} << 32) ? 4 : 8;
}

// Direction masks of fig. 2.17 for the 26 neighbour directions v.
struct DirectionMasks {
  std::array<uint32_t, 26> strict_bg{};  // neighbours t + w with w in the closed octant face of v
  std::array<uint32_t, 26> weak_bg{};    // neighbour t + v only
  std::array<uint32_t, 26> obj{};        // neighbour t - v
  std::array<uint32_t, 26> dirs{};       // sub-iteration directions of v
};

// The masks, built once on first use.
const DirectionMasks& direction_masks();

// Queue entries looked ahead when prefetching the state and priorities they will touch (the check,
// flag and removal loops walk the level bucket in queue order; its voxels are scattered).
constexpr int64_t kAhead = 8;  // (flag loop: 2 x kAhead)

// Sub-iteration order: up, down, north, south, east, west (+z, -z, +y, -y, +x, -x).
constexpr std::array<int, 6> kDirectionOrder = {4, 5, 2, 3, 0, 1};

// The direction of the sub-iteration `iteration` (1, 2, ...) among the directions present in `x`
// (bits as thinning_directions): the first present one in kDirectionOrder, starting at position
// iteration % 6, so the sub-iterations rotate through the directions. -1 if x is empty.
inline int choose_subiteration(uint32_t x, int64_t iteration) {
  for (int k = 0; k < 6; ++k) {
    const int d = kDirectionOrder[static_cast<size_t>((iteration + k) % 6)];
    if (x & (1u << d)) return d;
  }
  return -1;
}

// thinning_directions(nb) (fig. 2.17): the directions of the strict masks that match, else those
// of the weak masks. The reference: one mask at a time (tests; thinning uses directions_of below).
inline uint32_t matched_directions(uint32_t nb, const DirectionMasks& dm) {
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

// matched_directions(nb, direction_masks()) for all 26 masks at once on the 27-bit cube word
// (cube_word.hpp), branch-free: a strict mask of direction v matches iff every neighbour w with
// w_a in {0, v_a} on each axis a (the closed octant face of v, the centre counted as background) is
// background and the neighbour at -v is object. "Every w" is three erosions, one per axis: bit v of
// E_a(S) is S(v) and S(v with v_a = 0). The neighbour at -v is bit 26 - c of the cube word: the
// word reversed. Equal to matched_directions on all 2^26 configurations (tested).
inline uint32_t directions_of(uint32_t nb) {
  constexpr uint32_t x0 = cube::plane_mask(0, 0), x1 = cube::plane_mask(0, 1), x2 = cube::plane_mask(0, 2);
  constexpr uint32_t y0 = cube::plane_mask(1, 0), y1 = cube::plane_mask(1, 1), y2 = cube::plane_mask(1, 2);
  constexpr uint32_t z0 = cube::plane_mask(2, 0), z1 = cube::plane_mask(2, 1), z2 = cube::plane_mask(2, 2);
  const uint32_t obj = (nb & 0x1FFFu) | ((nb >> 13) << 14);  // cube bits, centre clear
  const uint32_t bg = ~obj & cube::kCube;                      // centre set
  auto erode = [](uint32_t s, int shift, uint32_t lo, uint32_t mid, uint32_t hi) {
    return (s & mid) | (s & (s >> shift) & lo) | (s & (s << shift) & hi);
  };
  uint32_t faces = erode(bg, 9, z0, z1, z2);
  faces = erode(faces, 3, y0, y1, y2);
  faces = erode(faces, 1, x0, x1, x2);
  uint32_t r = __builtin_bswap32(obj);  // reversed: bit c -> bit 31 - c, then >> 5: bit 26 - c
  r = ((r & 0x0F0F0F0Fu) << 4) | ((r >> 4) & 0x0F0F0F0Fu);
  r = ((r & 0x33333333u) << 2) | ((r >> 2) & 0x33333333u);
  r = ((r & 0x55555555u) << 1) | ((r >> 1) & 0x55555555u);
  const uint32_t opposite = r >> 5;  // bit v: the neighbour at -v is object (centre: 0)
  const uint32_t strict = faces & opposite;
  const uint32_t m = strict != 0 ? strict : bg & opposite;  // else the weak masks: background at v
  return static_cast<uint32_t>((m & x2) != 0) | static_cast<uint32_t>((m & x0) != 0) << 1 |
         static_cast<uint32_t>((m & y2) != 0) << 2 | static_cast<uint32_t>((m & y0) != 0) << 3 |
         static_cast<uint32_t>((m & z2) != 0) << 4 | static_cast<uint32_t>((m & z0) != 0) << 5;
}

// The sub-iteration directions of a deletable voxel with 26-neighbourhood `nb` as the smooth
// variant's check stores them: thinning_directions(nb), all six if that is empty (cannot happen for
// a simple voxel; kept as a guard), and bit 6 for a local end point (exactly one neighbour): end
// points depend on voxels beyond the 26-neighbourhood, so their check is never cached.
inline uint32_t candidate_directions(uint32_t nb) {
  uint32_t d = directions_of(nb);
  if (d == 0) d = 63u;
  if (std::popcount(nb) == 1) d |= 64u;
  return d;
}
// The same through the reference matched_directions (tests).
inline uint32_t candidate_directions(uint32_t nb, const DirectionMasks& dm) {
  uint32_t d = matched_directions(nb, dm);
  if (d == 0) d = 63u;
  if (std::popcount(nb) == 1) d |= 64u;
  return d;
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
          ++k;
        }
    for (int r = 0; r < 9; ++r) row_[static_cast<size_t>(r)] = nx_ * ((r % 3 - 1) + ny_ * (r / 3 - 1));
  }

  [[nodiscard]] uint32_t neighbourhood(int64_t i) const {
    if (st_[i] & kBorder) return neighbourhood_slow(i);
    // The nine rows of the 3x3x3 block in raster order (dz outer, dy, dx inner), three bits each: a
    // 27-bit word with the centre at bit 13, which is dropped (bit k of the result = neighbour k of
    // off_, the order neighbour_bit uses). Fewer address computations than 26 single offsets.
    const uint8_t* p = st_ + i;
    uint32_t w = 0;
#if defined(__SSE2__)
    // Rows 0-7 as eight 4-byte loads (bytes x-1 .. x+2) in two vectors; kObject (bit 0 of each byte)
    // shifted to bit 7 and collected by one movemask per vector: bit 4r + c = row r, byte c. Three
    // shift-and-mask steps drop byte 3 of every row (4 bits per row -> 3); row 8 as below.
    static_assert(kObject == 1);
    {
      auto load = [&](int r) {
        int32_t v;
        std::memcpy(&v, p + row_[static_cast<size_t>(r)] - 1, 4);
        return v;
      };
      const __m128i a = _mm_setr_epi32(load(0), load(1), load(2), load(3));
      const __m128i b = _mm_setr_epi32(load(4), load(5), load(6), load(7));
      uint32_t m = static_cast<uint32_t>(_mm_movemask_epi8(_mm_slli_epi16(a, 7))) |
                   static_cast<uint32_t>(_mm_movemask_epi8(_mm_slli_epi16(b, 7))) << 16;
      m = (m & 0x07070707u) | ((m >> 1) & 0x38383838u);  // two rows per byte, 6 bits
      m = (m & 0x003F003Fu) | ((m >> 2) & 0x0FC00FC0u);  // four rows per 16 bits, 12 bits
      m = (m & 0x00000FFFu) | ((m >> 4) & 0x00FFF000u);  // eight rows, 24 bits
      uint32_t v;  // row 8 from x-2 (x+2 of the voxel (nx-2, ny-2, nz-2) is one byte past the array)
      std::memcpy(&v, p + row_[8] - 2, 4);
      v = (v >> 8) & 0x010101u;  // x86: little-endian
      w = m | (((v * 0x10204u) >> 16) & 7u) << 24;
    }
#else
    if constexpr (std::endian::native == std::endian::little) {
      // One 4-byte load per row: bytes x-1, x, x+1 (and x+2, unused); kObject is bit 0 of each byte,
      // and one multiplication moves bits 0, 8, 16 to 16, 17, 18 (the other products land below bit
      // 16 or above 18). The last row loads x-2..x+1 instead (>> 8): x+2 of the voxel (nx-2, ny-2,
      // nz-2) is one byte past the array. Every byte read lies in the array for a voxel off the faces.
      static_assert(kObject == 1);
      auto row = [&](int r, int skip) {
        uint32_t v;
        std::memcpy(&v, p + row_[static_cast<size_t>(r)] - 1 - skip, 4);
        v = (v >> (8 * skip)) & 0x010101u;
        return static_cast<uint64_t>(((v * 0x10204u) >> 16) & 7u);
      };
      const uint64_t b = row(0, 0) | row(1, 0) << 3 | row(2, 0) << 6 | row(3, 0) << 9 | row(4, 0) << 12 |
                         row(5, 0) << 15 | row(6, 0) << 18 | row(7, 0) << 21 | row(8, 1) << 24;
      w = static_cast<uint32_t>(b);
    } else {
      for (int r = 0; r < 9; ++r) {
        const uint8_t* q = p + row_[static_cast<size_t>(r)];
        const uint32_t bits = static_cast<uint32_t>(q[-1] & kObject) |
                              static_cast<uint32_t>(q[0] & kObject) << 1 | static_cast<uint32_t>(q[1] & kObject) << 2;
        w |= bits << (3 * r);
      }
    }
#endif
    return (w & 0x1FFFu) | ((w >> 1) & 0x3FFE000u);
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
      for (uint32_t v = inside(i); v != 0; v &= v - 1) {
        const int64_t j = i + off_[static_cast<size_t>(std::countr_zero(v))];
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
    if (!gather(i, nb_out)) return false;
    return deletable_with(i, nb_out);
  }
  // deletable() in two steps, so that a loop over many voxels can prefetch the simple test's cache
  // slot (simple_slot) between them. gather: false if i is certainly not deletable (its six face
  // neighbours are object), else its neighbourhood word in `nb`.
  bool gather(int64_t i, uint32_t& nb) const {
    // The six face neighbours in the word (outside the array: 0).
    constexpr uint32_t kFaces = 1u << neighbour_bit(-1, 0, 0) | 1u << neighbour_bit(1, 0, 0) |
                                1u << neighbour_bit(0, -1, 0) | 1u << neighbour_bit(0, 1, 0) |
                                1u << neighbour_bit(0, 0, -1) | 1u << neighbour_bit(0, 0, 1);
    static_assert(kFaces == ((1u << 4) | (1u << 10) | (1u << 12) | (1u << 13) | (1u << 15) | (1u << 21)));
    nb = neighbourhood(i);
    return (nb & kFaces) != kFaces;
  }
  // The rest of deletable() for the word `nb` that gather() gave for i.
  [[nodiscard]] bool deletable_with(int64_t i, uint32_t nb) const {
    if (!simple(nb)) return false;
    if (l_ > 0 && std::popcount(nb) == 1 && importance(i) > l_) return false;
    return true;
  }
  // deletable_with() and, if deletable, candidate_directions(nb) (never 0); 0 if not deletable. The
  // directions come from the simple test's cache.
  [[nodiscard]] uint32_t deletable_directions(int64_t i, uint32_t nb) const {
    const uint32_t code = topology_code(nb);
    if (!(code & 64u)) return 0;
    const bool end = std::popcount(nb) == 1;
    if (l_ > 0 && end && importance(i) > l_) return 0;
    uint32_t d = code & 63u;
    if (d == 0) d = 63u;
    return end ? d | 64u : d;
  }
  // The slot of simple()'s cache that configuration nb uses (for a prefetch hint).
  [[nodiscard]] const void* simple_slot(uint32_t nb) const { return &cache_[slot_hash(nb) >> kTagBits]; }

  [[nodiscard]] bool simple(uint32_t nb) const { return (topology_code(nb) >> 6) & 1u; }

  // The exact simple test and the sub-iteration directions behind a small direct-mapped cache of
  // recent answers (thinning meets the same configurations over and over): bit 6 = simple, bits 0-5 =
  // directions_of(nb) (for a simple nb). A slot is addressed by the top kCacheBits bits of a 26-bit
  // bijective hash of nb and keeps the remaining kTagBits bits (which with the address give nb back),
  // a valid bit and the code in one relaxed atomic word, so the parallel check may share it; only
  // speed depends on its contents, never the answer.
  [[nodiscard]] uint32_t topology_code(uint32_t nb) const {
    const uint32_t h = slot_hash(nb);
    std::atomic<uint32_t>& slot = cache_[h >> kTagBits];
    const uint32_t key = (h & ((1u << kTagBits) - 1)) | (1u << kTagBits);
    const uint32_t c = slot.load(std::memory_order_relaxed);
    if ((c & ((2u << kTagBits) - 1)) == key) return c >> (kTagBits + 1);
    const uint32_t code = is_simple_direct(nb) ? 64u | directions_of(nb) : 0u;
    slot.store(key | code << (kTagBits + 1), std::memory_order_relaxed);
    return code;
  }
  // Odd multiplier modulo 2^26: a bijection of the 26-bit configurations.
  static uint32_t slot_hash(uint32_t nb) { return (nb * 0x9E3779B1u) & ((1u << 26) - 1); }

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
    uint32_t nb = 0;
    for (uint32_t v = inside(i); v != 0; v &= v - 1) {
      const int k = std::countr_zero(v);
      nb |= static_cast<uint32_t>(st_[i + off_[static_cast<size_t>(k)]] & kObject) << k;
    }
    return nb;
  }
  // The neighbours of i inside the array, as the bits of a neighbourhood word: the cube's planes
  // along each axis that the array holds (two divisions for the coordinates).
  [[nodiscard]] uint32_t inside(int64_t i) const {
    const int64_t z = i / (nx_ * ny_), r = i - z * (nx_ * ny_), y = r / nx_, x = r - y * nx_;
    constexpr uint32_t x0 = cube::plane_mask(0, 0), x1 = cube::plane_mask(0, 1), x2 = cube::plane_mask(0, 2);
    constexpr uint32_t y0 = cube::plane_mask(1, 0), y1 = cube::plane_mask(1, 1), y2 = cube::plane_mask(1, 2);
    constexpr uint32_t z0 = cube::plane_mask(2, 0), z1 = cube::plane_mask(2, 1), z2 = cube::plane_mask(2, 2);
    const uint32_t w = (x1 | (x > 0 ? x0 : 0u) | (x < nx_ - 1 ? x2 : 0u)) & (y1 | (y > 0 ? y0 : 0u) | (y < ny_ - 1 ? y2 : 0u)) &
                       (z1 | (z > 0 ? z0 : 0u) | (z < nz_ - 1 ? z2 : 0u));
    return (w & 0x1FFFu) | ((w >> 14) << 13);  // the centre (bit 13) dropped
  }

  uint8_t* st_;
  int64_t nx_, ny_, nz_;
  int l_;
  std::array<int64_t, 26> off_{};
  std::array<int64_t, 9> row_{};  // index offsets of the nine rows of the 3x3x3 neighbourhood
  static constexpr int kCacheBits = 15, kTagBits = 26 - kCacheBits;
  std::unique_ptr<std::atomic<uint32_t>[]> cache_{new std::atomic<uint32_t>[size_t{1} << kCacheBits]()};
};

// Bucket queue over dense levels; FIFO inside a bucket. E: the entry (voxel index) type, uint32_t or
// uint64_t. cache[v] is empty (no entry of bucket v carries cached directions) or as long as
// bucket[v]: the cached directions of each entry (kCacheValid | bits 0..5, or 0).
template <class E>
struct BucketQueue {
  std::vector<BigVector<E>> bucket;
  std::vector<BigVector<uint8_t>> cache;
  std::vector<size_t> head;
  int64_t lowest = 0;
  int64_t size = 0, peak = 0;
  int64_t taken_peak = 0;  // smooth variant: the largest level taken out of its bucket at once
  explicit BucketQueue(int64_t levels)
      : bucket(static_cast<size_t>(levels)), cache(static_cast<size_t>(levels)), head(static_cast<size_t>(levels), 0) {}
  // A large full buffer grows by grow_releasing: a plain reallocation would hold the old and the new
  // buffer at once (the removal's memory peak on dense objects, where one level's bucket grows to
  // hundreds of MiB).
  template <class T>
  static void make_room(BigVector<T>& v) {
    if (v.size() == v.capacity() && v.capacity() * sizeof(T) >= (size_t{4} << 20)) grow_releasing(v, v.size() + 1);
  }
  void push(uint32_t level, int64_t i) {
    auto& b = bucket[level];
    make_room(b);
    b.push_back(static_cast<E>(i));
    if (!cache[level].empty()) {
      make_room(cache[level]);
      cache[level].push_back(0);
    }
    if (static_cast<int64_t>(level) < lowest) lowest = level;
    peak = std::max(peak, ++size);
  }
  // An entry with cached directions `c` (kCacheValid | directions).
  void push_cached(uint32_t level, int64_t i, uint8_t c) {
    auto& b = bucket[level];
    auto& k = cache[level];
    if (k.size() < b.size()) k.resize(b.size(), 0);
    make_room(b);
    b.push_back(static_cast<E>(i));
    make_room(k);
    k.push_back(c);
    if (static_cast<int64_t>(level) < lowest) lowest = level;
    peak = std::max(peak, ++size);
  }
  // Working bytes (statistics): the bucket tables, and the most entries queued at once plus the
  // largest taken level, each an index and a direction byte (the taken level's buffer is freed as it
  // is taken, so capacities at the end would not show the peak).
  [[nodiscard]] uint64_t peak_bytes() const {
    return bucket.capacity() * sizeof(bucket[0]) + cache.capacity() * sizeof(cache[0]) +
           head.capacity() * sizeof(size_t) + static_cast<uint64_t>(peak + taken_peak) * (sizeof(E) + 1);
  }
  // Advances `lowest` to the first non-empty bucket; false if the queue is empty.
  bool settle() {
    const int64_t n = static_cast<int64_t>(bucket.size());
    while (lowest < n) {
      auto& b = bucket[static_cast<size_t>(lowest)];
      if (head[static_cast<size_t>(lowest)] < b.size()) return true;
      // Keep the capacity: levels are revisited (smooth variant; take_level frees the taken buffer).
      b.clear();
      cache[static_cast<size_t>(lowest)].clear();
      head[static_cast<size_t>(lowest)] = 0;
      ++lowest;
    }
    return false;
  }
};

// ---- phases ----

// Phase 1, per z-plane: what one pass over the mask finds.
struct PlaneScan {
  int64_t objects = 0;
  bool nan = false;            // a NaN priority at an object voxel
  KeySet keys;                 // distinct order_key()s of the object voxels' priorities
  int64_t base = 0;            // index of the plane's first voxel (nx * ny * z)
  // Unlocked object voxels with a background 6-neighbour (or on an array face), raster order, as
  // offsets x + nx * y from `base` (4 bytes; planes of more than 2^32 voxels are refused).
  std::vector<uint32_t> boundary;
};

// Phase 1: writes the initial state to `st` (mask.size() bytes): kObject, kLocked, kBorder on the
// array faces; 0 elsewhere. Fixed chunks of planes, so the result does not depend on `threads`.
template <class T>
std::vector<PlaneScan> scan_planes(const VolumeU8& mask, const T* priority, const VolumeU8* locked, uint8_t* st,
                                   int threads);

// Phase 2 input: the distinct keys of all planes; throws InputError on a NaN priority. Adds the
// object voxel count to `object_voxels`.
std::vector<uint64_t> gather_keys(const std::vector<PlaneScan>& planes, int64_t& object_voxels);

// Phase 3: the boundary voxels of `planes` into `q` (sized levels.count()), per level in raster
// order, buckets sized exactly; marks them kQueued. Frees the planes' boundary lists. The result does
// not depend on `threads`.
template <class T, class E>
void fill_initial_queue(std::vector<PlaneScan>& planes, const Levels<T>& levels, uint8_t* st, int64_t nz, int threads,
                        BucketQueue<E>& q);

// Phase 4: the removal loops over the queue (entries of type E, see BucketQueue). `progress` reports
// between 0.08 and 0.9.
template <class T, class E>
class Removal {
public:
  Removal(uint8_t* st, const Thinner& th, const Levels<T>& levels, BucketQueue<E>& q, const T* priority,
          ThinningStatistics& stats, int threads, const Interrupter& irq)
      : st_(st), th_(th), levels_(levels), q_(q), pv_(priority), stats_(stats), threads_(threads), irq_(irq),
        total_(static_cast<double>(stats.object_voxels)), next_check_(stats.tests + kProgressTests) {}

  // Algorithm 1: pops voxels in queue order and removes the deletable ones.
  void run_basic();
  // Algorithm 2: per level, sub-iterations (take_level, check, flag, choose, recheck) until no level
  // has a deletable voxel.
  void run_smooth();

  // Smooth steps, for one sub-iteration at level `lv` (public for tests).
  // Moves the unread entries of bucket lv to `tv` and their cached directions to `tc` (empty if none
  // is cached; the bucket keeps tv's and tc's old buffers).
  void take_level(size_t lv, BigVector<E>& tv, BigVector<uint8_t>& tc);
  // The parallel check (reads the state only): dirs[j] = candidate_directions of entry j if it is
  // deletable, else 0; a cached entry whose neighbourhood is unchanged (no kDirty) keeps its cached
  // directions. Returns the number of deletability tests run.
  int64_t check(const BigVector<E>& tv, const BigVector<uint8_t>& tc, BigVector<uint8_t>& dirs) const;
  // Flags the checked voxels (candidates keep kQueued, kDirty cleared) and compacts the candidates to
  // the front of tv, their directions (bits 0..6) to the front of dirs, in queue order. Returns the
  // union of the candidates' directions (bits 0..5) and their count through `nc`.
  uint32_t flag(BigVector<E>& tv, BigVector<uint8_t>& dirs, int64_t nt, int64_t& nc);
  // Sequential recheck of the candidates of direction bit `chosen`: removes the still deletable ones;
  // the candidates of other directions go back to level lv with their directions cached. They are
  // compacted into the front of tv and dirs (no second buffer for them) and merged with the voxels
  // the removals queue at level lv meanwhile, in the order of a push at the time (the bucket's order);
  // tv and dirs then hold the buffers the bucket had.
  void recheck(BigVector<E>& tv, BigVector<uint8_t>& dirs, int64_t nc, uint32_t chosen, uint32_t lv);

  // Removes t and queues its unqueued object neighbours (marking all of them kDirty).
  inline void remove(int64_t t);
  // The same with t's neighbourhood word `nb` already at hand (deletable() gave it; unused for a
  // voxel on the array's faces).
  inline void remove_with(int64_t t, uint32_t nb);

private:
  static constexpr int64_t kProgressTests = int64_t{1} << 21;
  void progress();

  // A push at level requeue_lv_ while recheck() runs: its position among the re-queued candidates.
  void push(uint32_t level, int64_t s) {
    if (level == requeue_lv_) fresh_pos_.push_back(static_cast<E>(requeue_w_));
    q_.push(level, s);
  }

  uint8_t* st_;
  const Thinner& th_;
  const Levels<T>& levels_;
  BucketQueue<E>& q_;
  uint32_t requeue_lv_ = ~0u;  // the level recheck() re-queues to (none outside recheck)
  int64_t requeue_w_ = 0;      // candidates re-queued so far
  BigVector<E> fresh_pos_;     // per push at requeue_lv_: requeue_w_ at that time
  const T* pv_;
  ThinningStatistics& stats_;
  int threads_;
  const Interrupter& irq_;
  double total_;
  int64_t next_check_;
};

// thin_doht with a fixed queue entry type (tests: the uint64_t entries of volumes above 2^32 voxels
// on small volumes). `entry_bytes` 4 or 8; 4 needs queue_entry_bytes(mask.dims()) == 4.
ThinningResult thin_doht_with_entries(const VolumeU8& mask, const DataObject& priority, const VolumeU8* locked,
                                      const ThinningOptions& options, int entry_bytes);

// Phase 5: the object voxels of `st` in raster order.
std::vector<int64_t> collect_skeleton(const uint8_t* st, const Dims& dims, int threads);
// Phase 5, one walk over the skeleton `skel`: skeleton_voxels, locked_voxels, kept_end_points,
// interior_voxels, and stuck_components and stuck_voxels (fig. 2.23): 26-components with more than
// one voxel, no locked voxel and (end_point_length > 0) no end point, that are contractible. Uses and
// leaves kVisited on the skeleton voxels.
void count_skeleton(const Thinner& th, uint8_t* st, const std::vector<int64_t>& skel, const Dims& dims,
                    int end_point_length, ThinningStatistics& stats);
// Phase 5: the state back to the 0/1 skeleton: skeleton voxels to 1, flags on the array faces cleared.
void finish_state(uint8_t* st, const std::vector<int64_t>& skel, const Dims& dims, int threads);

}  // namespace skel::thinning::detail
