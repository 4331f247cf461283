#pragma once
// The phases of boundary_distance (geodesic.hpp, thesis §2.3.2), for geodesic.cpp and its tests.
// Not part of the module's API: names and signatures follow the implementation.
//
// boundary_distance runs, in order:
//   1. prepare: the object and layer bitmaps (L = background voxels 26-adjacent to the object), the
//      nearest background point b(p) of every object voxel, the 6-components of L;
//   2. bucket_by_base: the object voxels grouped by b(p);
//   3. search_bases: per base point with work, its own breadth-first search over L to the targets of
//      its voxels (own_bfs), and where that runs to the threshold a pivot search (pivot_bfs) that
//      settles the far targets of the bases near it (process_base); the importance of every voxel;
//   4. threshold_surface: the surface skeleton (importance >= t).
#include <algorithm>
#include <atomic>
#include <bit>
#include <cstdint>
#include <limits>
#include <memory>
#include <mutex>
#include <utility>
#include <vector>

#include "geodesic/geodesic.hpp"
#include "skel/interrupter.hpp"
#include "skel/volume.hpp"

namespace skel::geodesic::detail {

constexpr uint32_t kNone = std::numeric_limits<uint32_t>::max();

// An allocator whose resize() leaves new elements uninitialised (for queues that are written by
// index up to their capacity before they are read: no zero fill per search).
template <class T>
struct NoInitAllocator : std::allocator<T> {
  template <class U>
  struct rebind {
    using other = NoInitAllocator<U>;
  };
  NoInitAllocator() = default;
  template <class U>
  NoInitAllocator(const NoInitAllocator<U>&) noexcept {}  // NOLINT(google-explicit-constructor): rebinding
  template <class U>
  void construct(U* p) noexcept {
    ::new (static_cast<void*>(p)) U;
  }
  template <class U, class... A>
  void construct(U* p, A&&... a) {
    ::new (static_cast<void*>(p)) U(std::forward<A>(a)...);
  }
};
template <class T>
using QueueVector = std::vector<T, NoInitAllocator<T>>;

// A bitmap over the padded domain with O(1) rank (number of set bits before a position): the bits
// (1 per voxel) and, after build_rank(), the set bits before every group of 8 words (512 bits) as
// 32 bits (object and layer voxels are < 2^32, checked in build_bitmaps): 1.0625 bits per voxel (a
// prefix per word took 1.5 bits: 1.6 bytes per object voxel more on the 7 %-object bone phantom at
// 1280³). A test touches the bits only; a rank adds four popcounts in the word's half-group and a
// prefix load.
struct RankBits {
  static constexpr size_t kGroup = 8;  // words per stored prefix
  std::vector<uint64_t> words;
  std::vector<uint32_t> pre;
  std::vector<uint32_t> wpre;  // optional: the prefix of every word (build_word_prefixes)
  [[nodiscard]] uint64_t word(size_t w) const { return words[w]; }
  // Set bits before word w: from the group's prefix forward over words 0 .. 3 of the group, or from
  // the next group's prefix backward over words 4 .. 7 (pre has one entry more), four popcounts
  // either way, branch-free (a loop to w mispredicts on its varying count).
  [[nodiscard]] uint64_t prefix(size_t w) const {
    if (!wpre.empty()) return wpre[w];
    const size_t hi = (w >> 2) & 1, k = (w & 3);  // the half of the group, w's place in it
    const uint64_t* h = words.data() + (w & ~size_t{3});
    uint64_t sum = 0;
    for (size_t j = 0; j < 4; ++j)
      sum += static_cast<uint64_t>(std::popcount(h[j])) & (uint64_t{0} - static_cast<uint64_t>((j < k) != (hi != 0)));
    const uint64_t base = pre[w / kGroup + hi];
    return hi ? base - sum : base + sum;
  }
  [[nodiscard]] bool test(int64_t pos) const { return (words[static_cast<size_t>(pos >> 6)] >> (pos & 63)) & 1u; }
  [[nodiscard]] uint64_t rank(int64_t pos) const {
    const size_t w = static_cast<size_t>(pos >> 6);
    const uint64_t below = words[w] & ((uint64_t{1} << (pos & 63)) - 1);
    return prefix(w) + static_cast<uint64_t>(std::popcount(below));
  }
  // Words for n bits, zero, padded to whole groups (prefix() reads a whole group).
  void assign_zero(size_t n_words) {
    nw = n_words;
    words.assign(padded(n_words), 0);
  }
  // Builds the prefixes; returns the number of set bits (prefixes saturate where it is >= 2^32,
  // which the caller refuses). The words beyond word_count() must be zero (assign_zero; else they
  // are added here).
  uint64_t build_rank() {
    if (nw == 0) nw = words.size();
    const size_t n = nw;
    words.resize(padded(n), 0);
    pre.resize((n + kGroup - 1) / kGroup + 1);
    uint64_t s = 0;
    for (size_t i = 0; i < words.size(); ++i) {
      if (i % kGroup == 0) pre[i / kGroup] = static_cast<uint32_t>(std::min<uint64_t>(s, 0xFFFFFFFFu));
      s += static_cast<uint64_t>(std::popcount(words[i]));
    }
    pre.back() = static_cast<uint32_t>(std::min<uint64_t>(s, 0xFFFFFFFFu));
    return s;
  }
  // A prefix per word as well (+0.5 bits per voxel): a rank is then one load and one popcount. For
  // the phases that rank most (the nearest points; searches whose scratch is indexed by L-id).
  void build_word_prefixes() {
    std::vector<uint32_t> wp;
    wp.reserve(words.size());
    uint64_t s = 0;
    for (uint64_t word : words) {
      wp.push_back(static_cast<uint32_t>(std::min<uint64_t>(s, 0xFFFFFFFFu)));
      s += static_cast<uint64_t>(std::popcount(word));
    }
    wpre = std::move(wp);
  }
  void drop_word_prefixes() { std::vector<uint32_t>().swap(wpre); }
  [[nodiscard]] size_t word_count() const { return nw ? nw : words.size(); }
  [[nodiscard]] uint64_t bytes() const { return words.size() * 8 + pre.size() * 4 + wpre.size() * 4; }

private:
  static size_t padded(size_t n) { return (n + kGroup - 1) / kGroup * kGroup; }
  size_t nw = 0;  // words before the padding (assign_zero or build_rank)
};

// Ranks for the loops that rank every neighbour they visit (searches over dense scratch, indexed by
// L-id; the nearest points): one load and one popcount where the word prefixes are built, else
// RankBits::rank. A local copy of the pointers, so that a loop keeps them in registers.
class DenseRanks {
public:
  explicit DenseRanks(const RankBits& r) : rb_(&r), words_(r.words.data()), wpre_(r.wpre.empty() ? nullptr : r.wpre.data()) {}
  [[nodiscard]] bool test(int64_t pos) const { return (words_[static_cast<size_t>(pos >> 6)] >> (pos & 63)) & 1u; }
  [[nodiscard]] uint32_t operator()(int64_t pos) const {
    if (!wpre_) [[unlikely]]
      return slow(pos);
    const size_t w = static_cast<size_t>(pos >> 6);
    return wpre_[w] + static_cast<uint32_t>(std::popcount(words_[w] & ((uint64_t{1} << (pos & 63)) - 1)));
  }

private:
  [[gnu::noinline]] uint32_t slow(int64_t pos) const { return static_cast<uint32_t>(rb_->rank(pos)); }
  const RankBits* rb_;
  const uint64_t* words_;
  const uint32_t* wpre_;
};

struct Coord {
  uint16_t x, y, z;
};

// The padded domain: mask voxel (x, y, z) lives at bit position (x+2) + BX*((y+2) + BY*(z+2)).
// Rows start at word boundaries; two empty voxels on every side (the first belongs to the domain as
// background "outside the array", the second is a guard that is never set).
struct Domain {
  // Exact quotient and remainder of a non-negative n < 2^52 by d (positions are far below): a
  // multiplication by the rounded reciprocal is off by at most one, which one step corrects; the
  // searches split positions into coordinates per target and per bucket member, where a 64-bit
  // division (35-90 cycles) was a few per cent of the run.
  struct Divider {
    int64_t d = 1;
    double inv = 1.0;
    int64_t operator()(int64_t n, int64_t& rem) const {
      int64_t q = static_cast<int64_t>(static_cast<double>(n) * inv);
      int64_t r = n - q * d;
      if (r < 0) {
        --q;
        r += d;
      } else if (r >= d) {
        ++q;
        r -= d;
      }
      rem = r;
      return q;
    }
  };
  int64_t nx, ny, nz, BX, BY, BZ, plane;
  Divider by_plane, by_row;
  explicit Domain(const Dims& d) : nx(d[0]), ny(d[1]), nz(d[2]) {
    BX = ((nx + 4 + 63) / 64) * 64;
    BY = ny + 4;
    BZ = nz + 4;
    plane = BX * BY;
    by_plane = Divider{plane, 1.0 / static_cast<double>(plane)};
    by_row = Divider{BX, 1.0 / static_cast<double>(BX)};
  }
  // Padded coordinates of position `pos`.
  void coords(int64_t pos, int64_t& x, int64_t& y, int64_t& z) const {
    int64_t r = 0;
    z = by_plane(pos, r);
    y = by_row(r, x);
  }
  [[nodiscard]] int64_t pos(int64_t x, int64_t y, int64_t z) const { return x + BX * (y + BY * z); }
  [[nodiscard]] int64_t bits() const { return BX * BY * BZ; }
  [[nodiscard]] int64_t row_words() const { return BX / 64; }
};

// b(p) as the offset from p to its nearest background point, 3 bytes per object voxel (the L-id
// would take 4 and give no position). Offsets beyond +-127 on an axis (objects more than 127 voxels
// thick) are marked by dx == kFar and kept in a sorted side table (object id, padded position of b).
struct BaseOffset {
  int8_t dx, dy, dz;
};
constexpr int8_t kFar = -128;
// While nearest_points runs: dx == kFar with dy != 0 marks a voxel not assigned yet.
constexpr BaseOffset kUnsetOffset{kFar, 1, 0};

struct Prepared {
  Domain dom;
  RankBits obj, layer;
  std::vector<Coord> lcoord;  // L-id -> padded coordinates (only for the reference, cells and tests:
                              // searches carry positions instead)
  std::vector<uint32_t> b;    // object id -> L-id of its nearest background point (only for the
                              // reference, cells and tests: base_ids)
  std::vector<BaseOffset> boff;  // object id -> offset to b(p) (nearest_points)
  std::vector<std::pair<uint32_t, int64_t>> bfar;  // object id -> position of b(p), where kFar
  std::vector<uint32_t> lcomp;  // L-id -> 6-connected component of L
  int64_t k = 0, nl = 0;
  uint64_t prepare_bytes = 0;  // peak working memory of prepare()
  explicit Prepared(const Dims& d) : dom(d) {}
  [[nodiscard]] int64_t lpos(uint32_t l) const { return dom.pos(lcoord[l].x, lcoord[l].y, lcoord[l].z); }
  // Padded position of the nearest background point of object voxel `oid` at `pos`.
  [[nodiscard]] int64_t base_pos_of_object(uint64_t oid, int64_t pos) const {
    const BaseOffset o = boff[oid];
    if (o.dx == kFar) {
      const auto it = std::lower_bound(bfar.begin(), bfar.end(), std::pair<uint32_t, int64_t>{static_cast<uint32_t>(oid), std::numeric_limits<int64_t>::min()});
      return it->second;
    }
    return pos + o.dx + dom.BX * (o.dy + dom.BY * static_cast<int64_t>(o.dz));
  }
  // Padded position of the nearest background point of the voxel at `pos` (object or layer voxel).
  [[nodiscard]] int64_t base_pos(int64_t pos) const {
    return obj.test(pos) ? base_pos_of_object(obj.rank(pos), pos) : pos;
  }
  // L-id of the nearest background point of the voxel at `pos` (object or layer voxel).
  [[nodiscard]] uint32_t base_of(int64_t pos) const { return static_cast<uint32_t>(layer.rank(base_pos(pos))); }
  [[nodiscard]] uint64_t base_bytes() const { return boff.size() * sizeof(BaseOffset) + bfar.size() * 16; }
};


// The 26 neighbour offsets in the padded domain.
std::vector<int64_t> offsets26(const Domain& d);

// Phase 1: builds the bitmaps, the nearest-point transform (as offsets) and (if `components`) L's
// components (the steps below); with `keep_coords` also the L coordinates and the L-ids of b (for
// the reference, cells and tests). Without components (P.lcomp empty) every target is searched.
void prepare(const VolumeU8& mask, Prepared& P, int threads, const Interrupter& intr, bool keep_coords,
             bool components = true);
// 1a: P.obj and P.layer (L = dilate26(O) minus O over the padded domain) with their ranks, P.k, P.nl.
void build_bitmaps(const VolumeU8& mask, Prepared& P, int threads, const Interrupter& intr);
// 1b: P.lcoord (padded coordinates of every L voxel).
void layer_coordinates(Prepared& P, int threads);
// 1c: P.boff and P.bfar (b(p) as offsets), by rings of 26-neighbours inward from L: ring r+1 =
// unreached object voxels 26-adjacent to ring r; each takes, among its neighbours of earlier rings,
// the nearest point that is closest in physical distance (ties: lower L-id). Sets P.prepare_bytes
// (bitmaps, offsets and two ring bitmaps of 1 bit per object voxel).
void nearest_points(const Vec3& spacing, Prepared& P, int threads, const Interrupter& intr);
// 1e: P.b (L-ids of b(p)) from the offsets.
void base_ids(Prepared& P, int threads);
// 1d: P.lcomp, the 6-connected component of every L voxel (its smallest L-id).
void layer_components(Prepared& P);

// Scratch of one worker, indexed either by L-id (dense: |L| entries) or by position in a box of
// the padded domain that holds everything the searches of one block of bases can touch (box: the
// block plus t + margin + 1 on every side; search_bases moves it from block to block), whichever is
// smaller. Only the index changes between the two; the searches are the same.
// Own searches (A*, own_bfs) mark the voxels they closed by range encoding (thesis §2.3.2): a
// 16-bit stamp per entry, and each search takes the next stamp value, so a voxel is closed in the
// current search iff its stamp equals the search's value; nothing is cleared after a search (nor when
// the box moves), the array only once every 65535 searches (when the stamp wraps). The open voxels
// wait in a bucket queue by their key g + h (h = 6-step lower bound to the nearest remaining target).
// Pivot searches keep 8- or 16-bit distances (d + 1, 0 = unvisited; none without pivots) because
// targets of neighbouring bases are looked up afterwards; they are reset through their list.
struct Scratch {
  struct Entry {  // 16 bytes; the padded position is x + BX * (y + BY * z)
    uint32_t id, g;  // id: scratch index (L-id or box index)
    uint16_t x, y, z, gen;  // gen: targets reached when queued (the key is stale once more are)
  };
  std::vector<uint16_t> stamp;   // own search: closed iff == cur
  // Own search: the smallest g a voxel was queued with in this search, as cur << 16 | g (valid iff
  // the high half is cur: range encoded like the stamps and cleared with them; used where the limit
  // is < 32767, i.e. in threshold mode), so a voxel is not queued again on a path that is not shorter
  // (each queued entry costs a heuristic evaluation and a pop). Bit 15 marks the voxel closed: the
  // stamps are not used then (a pop and an expansion read one array, not two).
  std::vector<uint32_t> queued;   // (allocated with the pivot distances: threshold mode)
  int64_t last_queued = 0;       // entries the last own search queued (tests)
  uint16_t cur = 0;
  int64_t stamp_resets = 0;
  // A bucket of the own search's queue: a stack whose push is a store and an increment, the
  // growth (doubling) out of line, so the search's loop keeps it inline.
  struct Bucket {
    std::vector<Entry> v;  // storage: size() is the capacity
    uint32_t n = 0;        // entries in use
    void push(const Entry& e) {
      if (n == v.size()) [[unlikely]] grow();
      v[n++] = e;
    }
    [[nodiscard]] Entry pop() { return v[--n]; }
    [[nodiscard]] bool empty() const { return n == 0; }
    void clear() { n = 0; }
    [[nodiscard]] size_t capacity() const { return v.size(); }
    [[gnu::noinline]] void grow() { v.resize(std::max<size_t>(16, 2 * v.size())); }
  };
  std::vector<Bucket> buckets;  // own search: open voxels by key (empty between searches)
  std::vector<uint8_t> pdist8;    // pivot search: distance + 1, where the pivot limit is <= 254
  std::vector<uint16_t> pdist16;  // pivot search: distance + 1, otherwise
  QueueVector<uint32_t> pqueue; // pivot search: visited voxels (scratch indices) in distance order (kept until the next pivot)
  QueueVector<int64_t> qpos;    // padded positions of the pivot search's queue
  // Box mode (bw > 0): entry of padded (x, y, z) = (x - bx0) + bw * ((y - by0) + bh * (z - bz0)).
  int64_t bw = 0, bh = 0, bd = 0, bx0 = 0, by0 = 0, bz0 = 0;
  // Landmarks (ALT heuristic, see own_bfs): breadth-first distance fields over L from the far
  // target of an expensive own search, bounded at `lm_radius` (<= 253; 0 = no landmarks) and kept
  // as distance + 1 in one byte per entry (0 = farther than the radius), for the searches that
  // follow in the same block. A field clipped at its radius, f(v) = min(d(lm, v), R + 1), is
  // 1-Lipschitz along 6-steps, so |f(c) - f(v)| <= g(v, c) is a consistent lower bound. Fields are
  // cleared (through their lists) when a block starts (begin_block), so what a search sees does not
  // depend on which worker ran which block before.
  struct Landmark {
    std::vector<uint8_t> f;      // distance + 1, 0 = beyond the radius (allocated on first use)
    QueueVector<uint32_t> list;  // entries set, in distance order (clearing, and the BFS queue)
    bool on = false;
  };
  static constexpr int kLandmarks = 2;
  Landmark lm[kLandmarks];
  int lm_next = 0;                // slot the next field replaces (round robin)
  uint32_t lm_radius = 0;
  int64_t lm_min_visited = 0;     // a field after an own search that closed at least this many voxels
  int64_t lm_built = 0;           // fields built (diagnostics)
  QueueVector<int64_t> lm_pos;    // positions of the field BFS queue
  [[nodiscard]] uint32_t lm_value(int s, uint32_t v) const {
    const uint8_t f = lm[s].f[v];
    return f ? f - 1u : lm_radius + 1;
  }
  bool fields = false;            // fields for the A*: the landmarks (if lm_radius > 0) and the pivot's
  bool pivot_field = false;       // the last pivot's distances serve the A* as a field too (if `fields`)
  uint32_t pivot_limit = 0;
  void clear_landmarks() {
    pivot_field = false;
    for (Landmark& L : lm) {
      for (uint32_t v : L.list) L.f[v] = 0;
      L.list.clear();
      L.on = false;
    }
    lm_next = 0;
  }
  // Called when a worker starts a block.
  void begin_block() { clear_landmarks(); }
  // Dense: one entry per L voxel.
  Scratch(size_t nl, uint32_t pivot_limit) { allocate(nl, pivot_limit); }
  // Box of w x h x d voxels (origin set by move_box).
  Scratch(int64_t w, int64_t h, int64_t d, uint32_t pivot_limit) : bw(w), bh(h), bd(d) {
    allocate(static_cast<size_t>(w * h * d), pivot_limit);
  }
  [[nodiscard]] bool boxed() const { return bw > 0; }
  void move_box(int64_t x0, int64_t y0, int64_t z0) {
    // pqueue holds indices of the old placement: clear the pivot distances first.
    for (uint32_t v : pqueue) {
      if (pdist8.empty()) pdist16[v] = 0;
      else pdist8[v] = 0;
    }
    pqueue.clear();
    qpos.clear();
    clear_landmarks();
    bx0 = x0, by0 = y0, bz0 = z0;
  }
  [[nodiscard]] uint32_t box_index(int64_t x, int64_t y, int64_t z) const {
    return static_cast<uint32_t>((x - bx0) + bw * ((y - by0) + bh * (z - bz0)));
  }
  // Scratch index of the L voxel with L-id `l` at padded position `pos`.
  [[nodiscard]] uint32_t index_of(const Domain& D, uint32_t l, int64_t pos) const {
    if (!boxed()) return l;
    int64_t x = 0, y = 0, z = 0;
    D.coords(pos, x, y, z);
    return box_index(x, y, z);
  }
  // The stamp of a new own search.
  uint16_t next_stamp() {
    if (cur == 0xFFFF) {
      std::fill(stamp.begin(), stamp.end(), uint16_t{0});
      std::fill(queued.begin(), queued.end(), uint32_t{0});
      cur = 0;
      ++stamp_resets;
    }
    return ++cur;
  }
  [[nodiscard]] uint32_t pdist(uint32_t v) const { return pdist8.empty() ? pdist16[v] : pdist8[v]; }
  [[nodiscard]] bool pivot_visited(uint32_t v) const { return pdist(v) != 0; }
  [[nodiscard]] uint32_t pivot_at(uint32_t v) const { return pdist(v) - 1; }
  [[nodiscard]] uint64_t bytes() const {
    uint64_t qb = 0;
    for (const auto& b : buckets) qb += b.capacity() * sizeof(Entry);
    uint64_t lb = lm_pos.capacity() * 8;
    for (const Landmark& L : lm) lb += L.f.size() + L.list.capacity() * 4;
    return stamp.size() * 2 + queued.size() * 4 + pdist8.size() + pdist16.size() * 2 + pqueue.capacity() * 4 + qpos.capacity() * 8 +
           buckets.capacity() * sizeof(buckets[0]) + qb + lb;
  }

private:
  void allocate(size_t n, uint32_t pivot_limit) {
    stamp.assign(n, 0);
    if (pivot_limit == 0) return;
    queued.assign(n, 0);
    if (pivot_limit <= 254) pdist8.assign(n, 0);
    else pdist16.assign(n, 0);
  }
};

// Object voxels grouped by base point, as offsets from their base (3 bytes: the negated b(p) - p);
// where that does not fit in 8 bits per axis (dx == kFar) the padded position is in `far`, sorted
// by slot.
struct Members {
  std::vector<BaseOffset> off;
  std::vector<std::pair<uint32_t, int64_t>> far;  // (slot, padded position)
  int64_t BX = 0, BY = 0;
  // Padded position of member slot `i` of the bucket of the base at padded position `base_pos`.
  [[nodiscard]] int64_t at(size_t i, int64_t base_pos) const {
    const BaseOffset o = off[i];
    if (o.dx == kFar)
      return std::lower_bound(far.begin(), far.end(), std::pair<uint32_t, int64_t>{static_cast<uint32_t>(i), std::numeric_limits<int64_t>::min()})->second;
    return base_pos + o.dx + BX * (o.dy + BY * static_cast<int64_t>(o.dz));
  }
  [[nodiscard]] uint64_t bytes() const { return off.size() * sizeof(BaseOffset) + far.size() * 16; }
};

// The considered neighbours of object voxel `pos` and their base points: f(padded position).
template <class F>
void for_each_target_pos(const Prepared& P, int64_t pos, F&& f) {
  const int64_t offs[3] = {1, P.dom.BX, P.dom.plane};
  for (int64_t o : offs) {
    // Lower neighbour: always (object or layer).
    f(P.base_pos(pos - o));
    // Upper neighbour: only if background (then it is in L).
    if (!P.obj.test(pos + o)) f(pos + o);
  }
}
// The same, L-ids only.
template <class F>
void for_each_target(const Prepared& P, int64_t pos, F&& f) {
  for_each_target_pos(P, pos, [&](int64_t bp) { f(static_cast<uint32_t>(P.layer.rank(bp))); });
}

// Phase 2: object voxels grouped by base point b(p) (counting sort): the voxels of base l are
// the slots begin(l) .. end(l) of `members`, in raster order (positions: member(slot, base position)). The bucket bounds are kept
// compactly: a member count per L voxel (1 byte; 255 = look the count up in `big`) and the first
// slot of every 64 L voxels (4 bytes), so about 1.06 bytes per L voxel instead of 4; begin(l) adds
// the counts of up to 63 preceding L voxels.
struct Buckets {
  std::vector<uint8_t> count;                       // per L-id: members, 255 = in `big`
  std::vector<std::pair<uint32_t, uint32_t>> big;   // (L-id, members) where >= 255, sorted
  std::vector<uint32_t> block;                      // per 64 L-ids: first member slot; one more at the end
  Members members;
  [[nodiscard]] bool has_work(uint32_t l) const { return count[l] != 0; }
  [[nodiscard]] uint32_t members_of(uint32_t l) const {
    if (count[l] != 255) return count[l];
    return std::lower_bound(big.begin(), big.end(), std::pair<uint32_t, uint32_t>{l, 0})->second;
  }
  [[nodiscard]] uint32_t begin(uint32_t l) const {
    const uint32_t b0 = l & ~uint32_t{63};
    uint32_t s = block[l >> 6], nbig = 0;
    for (uint32_t j = b0; j < l; ++j) {
      s += count[j];
      nbig += count[j] == 255;
    }
    if (nbig)
      for (uint32_t j = b0; j < l; ++j)
        if (count[j] == 255) s += members_of(j) - 255;
    return s;
  }
  [[nodiscard]] uint32_t end(uint32_t l) const { return begin(l) + members_of(l); }
  [[nodiscard]] int64_t member(uint32_t slot, int64_t base_pos) const { return members.at(slot, base_pos); }
  [[nodiscard]] uint64_t bytes() const { return count.size() + big.size() * 8 + block.size() * 4 + members.bytes(); }
};
// Parallel over chunks of base planes (the result does not depend on the thread count).
Buckets bucket_by_base(const Prepared& P, int threads = 1);

// The 6-neighbours of the L voxel at padded position `pos` that are in L: f(L-id, position).
// (Searches queue positions as well as L-ids, so a visit needs no coordinate look-up.)
template <class F>
inline void for_each_layer_neighbour(const Prepared& P, int64_t pos, F&& f) {
  const int64_t nb[6] = {pos - 1, pos + 1, pos - P.dom.BX, pos + P.dom.BX, pos - P.dom.plane, pos + P.dom.plane};
  for (int64_t q : nb)
    if (P.layer.test(q)) f(static_cast<uint32_t>(P.layer.rank(q)), q);
}

// Own search: A* over L from `src` towards the targets `want` (L-ids, at padded positions
// `want_pos`), with h = the smallest 1-norm distance to a target not reached yet (a lower bound on
// any 6-path, and consistent), so only voxels v with g(src, v) + h(v) <= limit are ever queued (the
// bounded search) and the search stops as soon as every target is reached or no open voxel has a key
// <= limit (early termination). Writes the exact distances <= limit to `wd` (kNone = farther than
// `limit`: no 6-path in L that short). Returns the number of voxels closed (visited). Nothing needs
// clearing afterwards (range-encoded marks, see Scratch). With the worker's landmark fields (ALT,
// see Scratch::Landmark) each target's bound is max(1-norm, |f(c) - f(v)|) over the fields that hold
// the target: still consistent, so the distances are the same and fewer voxels are closed; after a
// search that closed at least S.lm_min_visited voxels a field is built from its far target (its
// voxels are counted in the returned number).

int64_t own_bfs(const Prepared& P, Scratch& S, uint32_t src, int64_t src_pos, uint32_t limit,
                const std::vector<uint32_t>& want, const std::vector<int64_t>& want_pos, std::vector<uint32_t>& wd);

// Pivot search: breadth-first over all of L within distance `limit` (< 65535) from `src`; the
// distances stay readable (S.pivot_at) until the next pivot search, S.pqueue lists the visited
// voxels in distance order; where S.fields, the own searches that follow in the block use them as
// one more landmark field (clipped at limit + 1). Returns the number of visited voxels.
int64_t pivot_bfs(const Prepared& P, Scratch& S, uint32_t src, int64_t src_pos, uint32_t limit);

// What the workers of phase 3 share: inputs, the output, the claims and the counters.
struct SearchShared {
  const Prepared& P;
  const Buckets& B;
  const VolumeU8& mask;
  float* importance;       // output, mask.size() values (each voxel written once)
  uint32_t t = 0;          // threshold
  bool full = false;       // Mode::Full
  uint32_t pivot_margin = 0;  // 0 = no pivots
  bool force_box = false;     // tests: box scratch even where dense would be smaller
  bool landmarks = true;      // tests and benchmarks: landmark fields for the A* (same results)
  int64_t landmark_min_visited = -1;  // tests: a field after searches this large (-1: 8 t)
  // Bases are claimed once: by their own search or by a neighbouring pivot.
  std::vector<std::atomic<uint64_t>> claimed;
  std::atomic<int64_t> n_landmarks{0}, n_pivots{0}, n_long{0}, n_search{0}, n_saturated{0}, n_visited{0}, n_bases{0}, done_bases{0};

