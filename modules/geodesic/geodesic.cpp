// Geodesic boundary distance (thesis §2.3.2); the phases are declared in geodesic_phases.hpp.
#include "geodesic/geodesic.hpp"

#include <algorithm>
#include <atomic>
#include <bit>
#include <chrono>
#include <cmath>
#include <limits>
#include <mutex>
#include <type_traits>
#include <unordered_map>
#include <vector>

#include "geodesic/geodesic_phases.hpp"
#include "skel/error.hpp"
#include "skel/parallel.hpp"

namespace skel::geodesic {

namespace detail {

std::vector<int64_t> offsets26(const Domain& d) {
  std::vector<int64_t> o;
  for (int dz = -1; dz <= 1; ++dz)
    for (int dy = -1; dy <= 1; ++dy)
      for (int dx = -1; dx <= 1; ++dx)
        if (dx || dy || dz) o.push_back(dx + d.BX * (dy + d.BY * dz));
  return o;
}

namespace {

// The 26-dilation of the bitmap `src` over the padded domain at word i of row (y, z): the OR of the
// 3x3x3 neighbourhood of each of its 64 voxels (rows y - 1 .. y + 1 and planes z - 1 .. z + 1 must exist).
uint64_t dilated_word(const uint64_t* src, const Domain& D, int64_t y, int64_t z, int64_t i) {
  const int64_t rw = D.row_words();
  uint64_t r = 0;
  for (int dz = -1; dz <= 1; ++dz)
    for (int dy = -1; dy <= 1; ++dy) {
      const uint64_t* row = src + ((y + dy) + D.BY * (z + dz)) * rw;
      const uint64_t c = row[i], prev = i > 0 ? row[i - 1] : 0, next = i + 1 < rw ? row[i + 1] : 0;
      r |= c | (c << 1) | (prev >> 63) | (c >> 1) | (next << 63);
    }
  return r;
}

// Object id of the voxel at bit `bit` of a word whose object bits are `ob` and whose first object id is `id0`.
uint64_t id_at_bit(uint64_t ob, uint64_t id0, int bit) {
  return id0 + static_cast<uint64_t>(std::popcount(ob & ((uint64_t{1} << bit) - 1)));
}

}  // namespace

void build_bitmaps(const VolumeU8& mask, Prepared& P, int threads, const Interrupter& intr) {
  const Domain& D = P.dom;
  if (D.nx > 65000 || D.ny > 65000 || D.nz > 65000)
    throw InputError("geodesic: volumes up to 65000 voxels per axis are supported");
  const size_t nwords = static_cast<size_t>(D.bits() / 64);
  const int64_t rw = D.row_words();
  P.obj.assign_zero(nwords);
  // Object bits, parallel over z (rows are word-aligned, so slices never share a word).
  parallel_for(0, D.nz, threads, [&](int64_t z0, int64_t z1) {
    for (int64_t z = z0; z < z1; ++z)
      for (int64_t y = 0; y < D.ny; ++y) {
        const uint8_t* row = mask.data() + mask.index(0, y, z);
        const int64_t base = D.pos(2, y + 2, z + 2);
        for (int64_t x = 0; x < D.nx; ++x)
          if (row[x]) P.obj.words[static_cast<size_t>((base + x) >> 6)] |= uint64_t{1} << ((base + x) & 63);
      }
  });
  intr.check(0.02);
  // L = dilate26(O) minus O, over every row but the outermost guard rows.
  P.layer.assign_zero(nwords);
  parallel_for(1, D.BZ - 1, threads, [&](int64_t z0, int64_t z1) {
    for (int64_t z = z0; z < z1; ++z)
      for (int64_t y = 1; y < D.BY - 1; ++y)
        for (int64_t i = 0; i < rw; ++i) {
          const size_t w = static_cast<size_t>((y + D.BY * z) * rw + i);
          P.layer.words[w] = dilated_word(P.obj.words.data(), D, y, z, i) & ~P.obj.words[w];
        }
  });
  P.k = static_cast<int64_t>(P.obj.build_rank());
  P.nl = static_cast<int64_t>(P.layer.build_rank());
  if (P.nl >= static_cast<int64_t>(kNone) || P.k >= static_cast<int64_t>(kNone))
    throw InputError("geodesic: more than 4·10^9 object or boundary voxels are not supported");
  intr.check(0.05);
}

void layer_coordinates(Prepared& P, int threads) {
  const Domain& D = P.dom;
  const size_t nwords = static_cast<size_t>(D.bits() / 64);
  P.lcoord.resize(static_cast<size_t>(P.nl));
  parallel_for(0, static_cast<int64_t>(nwords), threads, [&](int64_t w0, int64_t w1) {
    uint64_t id = P.layer.prefix(static_cast<size_t>(w0));  // then counted along
    for (int64_t w = w0; w < w1; ++w) {
      uint64_t bits = P.layer.word(static_cast<size_t>(w));
      while (bits) {
        const int64_t pos = w * 64 + std::countr_zero(bits);
        bits &= bits - 1;
        const int64_t z = pos / D.plane, rem = pos % D.plane;
        P.lcoord[id++] = Coord{static_cast<uint16_t>(rem % D.BX), static_cast<uint16_t>(rem / D.BX),
                               static_cast<uint16_t>(z)};
      }
    }
  }, 4096);
}

namespace {

// A bitmap over object ids, set from several threads at once.
struct IdBits {
  std::vector<uint64_t> w;
  explicit IdBits(int64_t n) : w(static_cast<size_t>((n + 63) / 64), 0) {}
  void set(uint64_t i) { std::atomic_ref<uint64_t>(w[i >> 6]).fetch_or(uint64_t{1} << (i & 63), std::memory_order_relaxed); }
  [[nodiscard]] bool test(uint64_t i) const { return (w[i >> 6] >> (i & 63)) & 1u; }
  // test() while other threads set bits.
  [[nodiscard]] bool test_shared(uint64_t i) {
    return (std::atomic_ref<uint64_t>(w[i >> 6]).load(std::memory_order_relaxed) >> (i & 63)) & 1u;
  }
  // Bits i0 .. i0 + n - 1 (n <= 64) as the low bits of one word.
  [[nodiscard]] uint64_t get(uint64_t i0, int n) const {
    if (n == 0) return 0;
    const size_t a = static_cast<size_t>(i0 >> 6);
    const int sh = static_cast<int>(i0 & 63);
    uint64_t v = w[a] >> sh;
    if (sh && sh + n > 64) v |= w[a + 1] << (64 - sh);
    return n == 64 ? v : v & ((uint64_t{1} << n) - 1);
  }
  void clear() { std::fill(w.begin(), w.end(), uint64_t{0}); }
  [[nodiscard]] uint64_t bytes() const { return w.size() * 8; }
};

}  // namespace

void nearest_points(const Vec3& sp, Prepared& P, int threads, const Interrupter& intr) {
  // Nearest background point: rings of 26-neighbours inward from L. Ring r+1 = unreached object
  // voxels 26-adjacent to ring r; each takes, among its neighbours of earlier rings, the nearest point
  // that is closest in physical distance (ties: the lower position, i.e. the lower L-id). Values
  // depend only on earlier rings, so the result is independent of thread count. Works on the offsets
  // b(p) - p directly (a neighbour's candidate is its own offset plus the step), so neither the L
  // coordinates nor the L-ids of b are needed; the rings are bitmaps over object ids (1 bit per
  // object voxel each, for this ring and the next), walked along the object bitmap.
  const Domain& D = P.dom;
  const int64_t nwords = static_cast<int64_t>(P.obj.word_count());
  struct Nb {
    int64_t off;
    int32_t dx, dy, dz;
  };
  std::vector<Nb> nbs;
  for (int dz = -1; dz <= 1; ++dz)
    for (int dy = -1; dy <= 1; ++dy)
      for (int dx = -1; dx <= 1; ++dx)
        if (dx || dy || dz) nbs.push_back(Nb{dx + D.BX * (dy + D.BY * dz), dx, dy, dz});
  P.boff.assign(static_cast<size_t>(P.k), kUnsetOffset);
  const DenseRanks orank(P.obj);  // object ids of neighbours (through the word prefixes prepare() builds)
  // Object id -> padded position of b(p) where the offset does not fit in 8 bits (rare: objects
  // more than 127 voxels thick); read during a ring, written between rings.
  std::unordered_map<uint64_t, int64_t> far;
  auto coords = [&](int64_t pos, int32_t& x, int32_t& y, int32_t& z) {
    z = static_cast<int32_t>(pos / D.plane);
    const int64_t r = pos % D.plane;
    y = static_cast<int32_t>(r / D.BX);
    x = static_cast<int32_t>(r % D.BX);
  };
  IdBits ring(P.k), next(P.k);
  // Per worker range: voxels seen and far results (flushed at the end of the range).
  struct Local {
    std::vector<std::pair<uint64_t, int64_t>> far;
    int64_t n = 0;
  };
  // Calls f(pos, id, local) for every object voxel of `bits` (an IdBits) on `threads` workers, then
  // flush(local) once per worker range.
  auto for_each_in = [&](const IdBits& bits, auto&& f, auto&& flush) {
    parallel_for(0, nwords, threads, [&](int64_t w0, int64_t w1) {
      Local local;
      uint64_t next_id = P.obj.prefix(static_cast<size_t>(w0));  // object id of word w's first bit
      for (int64_t w = w0; w < w1; ++w) {
        uint64_t ob = P.obj.word(static_cast<size_t>(w));
        uint64_t id = next_id;
        next_id += static_cast<uint64_t>(std::popcount(ob));
        if (!ob) continue;
        uint64_t rb = bits.get(id, std::popcount(ob));
        for (; ob; ob &= ob - 1, rb >>= 1, ++id)
          if (rb & 1) f(w * 64 + std::countr_zero(ob), id, local);
      }
      flush(local);
    }, 2048);
  };
  // Ring 1 (object voxels with a background 26-neighbour, i.e. one in L), 64 voxels at a time: the
  // ring is obj & dilate26(L); a ring-1 voxel's candidates are its L neighbours only (its object
  // neighbours are in ring 1 or unassigned), so its nearest point is the first L neighbour in the
  // order of (physical distance, offset), the order the per-voxel rule below picks by (ties: the
  // lower position). Ring 2 = obj & ~ring1 & dilate26(ring1). ring1 is a bitmap over the padded
  // grid (1 bit per voxel), freed before the later rings.
  const int64_t rw = D.row_words();
  // Object voxels live in rows y = 2 .. ny + 1 of planes z = 2 .. nz + 1.
  auto for_object_rows = [&](auto&& f) {
    parallel_for(2, D.nz + 2, threads, [&](int64_t z0, int64_t z1) {
      for (int64_t z = z0; z < z1; ++z)
        for (int64_t y = 2; y < D.ny + 2; ++y)
          for (int64_t i = 0; i < rw; ++i) f(y, z, i, (y + D.BY * z) * rw + i);
    });
  };
  std::vector<uint64_t> ring1(static_cast<size_t>(nwords), 0);
  for_object_rows([&](int64_t y, int64_t z, int64_t i, int64_t w) {
    const uint64_t ob = P.obj.word(static_cast<size_t>(w));
    if (ob) ring1[static_cast<size_t>(w)] = ob & dilated_word(P.layer.words.data(), D, y, z, i);
  });
  {
    // The 26 offsets by (physical distance, offset).
    std::vector<std::pair<double, size_t>> order;
    for (size_t j = 0; j < nbs.size(); ++j) {
      const double ex = nbs[j].dx * sp[0], ey = nbs[j].dy * sp[1], ez = nbs[j].dz * sp[2];
      order.emplace_back(ex * ex + ey * ey + ez * ez, j);
    }
    std::sort(order.begin(), order.end(), [&](const auto& a, const auto& b) {
      return a.first < b.first || (a.first == b.first && nbs[a.second].off < nbs[b.second].off);
    });
    std::vector<Nb> byd;
    for (const auto& o : order) byd.push_back(nbs[o.second]);
    const uint64_t* lw = P.layer.words.data();
    parallel_for(0, nwords, threads, [&](int64_t w0, int64_t w1) {
      for (int64_t w = w0; w < w1; ++w) {
        uint64_t rem = ring1[static_cast<size_t>(w)];
        if (!rem) continue;
        const uint64_t ob = P.obj.word(static_cast<size_t>(w));
        const uint64_t id0 = P.obj.prefix(static_cast<size_t>(w));
        for (const Nb& n : byd) {
          // The L bits at offset n of the word's 64 voxels.
          const int64_t b = w * 64 + n.off;
          const int sh = static_cast<int>(b & 63);
          const size_t wi = static_cast<size_t>(b >> 6);
          const uint64_t l = sh ? (lw[wi] >> sh) | (lw[wi + 1] << (64 - sh)) : lw[wi];
          for (uint64_t sel = rem & l; sel; sel &= sel - 1)
            P.boff[id_at_bit(ob, id0, std::countr_zero(sel))] =
                BaseOffset{static_cast<int8_t>(n.dx), static_cast<int8_t>(n.dy), static_cast<int8_t>(n.dz)};
          rem &= ~l;
          if (!rem) break;
        }
      }
    }, 2048);
  }
  std::atomic<int64_t> in_ring1{0};
  for_object_rows([&](int64_t y, int64_t z, int64_t i, int64_t w) {
    const uint64_t ob = P.obj.word(static_cast<size_t>(w));
    if (!ob) return;
    const uint64_t r1 = ring1[static_cast<size_t>(w)];
    if (r1) in_ring1.fetch_add(std::popcount(r1), std::memory_order_relaxed);
    const uint64_t r2 = ob & ~r1 & dilated_word(ring1.data(), D, y, z, i);
    const uint64_t id0 = P.obj.prefix(static_cast<size_t>(w));
    for (uint64_t sel = r2; sel; sel &= sel - 1) ring.set(id_at_bit(ob, id0, std::countr_zero(sel)));
  });
  P.prepare_bytes = std::max(P.prepare_bytes, P.obj.bytes() + P.layer.bytes() + P.base_bytes() + ring.bytes() +
                                                  next.bytes() + ring1.size() * 8);
  std::vector<uint64_t>().swap(ring1);
  intr.check(0.1);
  int64_t assigned = in_ring1.load();
  std::mutex far_mutex;
  std::vector<std::pair<uint64_t, int64_t>> newfar;
  std::atomic<int64_t> in_ring{0};
  for (;;) {
    // This ring: each voxel's b from its neighbours of earlier rings, written in place (the
    // neighbours in this ring are skipped by their ring bit, so nobody reads a value being written).
    // The same walk marks the next ring: the unassigned object neighbours of this ring (their
    // offsets are not written during this walk).
    newfar.clear();
    in_ring = 0;
    next.clear();
    {
      for_each_in(ring, [&](int64_t pos, uint64_t id, Local& local) {
        ++local.n;
        int32_t px = 0, py = 0, pz = 0;
        bool have_p = false;
        int64_t bpos = std::numeric_limits<int64_t>::max();
        int32_t bx = 0, by = 0, bz = 0;
        double bd = std::numeric_limits<double>::infinity();
        uint64_t row_id = 0;  // object id of the row's dx = -1 neighbour
        // Rings from 2 on have no L voxel among their 26 neighbours (ring 1 holds every object voxel
        // that has one), and every background 26-neighbour of an object voxel is in L: so all 26
        // neighbours are object voxels, and the three of a row have consecutive object ids (one
        // rank per row instead of one per neighbour; nbs runs dx = -1, 0, 1 within each row).
        for (const Nb& n : nbs) {
          const int64_t q = pos + n.off;
          int32_t cx, cy, cz;  // offset from p to the candidate
          int64_t cpos;
          {
            if (n.dx == -1) row_id = orank(q);
            const uint64_t qi = row_id + static_cast<uint64_t>(n.dx + 1);
            if (ring.test(qi)) continue;  // this ring: not committed
            const BaseOffset o = P.boff[qi];
            if (o.dx == kFar) {
              if (o.dy != 0) {  // not assigned yet: in the next ring (ring r+1 = unassigned neighbours of ring r)
                if (!next.test_shared(qi)) next.set(qi);
                continue;
              }
              cpos = far.at(qi);
              if (!have_p) {
                coords(pos, px, py, pz);
                have_p = true;
              }
              int32_t fx, fy, fz;
              coords(cpos, fx, fy, fz);
              cx = fx - px, cy = fy - py, cz = fz - pz;
            } else {
              cx = n.dx + o.dx, cy = n.dy + o.dy, cz = n.dz + o.dz;
              cpos = q + o.dx + D.BX * (o.dy + D.BY * static_cast<int64_t>(o.dz));
            }
          }
          const double ex = static_cast<double>(cx) * sp[0], ey = static_cast<double>(cy) * sp[1],
                       ez = static_cast<double>(cz) * sp[2];
          const double d = ex * ex + ey * ey + ez * ez;
          // Ties: the lower position (= the lower L-id).
          if (d < bd || (d == bd && cpos < bpos)) {
            bd = d;
            bpos = cpos;
            bx = cx, by = cy, bz = cz;
          }
        }
        if (std::max({std::abs(bx), std::abs(by), std::abs(bz)}) <= 127) {
          P.boff[id] = BaseOffset{static_cast<int8_t>(bx), static_cast<int8_t>(by), static_cast<int8_t>(bz)};
        } else {
          P.boff[id] = BaseOffset{kFar, 0, 0};
          local.far.emplace_back(id, bpos);
        }
      }, [&](Local& local) {
        in_ring += local.n;
        if (!local.far.empty()) {
          std::lock_guard lock(far_mutex);
          newfar.insert(newfar.end(), local.far.begin(), local.far.end());
        }
      });
    }
    if (in_ring.load() == 0) break;
    for (const auto& [oid, bp] : newfar) far[oid] = bp;
    assigned += in_ring.load();
    std::swap(ring, next);
    intr.check(0.08 + 0.12 * static_cast<double>(assigned) / static_cast<double>(std::max<int64_t>(P.k, 1)));
  }
  P.bfar.assign(far.begin(), far.end());
  std::sort(P.bfar.begin(), P.bfar.end());
  P.prepare_bytes = std::max(P.prepare_bytes, P.obj.bytes() + P.layer.bytes() + P.base_bytes() + ring.bytes() +
                                                  next.bytes() + far.size() * 32);
}

void base_ids(Prepared& P, int threads) {
  P.b.assign(static_cast<size_t>(P.k), kNone);
  const int64_t nwords = static_cast<int64_t>(P.obj.word_count());
  parallel_for(0, nwords, threads, [&](int64_t w0, int64_t w1) {
    uint64_t id = P.obj.prefix(static_cast<size_t>(w0));  // then counted along
    for (int64_t w = w0; w < w1; ++w) {
      uint64_t bits = P.obj.word(static_cast<size_t>(w));
      for (; bits; bits &= bits - 1, ++id) {
        const int64_t pos = w * 64 + std::countr_zero(bits);
        P.b[id] = static_cast<uint32_t>(P.layer.rank(P.base_pos_of_object(id, pos)));
      }
    }
  }, 4096);
}

void layer_components(Prepared& P) {
  const Domain& D = P.dom;
  // 6-connected components of L (union-find with path halving over forward neighbours).
  P.lcomp.resize(static_cast<size_t>(P.nl));
  for (int64_t i = 0; i < P.nl; ++i) P.lcomp[static_cast<size_t>(i)] = static_cast<uint32_t>(i);
  auto find = [&](uint32_t a) {
    while (P.lcomp[a] != a) {
      P.lcomp[a] = P.lcomp[P.lcomp[a]];
      a = P.lcomp[a];
    }
    return a;
  };
  uint32_t i = 0;  // L-id, counted along
  for (size_t w = 0; w < P.layer.word_count(); ++w) {
    uint64_t bits = P.layer.word(w);
    for (; bits; bits &= bits - 1, ++i) {
      const int64_t pos = static_cast<int64_t>(w) * 64 + std::countr_zero(bits);
      for (int64_t o : {int64_t{1}, D.BX, D.plane}) {
        if (!P.layer.test(pos + o)) continue;
        uint32_t a = find(i), c = find(static_cast<uint32_t>(P.layer.rank(pos + o)));
        if (a != c) P.lcomp[std::max(a, c)] = std::min(a, c);
      }
    }
  }
  for (int64_t i = 0; i < P.nl; ++i) P.lcomp[static_cast<size_t>(i)] = find(static_cast<uint32_t>(i));
}

void prepare(const VolumeU8& mask, Prepared& P, int threads, const Interrupter& intr, bool keep_coords,
             bool components) {
  build_bitmaps(mask, P, threads, intr);
  intr.check(0.08);
  // The rings rank object neighbours many times per voxel: word prefixes while they run (counted in
  // their bytes; the searches need less memory than this phase's peak and go without them).
  P.obj.build_word_prefixes();
  nearest_points(mask.spacing(), P, threads, intr);
  P.obj.drop_word_prefixes();
  if (keep_coords) {
    layer_coordinates(P, threads);
    base_ids(P, threads);
    P.prepare_bytes = std::max(P.prepare_bytes, P.obj.bytes() + P.layer.bytes() + P.lcoord.size() * sizeof(Coord) +
                                                    P.b.size() * 4 + P.base_bytes());
  }
  if (components) layer_components(P);
  intr.check(0.22);
}

namespace {

// Fills the members of the buckets one chunk owns, in raster order, without a cursor array: while
// a bucket of fewer than 255 members is being filled, its last slot holds the number placed so far
// (0 initially) until that slot gets its own member, which is the last one; the few larger buckets
// keep cursors in a map. Members with far offsets go to `far` (slot, position).
template <class ForEachBase>
void members_fill(Buckets& bk, std::vector<std::pair<uint32_t, int64_t>>& far, ForEachBase&& for_each_base) {
  Members& members = bk.members;
  std::unordered_map<uint32_t, uint32_t> cursor;  // buckets of 255 members and more
  for_each_base([&](int64_t pos, uint32_t l, BaseOffset o) {
    const uint32_t b = bk.begin(l);
    uint32_t slot;
    if (bk.count[l] == 255) {
      slot = b + cursor[l]++;
    } else {
      const uint32_t n = bk.count[l];
      const uint32_t placed = n == 1 ? 0 : static_cast<uint8_t>(members.off[b + n - 1].dx);
      slot = b + placed;
      if (placed + 1 < n) members.off[b + n - 1].dx = static_cast<int8_t>(static_cast<uint8_t>(placed + 1));
    }
    // The member's offset from its base is the negated offset from the member to its base.
    if (o.dx != kFar) {
      members.off[slot] = BaseOffset{static_cast<int8_t>(-o.dx), static_cast<int8_t>(-o.dy), static_cast<int8_t>(-o.dz)};
    } else {
      members.off[slot] = BaseOffset{kFar, 0, 0};
      far.emplace_back(slot, pos);
    }
  });
}

}  // namespace

Buckets bucket_by_base(const Prepared& P, int threads) {
  Buckets bk;
  const Domain& D = P.dom;
  const size_t nl = static_cast<size_t>(P.nl);
  // Work in chunks of base planes: a chunk owns the buckets of the bases in its planes (a range of
  // L-ids) and walks the object voxels within R planes of them (R: the largest |dz| of an offset;
  // every plane where an offset is far), in raster order. Each bucket is counted and filled by its
  // one owner in raster order, so the buckets are those of one sequential walk for any chunking.
  int64_t R = 0;
  if (!P.bfar.empty()) {
    R = D.BZ;
  } else {
    std::vector<int64_t> rmax(64, 0);
    parallel_chunks(0, P.k, 64, threads, [&](int64_t c, int64_t i0, int64_t i1) {
      int64_t r = 0;
      for (int64_t i = i0; i < i1; ++i) r = std::max<int64_t>(r, std::abs(static_cast<int>(P.boff[static_cast<size_t>(i)].dz)));
      rmax[static_cast<size_t>(c)] = r;
    });
    R = *std::max_element(rmax.begin(), rmax.end());
  }
  const int64_t plane_words = D.plane / 64;
  // f(pos, L-id of the base, offset) for the object voxels whose base lies in planes [z0, z1), in raster order.
  auto for_each_base_in = [&](int64_t z0, int64_t z1, auto&& f) {
    const size_t w0 = static_cast<size_t>(std::max<int64_t>(0, z0 - R) * plane_words);
    const size_t w1 = static_cast<size_t>(std::min<int64_t>(D.BZ, z1 + R) * plane_words);
    const int64_t b0 = z0 * D.plane, b1 = z1 * D.plane;
    uint64_t id = P.obj.prefix(w0);  // then counted along
    for (size_t w = w0; w < w1; ++w) {
      uint64_t bits = P.obj.word(w);
      for (; bits; bits &= bits - 1, ++id) {
        const int64_t pos = static_cast<int64_t>(w) * 64 + std::countr_zero(bits);
        const int64_t bp = P.base_pos_of_object(id, pos);
        if (bp < b0 || bp >= b1) continue;
        f(pos, static_cast<uint32_t>(P.layer.rank(bp)), P.boff[id]);
      }
    }
  };
  // Chunks: up to two per thread, at least 8 R planes thick (each walks 2 R planes more than it owns).
  const int64_t nthreads = effective_threads(threads);
  const int64_t nchunks = std::clamp<int64_t>(D.BZ / std::max<int64_t>(1, 8 * R), 1, 2 * nthreads);
  auto chunk_planes = [&](int64_t c, int64_t& z0, int64_t& z1) {
    z0 = D.BZ * c / nchunks;
    z1 = D.BZ * (c + 1) / nchunks;
  };
  bk.count.assign(nl, 0);
  std::vector<std::vector<std::pair<uint32_t, uint32_t>>> big(static_cast<size_t>(nchunks));  // counts >= 255
  parallel_chunks(0, nchunks, nchunks, threads, [&](int64_t c, int64_t, int64_t) {
    int64_t z0, z1;
    chunk_planes(c, z0, z1);
    std::unordered_map<uint32_t, uint32_t> local;
    for_each_base_in(z0, z1, [&](int64_t, uint32_t l, BaseOffset) {
      if (bk.count[l] < 255) {
        if (++bk.count[l] == 255) local[l] = 255;
      } else {
        ++local[l];
      }
    });
    big[static_cast<size_t>(c)].assign(local.begin(), local.end());
  });
  for (const auto& b : big) bk.big.insert(bk.big.end(), b.begin(), b.end());
  std::sort(bk.big.begin(), bk.big.end());
  big.clear();
  bk.block.assign((nl + 63) / 64, 0);
  {
    uint32_t s = 0;
    for (size_t l = 0; l < nl; ++l) {
      if ((l & 63) == 0) bk.block[l >> 6] = s;
      s += bk.members_of(static_cast<uint32_t>(l));
    }
  }
  Members& members = bk.members;
  members.off.assign(static_cast<size_t>(P.k), BaseOffset{0, 0, 0});
  members.far.clear();
  members.BX = D.BX;
  members.BY = D.BY;
  std::vector<std::vector<std::pair<uint32_t, int64_t>>> far(static_cast<size_t>(nchunks));
  parallel_chunks(0, nchunks, nchunks, threads, [&](int64_t c, int64_t, int64_t) {
    int64_t z0, z1;
    chunk_planes(c, z0, z1);
    members_fill(bk, far[static_cast<size_t>(c)], [&](auto&& f) { for_each_base_in(z0, z1, f); });
  });
  for (const auto& f : far) members.far.insert(members.far.end(), f.begin(), f.end());
  std::sort(members.far.begin(), members.far.end());
  return bk;
}

namespace {

// Landmark policy: a field (about 2 t^2 voxels on a flat surface, both sides of a thin plate) is
// built after an own search that closed at least S.lm_min_visited voxels (8 t by default: rim
// crossings), unless a field already starts within kLandmarkReuse steps of its far target. Measured
// on 256³ plates, t = 40 (bench/RESULTS.md, session 9): t and 4 t cost more than they save, 9-18 t
// the same; reuse distances 2-16 make little difference. Measured again with the code of session 19
// (instructions at 192³, wall time at 512³, t = 40): 6-8 t 4-6 % fewer instructions than 12 t on
// plates and mixed (24-50 t: 27-29 % more on mixed); the search's wall time about 10 % shorter on
// mixed (the bone phantom), unchanged on plates.
constexpr uint32_t kLandmarkReuse = 8;

// f(std::integral_constant<int, n>) for n = 0 .. 5: the six 6-neighbours' steps as constants of
// each call (the loops over them unrolled).
template <class F>
[[gnu::always_inline]] inline void for_six_neighbours(F&& f) {
  [&]<int... N>(std::integer_sequence<int, N...>) { (f(std::integral_constant<int, N>{}), ...); }(std::make_integer_sequence<int, 6>{});
}

// Breadth-first search over L from scratch index `si` at padded position `src_pos` to the distance
// `limit`: dist[v] = distance + 1 (entries must be 0 beforehand), `list` and `posq` the visited
// voxels (scratch indices, positions) in distance order; returns their number. Processed layer by
// layer (no distance read per voxel) into vectors written by index (resized to their capacity
// without initialising, grown by doubling, cut to size at the end): the same order as a plain FIFO
// queue.
template <bool kBoxed, class T>
size_t layered_bfs(const Prepared& P, const Scratch& S, T* dist, QueueVector<uint32_t>& list, QueueVector<int64_t>& posq,
                   uint32_t si, int64_t src_pos, uint32_t limit) {
  const Domain& D = P.dom;
  const int64_t nb[6] = {-1, 1, -D.BX, D.BX, -D.plane, D.plane};
  const int64_t lb[6] = {-1, 1, -S.bw, S.bw, -S.bw * S.bh, S.bw * S.bh};  // the same steps in the box
  const DenseRanks lrank(P.layer);
  // Use the capacity left from earlier searches without reallocating.
  list.resize(std::max<size_t>(list.capacity(), 64));
  posq.resize(list.size());
  uint32_t* lq = list.data();
  int64_t* pq = posq.data();
  size_t cap = list.size(), tail = 0;
  dist[si] = 1;
  lq[tail] = si;
  pq[tail++] = src_pos;
  size_t head = 0;
  for (uint32_t d = 0; d < limit && head < tail; ++d) {
    const T next = static_cast<T>(d + 2);  // distance + 1 of the next layer
    for (const size_t layer_end = tail; head < layer_end; ++head) {
      if (tail + 6 > cap) {
        cap *= 2;
        list.resize(cap);
        posq.resize(cap);
        lq = list.data();
        pq = posq.data();
      }
      const uint32_t v = lq[head];
      const int64_t pos = pq[head];
      auto step = [&](auto nc) __attribute__((always_inline)) {  // unrolled: constant steps
        constexpr int n = decltype(nc)::value;
        const int64_t q = pos + nb[n];
        if constexpr (kBoxed) {
          // Without branches (whether a neighbour is new is data, and mispredicted about one time in
          // six): the box holds every neighbour of a voxel closer than the limit, L or not, and
          // entries off L stay 0, so the entry is read and written either way and the queue's tail
          // moves only for a new L voxel.
          const uint32_t u = static_cast<uint32_t>(static_cast<int64_t>(v) + lb[n]);
          const T du = dist[u];
          const T fresh = static_cast<T>(static_cast<T>(lrank.test(q)) & static_cast<T>(du == 0));
          dist[u] = static_cast<T>(du | (next & static_cast<T>(0 - fresh)));
          lq[tail] = u;
          pq[tail] = q;
          tail += fresh;
        } else {
          if (!lrank.test(q)) return;
          const uint32_t u = lrank(q);
          if (dist[u]) return;
          dist[u] = next;
          lq[tail] = u;
          pq[tail++] = q;
        }
      };
      for_six_neighbours(step);
    }
  }
  list.resize(tail);
  posq.resize(tail);
  return tail;
}

// Breadth-first field from the L voxel with scratch index `ci` at padded position `pos` to the
// radius S.lm_radius, into the next landmark slot. The caller checks that a box holds every voxel
// within the radius (a 6-path of length R stays within R on every axis), so the field is the true
// distance within the radius. Returns the voxels visited.
template <bool kBoxed>
int64_t landmark_bfs(const Prepared& P, Scratch& S, uint32_t ci, int64_t pos) {
  const int s2 = S.lm_next;
  S.lm_next = (S.lm_next + 1) % Scratch::kLandmarks;
  Scratch::Landmark& L = S.lm[s2];
  const size_t n = S.stamp.size();
  if (L.f.size() != n) L.f.assign(n, 0);
  for (uint32_t v : L.list) L.f[v] = 0;
  layered_bfs<kBoxed>(P, S, L.f.data(), L.list, S.lm_pos, ci, pos, S.lm_radius);
  L.on = true;
  ++S.lm_built;
  return static_cast<int64_t>(L.list.size());
}

constexpr uint32_t kClosedBit = 0x8000;  // in Scratch::queued: the voxel is closed in the search of the tag

template <bool kBoxed>
int64_t own_bfs_impl(const Prepared& P, Scratch& S, uint32_t src, int64_t src_pos, uint32_t limit,
                     const std::vector<uint32_t>& want, const std::vector<int64_t>& want_pos, std::vector<uint32_t>& wd) {
  const Domain& D = P.dom;
  wd.assign(want.size(), kNone);
  if (want.empty()) return 0;
  // Targets not reached yet: coordinates and index in `want`.
  struct Tgt {
    int32_t x, y, z;
    uint32_t i;
    int32_t fc[Scratch::kLandmarks + 1];  // field distances of the target (the last: the pivot's)
    uint32_t lmask;                       // fields that hold the target
  };
  constexpr int K = Scratch::kLandmarks;
  // The fields: the landmarks, and the last pivot search's distances (a field from a base like any
  // other: exact to its limit, clipped beyond), while it is there.
  const int nf = S.pivot_field ? K + 1 : K;
  auto f_on = [&](int s2) { return s2 < K ? S.lm[s2].on : S.pivot_field; };
  // The fields' arrays and clipped values (radius + 1), looked up by slot without branching on the
  // slot: every field is a byte array except 16-bit pivot distances (pivot limits above 254).
  const uint8_t* fbyte[K + 1];
  int32_t fclip[K + 1];
  for (int s2 = 0; s2 < K; ++s2) {
    fbyte[s2] = S.lm[s2].f.data();
    fclip[s2] = static_cast<int32_t>(S.lm_radius) + 1;
  }
  fbyte[K] = S.pdist8.empty() ? nullptr : S.pdist8.data();
  fclip[K] = static_cast<int32_t>(S.pivot_limit) + 1;
  const uint16_t* const fwide = S.pdist8.empty() ? S.pdist16.data() : nullptr;
  auto f_raw = [&](int s2, uint32_t v) -> uint32_t {
    return s2 == K && fwide ? fwide[v] : fbyte[s2][v];
  };
  auto f_val = [&](int s2, uint32_t v) -> int32_t {
    const uint32_t r = f_raw(s2, v);
    return r ? static_cast<int32_t>(r) - 1 : fclip[s2];
  };
  Tgt tg[64];
  std::vector<Tgt> tg_heap;
  Tgt* rem = tg;
  if (want.size() > 64) {
    tg_heap.resize(want.size());
    rem = tg_heap.data();
  }
  size_t nrem = 0;
  auto coords = [&](int64_t pos, int32_t& x, int32_t& y, int32_t& z) {
    int64_t x64 = 0, y64 = 0, z64 = 0;
    D.coords(pos, x64, y64, z64);
    x = static_cast<int32_t>(x64);
    y = static_cast<int32_t>(y64);
    z = static_cast<int32_t>(z64);
  };
  // Scratch index of the L voxel at padded (x, y, z) with L-id l, or kNone where a box does not
  // hold it.
  auto index_at = [&](int32_t x, int32_t y, int32_t z, uint32_t l) -> uint32_t {
    if constexpr (kBoxed) {
      if (x < S.bx0 || y < S.by0 || z < S.bz0 || x >= S.bx0 + S.bw || y >= S.by0 + S.bh || z >= S.bz0 + S.bd) return kNone;
      return S.box_index(x, y, z);
    } else {
      return l;
    }
  };
  for (size_t i = 0; i < want.size(); ++i) {
    Tgt t{};
    coords(want_pos[i], t.x, t.y, t.z);
    t.i = static_cast<uint32_t>(i);
    t.lmask = 0;
    const uint32_t ci = index_at(t.x, t.y, t.z, want[i]);
    for (int s2 = 0; s2 < nf; ++s2) {
      t.fc[s2] = 0;
      if (!f_on(s2) || ci == kNone || f_raw(s2, ci) == 0) continue;
      t.fc[s2] = f_val(s2, ci);
      t.lmask |= 1u << s2;
    }
    rem[nrem++] = t;
  }
  // Fields that some remaining target uses (recomputed when a target is reached).
  uint32_t fields_used = 0;
  for (size_t j = 0; j < nrem; ++j) fields_used |= rem[j].lmask;
  // h = the smallest lower bound over the remaining targets; each target's bound is the larger of
  // the 1-norm distance and its landmark bounds |f(c) - f(v)| (both consistent, so their max and
  // the min over targets are too: a closed voxel's g is final and the result is that of plain A*).
  // One target left (most searches): its fields as a short list of byte arrays, no minimum over
  // targets (with 16-bit pivot distances among its fields it goes the general way below).
  struct OneField {
    const uint8_t* f;
    int32_t fc, clip;
  };
  OneField one[K + 1];
  int n_one = -1;  // -1: the general way
  auto set_one = [&]() {
    n_one = -1;
    if (nrem != 1 || (fwide && (rem[0].lmask >> K & 1u))) return;
    n_one = 0;
    for (uint32_t lmk = rem[0].lmask; lmk; lmk &= lmk - 1) {
      const int s2 = std::countr_zero(lmk);
      one[n_one++] = OneField{fbyte[s2], rem[0].fc[s2], fclip[s2]};
    }
  };
  set_one();
  auto h = [&](int32_t x, int32_t y, int32_t z, uint32_t idx) __attribute__((always_inline)) {
    if (n_one >= 0) {
      const Tgt& c = rem[0];
      int32_t d = std::abs(x - c.x) + std::abs(y - c.y) + std::abs(z - c.z);
      for (int i = 0; i < n_one; ++i) {
        const uint32_t r = one[i].f[idx];
        d = std::max(d, std::abs(one[i].fc - (r ? static_cast<int32_t>(r) - 1 : one[i].clip)));
      }
      return static_cast<uint32_t>(d);
    }
    if (fields_used == 0) {
      uint32_t m = std::numeric_limits<uint32_t>::max();
      for (size_t j = 0; j < nrem; ++j) {
        const uint32_t d = static_cast<uint32_t>(std::abs(x - rem[j].x) + std::abs(y - rem[j].y) + std::abs(z - rem[j].z));
        m = std::min(m, d);
      }
      return m;
    }
    int32_t fv[Scratch::kLandmarks + 1];
    for (uint32_t fu = fields_used; fu; fu &= fu - 1) {
      const int s2 = std::countr_zero(fu);
      fv[s2] = f_val(s2, idx);
    }
    uint32_t m = std::numeric_limits<uint32_t>::max();
    for (size_t j = 0; j < nrem; ++j) {
      int32_t d = std::abs(x - rem[j].x) + std::abs(y - rem[j].y) + std::abs(z - rem[j].z);
      for (uint32_t lmk = rem[j].lmask; lmk; lmk &= lmk - 1) {
        const int s2 = std::countr_zero(lmk);
        d = std::max(d, std::abs(rem[j].fc[s2] - fv[s2]));
      }
      m = std::min(m, static_cast<uint32_t>(d));
    }
    return m;
  };
  const uint16_t st = S.next_stamp();
  auto& bk = S.buckets;
  uint32_t lo = 0, hi = 0;  // keys in use: [lo, hi]
  // Keys never exceed the limit: with a small limit the buckets are allocated once for all searches.
  const bool sized = limit < 65536;
  if (sized && bk.size() < static_cast<size_t>(limit) + 1) bk.resize(static_cast<size_t>(limit) + 1);
  int64_t nqueued = 0;
  auto push = [&](uint32_t key, const Scratch::Entry& e) __attribute__((always_inline)) {
    if (!sized && key >= bk.size()) bk.resize(static_cast<size_t>(key) + 1);
    bk[key].push(e);
    ++nqueued;
    hi = std::max(hi, key);
  };
  uint16_t gen = 0;  // targets reached so far, mod 2^16 (h changes only then)
  const bool track_gen = want.size() < 0xFFFF;  // else every pop recomputes h
  // Queued-g marks (Scratch::queued): a voxel is queued again only on a shorter path. With them,
  // bit 15 marks a closed voxel (g < 2^15), so a pop and an expansion read one array, not two.
  const bool dedup = limit < kClosedBit && S.queued.size() == S.stamp.size();
  uint32_t* const queued = S.queued.data();
  const uint32_t tag = static_cast<uint32_t>(st) << 16;
  const uint32_t closed_tag = tag | kClosedBit;
  auto is_closed = [&](uint32_t id) {
    return dedup ? (queued[id] & ~uint32_t{kClosedBit - 1}) == closed_tag : S.stamp[id] == st;
  };
  {
    int32_t x, y, z;
    coords(src_pos, x, y, z);
    const uint32_t si = kBoxed ? S.box_index(x, y, z) : src;
    const Scratch::Entry e{si, 0, static_cast<uint16_t>(x), static_cast<uint16_t>(y), static_cast<uint16_t>(z), gen};
    const uint32_t f = h(x, y, z, si);
    if (f <= limit) {
      lo = hi = f;
      push(f, e);
      if (dedup) queued[si] = tag;
    }
  }
  int64_t visited = 0;
  Tgt last_reached{};
  last_reached.i = kNone;
  const int64_t nb[6] = {-1, 1, -D.BX, D.BX, -D.plane, D.plane};
  static constexpr int32_t ndx[6] = {-1, 1, 0, 0, 0, 0}, ndy[6] = {0, 0, -1, 1, 0, 0}, ndz[6] = {0, 0, 0, 0, -1, 1};
  const int64_t lstep[6] = {-1, 1, -S.bw, S.bw, -S.bw * S.bh, S.bw * S.bh};  // the same steps in the box
  const DenseRanks lrank(P.layer);
  uint32_t key = lo;
  const uint32_t last = std::min(limit, std::numeric_limits<uint32_t>::max() - 8);
  while (nrem > 0 && key <= hi && key <= last) {
    if (bk[key].empty()) {
      ++key;
      continue;
    }
    Scratch::Entry e = bk[key].pop();  // last in, first out: the deepest voxel of the key first
    if (is_closed(e.id)) continue;
    uint32_t hv = key - e.g;
    if (!track_gen || e.gen != gen) {  // h grew since the voxel was queued (a target was reached): requeue by its key
      hv = h(e.x, e.y, e.z, e.id);
      e.gen = gen;
      if (e.g + hv > key) {
        if (e.g + hv <= last) push(e.g + hv, e);
        continue;
      }
    }
    if (dedup) queued[e.id] = closed_tag | e.g;
    else S.stamp[e.id] = st;
    ++visited;
    if (hv == 0) {  // a target (exact: g is final when a voxel is closed with a consistent h)
      for (size_t j = 0; j < nrem; ++j)
        if (rem[j].x == e.x && rem[j].y == e.y && rem[j].z == e.z) {
          wd[rem[j].i] = e.g;
          last_reached = rem[j];
          rem[j] = rem[--nrem];
          break;
        }
      fields_used = 0;
      for (size_t j = 0; j < nrem; ++j) fields_used |= rem[j].lmask;
      set_one();
      if (nrem == 0) break;
      ++gen;
      // Expanded now (its g is final; its neighbours are queued by the new h).
    }
    const int64_t pos = e.x + D.BX * (e.y + D.BY * static_cast<int64_t>(e.z));
    // The six neighbours, unrolled (the steps are constants of each copy).
    auto expand = [&](auto nc) __attribute__((always_inline)) {
      constexpr int n = decltype(nc)::value;
      const int64_t q = pos + nb[n];
      if (!lrank.test(q)) return;
      const uint32_t u = kBoxed ? static_cast<uint32_t>(static_cast<int64_t>(e.id) + lstep[n])
                                : lrank(q);
      if (dedup) {
        // Queued before on a path at least as short: that entry does the work. This also skips
        // closed voxels (a closed voxel was queued with its final g <= e.g + 1), without the stamp.
        // One comparison: a mark of another search leaves high bits in the difference.
        if (((queued[u] - tag) & ~kClosedBit) <= e.g + 1) return;
      } else if (S.stamp[u] == st) {
        return;
      }
      const int32_t x = e.x + ndx[n], y = e.y + ndy[n], z = e.z + ndz[n];
      const uint32_t fn = e.g + 1 + h(x, y, z, u);
      if (fn <= last) {
        push(fn, Scratch::Entry{u, e.g + 1, static_cast<uint16_t>(x), static_cast<uint16_t>(y), static_cast<uint16_t>(z), gen});
        if (dedup) queued[u] = tag | (e.g + 1);
      }
    };
    for_six_neighbours(expand);
  }
  for (uint32_t k2 = lo; k2 <= hi && k2 < bk.size(); ++k2) bk[k2].clear();
  S.last_queued = nqueued;
  // An expensive search (typically across a plate's rim): a landmark field from its far target (the
  // last one reached, or one left open), for the searches of the neighbouring bases, whose targets
  // lie near it. Not where a field already starts next to that target.
  if (S.lm_radius > 0 && visited >= S.lm_min_visited) {
    const Tgt& c = nrem > 0 ? rem[0] : last_reached;
    if (c.i != kNone) {
      const uint32_t ci = index_at(c.x, c.y, c.z, want[c.i]);
      bool covered = false;
      for (int s2 = 0; s2 < K; ++s2)
        if (S.lm[s2].on && ci != kNone && S.lm[s2].f[ci] != 0 && S.lm_value(s2, ci) <= kLandmarkReuse) covered = true;
      const int64_t R = S.lm_radius;
      // The box holds every voxel within R of the landmark (faces at the domain's need no room: L
      // never reaches the guard voxels).
      const bool inside = !kBoxed || ((c.x - S.bx0 >= R || S.bx0 == 0) && (c.y - S.by0 >= R || S.by0 == 0) &&
                                      (c.z - S.bz0 >= R || S.bz0 == 0) && (S.bx0 + S.bw - 1 - c.x >= R || S.bx0 + S.bw == D.BX) &&
                                      (S.by0 + S.bh - 1 - c.y >= R || S.by0 + S.bh == D.BY) &&
                                      (S.bz0 + S.bd - 1 - c.z >= R || S.bz0 + S.bd == D.BZ));
      if (!covered && inside && ci != kNone) visited += landmark_bfs<kBoxed>(P, S, ci, want_pos[c.i]);
    }
  }
  return visited;
}

template <bool kBoxed>
int64_t pivot_bfs_impl(const Prepared& P, Scratch& S, uint32_t src, int64_t src_pos, uint32_t limit) {
  auto run = [&](auto& pdist) {
    for (uint32_t v : S.pqueue) pdist[v] = 0;
    layered_bfs<kBoxed>(P, S, pdist.data(), S.pqueue, S.qpos, S.index_of(P.dom, src, src_pos), src_pos, limit);
  };
  if (S.pdist8.empty()) run(S.pdist16);
  else run(S.pdist8);
  S.pivot_field = S.fields;
  S.pivot_limit = limit;
  return static_cast<int64_t>(S.pqueue.size());
}

}  // namespace

int64_t own_bfs(const Prepared& P, Scratch& S, uint32_t src, int64_t src_pos, uint32_t limit,
                const std::vector<uint32_t>& want, const std::vector<int64_t>& want_pos, std::vector<uint32_t>& wd) {
  return S.boxed() ? own_bfs_impl<true>(P, S, src, src_pos, limit, want, want_pos, wd)
                   : own_bfs_impl<false>(P, S, src, src_pos, limit, want, want_pos, wd);
}

int64_t pivot_bfs(const Prepared& P, Scratch& S, uint32_t src, int64_t src_pos, uint32_t limit) {
  return S.boxed() ? pivot_bfs_impl<true>(P, S, src, src_pos, limit) : pivot_bfs_impl<false>(P, S, src, src_pos, limit);
}

SearchShared::SearchShared(const Prepared& p, const Buckets& b, const VolumeU8& m, float* out, uint32_t threshold,
                           bool full_mode)
    : P(p), B(b), mask(m), importance(out), t(threshold), full(full_mode),
      claimed(static_cast<size_t>((p.nl + 63) / 64)) {
  for (auto& c : claimed) c.store(0, std::memory_order_relaxed);
  // Pivot distances are 16-bit: no pivots where t + margin does not fit (results are the same).
  pivot_margin = full || t + std::max<uint32_t>(2, t / 4) >= 65534 ? 0 : std::max<uint32_t>(2, t / 4);
}

void BaseWork::gather(uint32_t base_id, int64_t base_pos) {
  const Prepared& P = sh_.P;
  targets.clear();
  tpos.clear();
  mpos.clear();
  for (uint32_t m = sh_.B.begin(base_id), me = m + sh_.B.members_of(base_id); m < me; ++m)
    mpos.push_back(sh_.B.member(m, base_pos));
  mtarget.clear();
  mcount.clear();
  // Targets are told apart by position (as by L-id: one L voxel per position). Their L-ids are
  // needed only with dense scratch (indexed by L-id) and L's components; a box is indexed by
  // position, so with one the rank per target is skipped (kNone: never read).
  for (int64_t pos : mpos) {
    uint8_t n = 0;
    for_each_target_pos(P, pos, [&](int64_t cpos) {
      const size_t i = static_cast<size_t>(std::find(tpos.begin(), tpos.end(), cpos) - tpos.begin());
      if (i == tpos.size()) tpos.push_back(cpos);
      mtarget.push_back(static_cast<uint32_t>(i));
      ++n;
    });
    mcount.push_back(n);
  }
  if (S_.boxed() && P.lcomp.empty()) {
    targets.assign(tpos.size(), kNone);
  } else {
    for (int64_t cpos : tpos) targets.push_back(static_cast<uint32_t>(P.layer.rank(cpos)));
  }
  tdist.assign(targets.size(), kNone);
}

void BaseWork::finish() {
  const bool full = sh_.full;
  const uint32_t t = sh_.t;
  const float inf = std::numeric_limits<float>::infinity();
  size_t k = 0;
  for (size_t m = 0; m < mpos.size(); ++m) {
    float v = 0.0f;
    for (const size_t ke = k + mcount[m]; k < ke; ++k) {
      const uint32_t d = tdist[mtarget[k]];
      float g = d == kNone ? (full ? inf : static_cast<float>(t)) : static_cast<float>(d);
      if (!full) g = std::min(g, static_cast<float>(t));
      v = std::max(v, g);
    }
    sh_.importance[sh_.mask_index(mpos[m])] = v;
  }
}

void BaseWork::mark_needed() {
  const bool full = sh_.full;
  const uint32_t t = sh_.t;
  const bool any_saturated =
      !full && std::any_of(tdist.begin(), tdist.end(), [&](uint32_t d) { return d != kNone && d >= t; });
  needed.assign(targets.size(), any_saturated ? 0 : 1);
  if (!any_saturated) return;
  size_t k = 0;
  for (size_t m = 0; m < mpos.size(); ++m) {
    const size_t k0 = k, ke = k + mcount[m];
    bool saturated = false;
    for (; k < ke; ++k)
      if (tdist[mtarget[k]] != kNone && tdist[mtarget[k]] >= t) saturated = true;
    if (!saturated)
      for (size_t j = k0; j < ke; ++j) needed[mtarget[j]] = 1;
  }
}

bool BaseWork::own_search(uint32_t base_id, int64_t base_pos) {
  constexpr int kShortcut = 4;  // targets up to this 1-norm distance may be settled without a search
  const Prepared& P = sh_.P;
  std::vector<uint32_t>& want = want_;
  std::vector<uint32_t>& wd = wd_;
  std::vector<size_t>& want_index = want_index_;
  want.clear();
  want_pos_.clear();
  want_index.clear();
  mark_needed();
  // Targets a few steps away are settled without a search where a monotone 6-path (every step
  // towards the target) lies in L: the 1-norm is a lower bound on every path, so that path's length
  // is the distance (0 and 1 always: both ends are in L). At 128³ plates this spares 58 % of the own
  // searches and 10 % of the instructions; the distances are the same.
  const Domain& D = P.dom;
  int64_t ax = 0, ay = 0, az = 0;
  D.coords(base_pos, ax, ay, az);
  for (size_t i = 0; i < targets.size(); ++i) {
    if (tdist[i] != kNone || !needed[i]) continue;
    const int64_t c = tpos[i];
    if (c == base_pos) {
      tdist[i] = 0;
      continue;
    }
    int64_t cx = 0, cy = 0, cz = 0;
    D.coords(c, cx, cy, cz);
    const int64_t dx = cx - ax, dy = cy - ay, dz = cz - az;
    const int64_t n1 = std::abs(dx) + std::abs(dy) + std::abs(dz);
    if (n1 == 1) {
      tdist[i] = 1;
    } else if (n1 <= kShortcut) {
      // A monotone path (each step towards c) with every voxel in L has the length n1.
      int64_t st[kShortcut];
      int ns = 0;
      for (int64_t k = 0; k < std::abs(dx); ++k) st[ns++] = dx > 0 ? 1 : -1;
      for (int64_t k = 0; k < std::abs(dy); ++k) st[ns++] = dy > 0 ? D.BX : -D.BX;
      for (int64_t k = 0; k < std::abs(dz); ++k) st[ns++] = dz > 0 ? D.plane : -D.plane;
      std::sort(st, st + ns);
      do {
        int64_t q = base_pos;
        bool ok = true;
        for (int j = 0; j + 1 < ns && ok; ++j) ok = P.layer.test(q += st[j]);
        if (ok) {
          tdist[i] = static_cast<uint32_t>(ns);
          break;
        }
      } while (std::next_permutation(st, st + ns));
    }
  }
  for (size_t i = 0; i < targets.size(); ++i)
    if (tdist[i] == kNone && needed[i] && (P.lcomp.empty() || P.lcomp[targets[i]] == P.lcomp[base_id])) {
      want.push_back(targets[i]);
      want_pos_.push_back(tpos[i]);
      want_index.push_back(i);
    }
  if (want.empty()) return false;
  const uint32_t limit = sh_.full ? static_cast<uint32_t>(std::min<int64_t>(P.nl, kNone / 2)) : sh_.t;
  sh_.n_visited += own_bfs(P, S_, base_id, base_pos, limit, want, want_pos_, wd);
  ++sh_.n_search;
  bool open = false;
  for (size_t j = 0; j < want.size(); ++j) {
    if (wd[j] != kNone) tdist[want_index[j]] = wd[j];
    else open = true;
  }
  return open;
}

void process_base(SearchShared& sh, Scratch& S, BaseWork& w, uint32_t a, int64_t apos) {
  const uint32_t t = sh.t, pivot_margin = sh.pivot_margin;
  std::vector<uint32_t>& targets = w.targets;
  std::vector<uint32_t>& tdist = w.tdist;
  w.gather(a, apos);
  const bool long_search = w.own_search(a, apos);
  if (long_search) ++sh.n_long;
  w.finish();
  sh.done_bases++;
  if (!long_search || sh.full || pivot_margin == 0) return;

  // Pivot: search from `a` up to t + margin, then settle the bases within `margin`.
  const uint32_t plimit = t + pivot_margin;
  sh.n_visited += pivot_bfs(sh.P, S, a, apos, plimit);
  ++sh.n_search;
  ++sh.n_pivots;
  // Bases with work within `margin` of a, with their positions (the queue is in distance order).
  std::vector<std::pair<uint32_t, int64_t>> near;
  for (size_t i = 0; i < S.pqueue.size(); ++i) {
    const uint32_t v = S.pqueue[i];
    if (S.pivot_at(v) > pivot_margin) break;
    if (i == 0) continue;  // a itself
    const uint32_t l = S.boxed() ? static_cast<uint32_t>(sh.P.layer.rank(S.qpos[i])) : v;
    if (sh.B.has_work(l)) near.emplace_back(l, S.qpos[i]);
  }
  for (const auto& [a2, a2pos] : near) {
    if (!sh.claim(a2)) continue;
    w.gather(a2, a2pos);
    const uint32_t da2 = S.pivot_at(S.index_of(sh.P.dom, a2, a2pos));
    for (size_t i = 0; i < targets.size(); ++i) {
      const uint32_t c = S.index_of(sh.P.dom, targets[i], w.tpos[i]);
      // g(a, c) > t + margin (unreached) or >= t + g(a, a2): then g(a2, c) >= t.
      if (!S.pivot_visited(c) || S.pivot_at(c) >= t + da2) {
        tdist[i] = t;
        ++sh.n_saturated;
      }
    }
    if (w.own_search(a2, a2pos)) ++sh.n_long;
    w.finish();
    sh.done_bases++;
  }
}

SearchLayout search_layout(const SearchShared& sh) {
  const Prepared& P = sh.P;
  const Domain& D = P.dom;
  const int64_t t = sh.t, pivot_margin = sh.pivot_margin;
  SearchLayout L;
  const int64_t extent = std::max<int64_t>(2 * pivot_margin + 2, 8);
  const int64_t rw = D.row_words();
  L.nbx = std::max<int64_t>(1, rw / ((extent + 63) / 64));
  L.nby = std::max<int64_t>(1, D.BY / extent);
  L.nbz = std::max<int64_t>(1, D.BZ / extent);
  // Scratch box: the largest block plus everything its searches reach (own searches to t from bases
  // within `margin` of the block, pivots to t + margin from the block's bases, and one neighbour
  // more), clipped to the domain; dense (one entry per L voxel) where that is smaller, in full mode
  // (unbounded searches) and where the box index would not fit in 32 bits.
  L.halo = t + pivot_margin + 1;
  L.bw = std::min(D.BX, 64 * ((rw + L.nbx - 1) / L.nbx) + 2 * L.halo);
  L.bh = std::min(D.BY, (D.BY + L.nby - 1) / L.nby + 2 * L.halo);
  L.bd = std::min(D.BZ, (D.BZ + L.nbz - 1) / L.nbz + 2 * L.halo);
  const int64_t box = L.bw * L.bh * L.bd;
  L.boxed = !sh.full && (sh.force_box || box < P.nl) && box < static_cast<int64_t>(std::numeric_limits<uint32_t>::max());
  return L;
}

uint64_t search_bases(SearchShared& sh, int threads, const Interrupter& search_progress) {
  const Prepared& P = sh.P;
  const Domain& D = P.dom;
  const int nthreads = effective_threads(threads);
  const uint32_t t = sh.t, pivot_margin = sh.pivot_margin;

  // Work: bases with a non-empty bucket, found by walking the words of L (which gives their
  // positions too). Each base is claimed exactly once, and every value is exact (searches) or a
  // proven saturation, so the importance never depends on who claimed a base. The diagnostic counts
  // (searches, pivots, saturated, visited) do depend on it, so claims are made deterministic: the
  // padded domain is cut into blocks (x: whole words; y, z: rows and slabs), each at least
  // 2*margin + 2 voxels thick on every axis, coloured by the parity of (x, y, z) block index, and the
  // eight colours run one after the other. A block is processed by one worker in L order; a pivot
  // claims only bases within `margin` 6-steps (so within `margin` on every axis): never in another
  // block of the same colour, and no base is within reach of two blocks of one colour. So the
  // claims, and with them every count, are those of a fixed sequential order, whatever the thread
  // count (the blocks do not depend on it).
  {
    int64_t nb = 0;
    for (int64_t l = 0; l < P.nl; ++l) nb += sh.B.has_work(static_cast<uint32_t>(l));
    sh.n_bases = nb;
  }
  const SearchLayout lay = search_layout(sh);
  const int64_t rw = D.row_words(), nbx = lay.nbx, nby = lay.nby, nbz = lay.nbz, halo = lay.halo;
  const int64_t bw = lay.bw, bh = lay.bh, bd = lay.bd;
  const bool boxed = lay.boxed;

  std::mutex scratch_mutex;
  std::vector<std::unique_ptr<Scratch>> pool;
  auto acquire = [&]() {
    std::lock_guard lock(scratch_mutex);
    if (!pool.empty()) {
      auto s = std::move(pool.back());
      pool.pop_back();
      return s;
    }
    const uint32_t plimit = pivot_margin ? t + pivot_margin : 0;
    auto s = boxed ? std::make_unique<Scratch>(bw, bh, bd, plimit)
                   : std::make_unique<Scratch>(static_cast<size_t>(P.nl), plimit);
    // Landmark fields to the radius t (one byte per entry): a box holds them around targets up to
    // margin + 1 voxels beyond the block.
    s->fields = sh.landmarks && !sh.full;
    s->lm_radius = s->fields && t <= 253 ? t : 0;
    s->lm_min_visited = sh.landmark_min_visited >= 0 ? sh.landmark_min_visited : 8 * static_cast<int64_t>(t);
    if (s->lm_radius > 0)  // allocated up front, so the bytes do not depend on which worker built fields
      for (Scratch::Landmark& L : s->lm) L.f.assign(s->stamp.size(), 0);
    return s;
  };
  auto release = [&](std::unique_ptr<Scratch> s) {
    std::lock_guard lock(scratch_mutex);
    pool.push_back(std::move(s));
  };
  for (int colour = 0; colour < 8; ++colour) {
    struct Block {
      int64_t ix, iy, iz;
    };
    std::vector<Block> blocks;
    for (int64_t iz = (colour >> 2) & 1; iz < nbz; iz += 2)
      for (int64_t iy = (colour >> 1) & 1; iy < nby; iy += 2)
        for (int64_t ix = colour & 1; ix < nbx; ix += 2) blocks.push_back(Block{ix, iy, iz});
    parallel_for(0, static_cast<int64_t>(blocks.size()), nthreads, [&](int64_t b0, int64_t b1) {
      auto S = acquire();
      BaseWork work(sh, *S);  // its vectors are reused from base to base
      for (int64_t bi = b0; bi < b1; ++bi) {
        const Block& bl = blocks[static_cast<size_t>(bi)];
        const int64_t z0 = D.BZ * bl.iz / nbz, z1 = D.BZ * (bl.iz + 1) / nbz;
        const int64_t y0 = D.BY * bl.iy / nby, y1 = D.BY * (bl.iy + 1) / nby;
        const int64_t w0 = rw * bl.ix / nbx, w1 = rw * (bl.ix + 1) / nbx;
        S->begin_block();
        if (S->boxed())
          S->move_box(std::clamp<int64_t>(w0 * 64 - halo, 0, D.BX - bw), std::clamp<int64_t>(y0 - halo, 0, D.BY - bh),
                      std::clamp<int64_t>(z0 - halo, 0, D.BZ - bd));
        for (int64_t z = z0; z < z1; ++z) {
          for (int64_t y = y0; y < y1; ++y) {
            const int64_t row = (z * D.BY + y) * rw;
            uint32_t a = static_cast<uint32_t>(P.layer.prefix(static_cast<size_t>(row + w0)));  // counted along
            for (int64_t w = row + w0; w < row + w1; ++w) {
              uint64_t bits = P.layer.word(static_cast<size_t>(w));
              for (; bits; bits &= bits - 1, ++a) {
                if (!sh.B.has_work(a) || !sh.claim(a)) continue;
                process_base(sh, *S, work, a, w * 64 + std::countr_zero(bits));
              }
            }
          }
          search_progress.check(static_cast<double>(sh.done_bases.load()) /
                                static_cast<double>(std::max<int64_t>(1, sh.n_bases.load())));
        }
      }
      release(std::move(S));
    });
  }
  uint64_t bytes = 0;
  for (const auto& sc : pool) {
    bytes += sc->bytes();
    sh.n_landmarks += sc->lm_built;
  }
  return bytes;
}

void threshold_surface(const VolumeF32& importance, VolumeU8& skeleton, uint32_t t, int threads) {
  // Background is 0 < t.
  const float tf = static_cast<float>(t);
  parallel_for(0, static_cast<int64_t>(importance.size()), threads, [&](int64_t i0, int64_t i1) {
    for (int64_t i = i0; i < i1; ++i) skeleton[i] = importance[i] >= tf ? 1 : 0;
  }, 1 << 16);
}

}  // namespace detail

namespace {

using namespace detail;

Result empty_result(const VolumeU8& mask) {
  Result res;
  res.importance = VolumeF32(mask.grid(), 0.0f);
  res.surface_skeleton = VolumeU8(mask.grid(), 0);
  return res;
}

}  // namespace

Result boundary_distance(const VolumeU8& mask, const Options& opt) {
  mask.grid().validate();
  if (opt.threshold < 1) throw InputError("geodesic: threshold must be >= 1");
  if (opt.threshold > 1000000) throw InputError("geodesic: threshold must be <= 10^6");
  const bool full = opt.mode == Mode::Full;
  const uint32_t t = static_cast<uint32_t>(opt.threshold);
  if (mask.size() == 0) return empty_result(mask);

  // The outputs: the importance is 0 off the object (zeroed here by all threads: 4 bytes per voxel,
  // 8 GiB at 1280³, first touched here); the surface is written whole by threshold_surface, so it is
  // not filled first.
  Result res;
  res.importance = VolumeF32::uninitialized(mask.grid());
  res.surface_skeleton = VolumeU8::uninitialized(mask.grid());
  parallel_for(0, static_cast<int64_t>(res.importance.size()), opt.threads, [&](int64_t i0, int64_t i1) {
    std::fill(res.importance.data() + i0, res.importance.data() + i1, 0.0f);
  }, 1 << 20);
  using clock = std::chrono::steady_clock;
  const auto t0 = clock::now();
  Prepared P(mask.dims());
  // L's components only in full mode: they spare searches that would run through a whole component
  // to prove "no path"; in threshold mode the bounded search stops at t anyway (4 bytes per L voxel).
  prepare(mask, P, opt.threads, opt.interrupter.sub(0.0, 1.0), false, full);
  res.stats.object_voxels = P.k;
  res.stats.layer_voxels = P.nl;
  if (P.k == 0) {
    std::fill(res.surface_skeleton.data(), res.surface_skeleton.data() + res.surface_skeleton.size(), uint8_t{0});
    return res;
  }

  const Buckets B = bucket_by_base(P, opt.threads);
  opt.interrupter.check(0.25);
  const auto t1 = clock::now();

  // Importance goes straight into the output (written once per voxel: each voxel is in exactly one
  // bucket, so threads never write the same element).
  SearchShared sh(P, B, mask, res.importance.data(), t, full);
  sh.landmarks = opt.landmarks;
  // Dense scratch (full mode, and volumes so small that a box would hold more voxels than L): the
  // searches rank every neighbour they visit, so the bitmaps get a prefix per word as well (+0.5
  // bits per voxel each, counted in the bytes).
  if (!search_layout(sh).boxed) {
    P.layer.build_word_prefixes();
    P.obj.build_word_prefixes();
  }
  const uint64_t scratch_bytes = search_bases(sh, opt.threads, opt.interrupter.sub(0.25, 0.97));
  threshold_surface(res.importance, res.surface_skeleton, t, opt.threads);
  res.stats.seconds_prepare = std::chrono::duration<double>(t1 - t0).count();
  res.stats.seconds_search = std::chrono::duration<double>(clock::now() - t1).count();
  res.stats.base_points = sh.n_bases.load();
  res.stats.searches = sh.n_search.load();
  res.stats.pivots = sh.n_pivots.load();
  res.stats.long_searches = sh.n_long.load();
  res.stats.saturated_by_pivot = sh.n_saturated.load();
  res.stats.visited = sh.n_visited.load();
  res.stats.landmarks = sh.n_landmarks.load();
  // Peak of the two phases: the nearest-point transform (with L coordinates and the ring marks) and
  // the searches (with components, buckets, claims and the workers' scratch).
  const uint64_t search_bytes = P.obj.bytes() + P.layer.bytes() + P.base_bytes() + P.lcomp.size() * 4 +
                                B.bytes() + sh.claimed.size() * 8 + scratch_bytes;
  res.stats.bytes = std::max(P.prepare_bytes, search_bytes);
  res.stats.bytes_prepare = P.prepare_bytes;
  res.stats.bytes_search = search_bytes;
  opt.interrupter.check(1.0);
  return res;
}

Result boundary_distance_reference(const VolumeU8& mask, const Options& opt) {
  const bool full = opt.mode == Mode::Full;
  const uint32_t t = static_cast<uint32_t>(opt.threshold);
  Result res = empty_result(mask);
  if (mask.size() == 0) return res;
  Prepared P(mask.dims());
  prepare(mask, P, 1, {}, true);
  const Domain& D = P.dom;
  std::vector<int64_t> dist(static_cast<size_t>(P.nl));
  for (int64_t z = 0; z < D.nz; ++z)
    for (int64_t y = 0; y < D.ny; ++y)
      for (int64_t x = 0; x < D.nx; ++x) {
        const int64_t pos = D.pos(x + 2, y + 2, z + 2);
        if (!P.obj.test(pos)) continue;
        const uint32_t a = P.b[P.obj.rank(pos)];
        // Plain BFS over all of L from a.
        std::fill(dist.begin(), dist.end(), -1);
        std::vector<uint32_t> q{a};
        dist[a] = 0;
        for (size_t h = 0; h < q.size(); ++h) {
          const int64_t p = P.lpos(q[h]);
          for (int64_t n : {p - 1, p + 1, p - D.BX, p + D.BX, p - D.plane, p + D.plane}) {
            if (!P.layer.test(n)) continue;
            const uint32_t u = static_cast<uint32_t>(P.layer.rank(n));
            if (dist[u] >= 0) continue;
            dist[u] = dist[q[h]] + 1;
            q.push_back(u);
          }
        }
        float v = 0;
        for_each_target(P, pos, [&](uint32_t c) {
          float g = dist[c] < 0 ? std::numeric_limits<float>::infinity() : static_cast<float>(dist[c]);
          if (!full) g = std::min(g, static_cast<float>(t));
          v = std::max(v, g);
        });
        res.importance(x, y, z) = v;
        res.surface_skeleton(x, y, z) = v >= static_cast<float>(t) ? 1 : 0;
      }
  return res;
}

}  // namespace skel::geodesic