  SearchShared(const Prepared& p, const Buckets& b, const VolumeU8& m, float* out, uint32_t threshold, bool full_mode);
  // True for the one caller that claims base l.
  bool claim(uint32_t l) {
    const uint64_t bit = uint64_t{1} << (l & 63);
    return !(claimed[l >> 6].fetch_or(bit) & bit);
  }
  // Index in the mask of the object voxel at padded position `pos`.
  [[nodiscard]] int64_t mask_index(int64_t pos) const {
    int64_t x = 0, y = 0, z = 0;
    P.dom.coords(pos, x, y, z);
    return mask.index(x - 2, y - 2, z - 2);
  }
};

// The work on one base's bucket (and, after a pivot, on a neighbouring base's).
class BaseWork {
public:
  BaseWork(SearchShared& sh, Scratch& S) : sh_(sh), S_(S) {}
  // targets = the distinct bases of the considered neighbours of the bucket's voxels; tdist = kNone.
  // Also lists the bucket's voxels (mpos) and the targets of each (mtarget, mcount) for mark_needed and finish.
  void gather(uint32_t base_id, int64_t base_pos);
  // In threshold mode a voxel with a target already proved >= t (by a pivot) has importance t, so
  // its other targets are searched only if another voxel of the bucket needs them: needed[i].
  void mark_needed();
  // Own search from `base_id` for the targets not settled yet (tdist == kNone) that lie in the same
  // component of L (the others have no path: infinite). Returns true if targets were left when the
  // search reached the threshold.
  bool own_search(uint32_t base_id, int64_t base_pos);
  // Importance of the bucket's voxels from tdist.
  void finish();

  std::vector<uint32_t> targets, tdist;
  std::vector<int64_t> tpos;  // padded positions of the targets
  std::vector<int64_t> mpos;  // padded positions of the bucket's voxels
  std::vector<uint32_t> mtarget;  // per voxel, in order, the indices in `targets` of its considered neighbours' bases
  std::vector<uint8_t> mcount;    // per voxel: how many (3 to 6)
  std::vector<uint8_t> needed;

private:
  SearchShared& sh_;
  Scratch& S_;
  std::vector<uint32_t> want_, wd_;
  std::vector<int64_t> want_pos_;
  std::vector<size_t> want_index_;
};

// Processes base `a`: its own search, and, when that search runs to the threshold, a pivot search
// to t + margin that settles the far targets of all bases within `margin` of `a` (triangle
// inequality: g(a', c) >= g(a, c) - g(a, a') >= t).
// `w` is the worker's (its vectors are reused from base to base).
void process_base(SearchShared& sh, Scratch& S, BaseWork& w, uint32_t a, int64_t apos);

// How search_bases cuts the work: blocks of bases (nbx x nby x nbz, x in whole words) and the
// workers' scratch: a box of bw x bh x bd voxels around a block, or dense (one entry per L voxel).
struct SearchLayout {
  int64_t nbx = 1, nby = 1, nbz = 1, halo = 0, bw = 0, bh = 0, bd = 0;
  bool boxed = false;
};
SearchLayout search_layout(const SearchShared& sh);

// Phase 3: every base with work, claimed once, on `threads` workers; returns the bytes of the
// workers' scratch. The importance does not depend on the thread count.
uint64_t search_bases(SearchShared& sh, int threads, const Interrupter& progress);

// Phase 4: skeleton[i] = importance[i] >= t.
void threshold_surface(const VolumeF32& importance, VolumeU8& skeleton, uint32_t t, int threads);

}  // namespace skel::geodesic::detail
