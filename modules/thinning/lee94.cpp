// Lee94 thinning, voxel-for-voxel compatible with scikit-image skeletonize_3d / Fiji Skeletonize3D
// (see lee94.hpp for the algorithm and the implementation notes).
#include "thinning/lee94.hpp"
#include "thinning/cube_word.hpp"

#include <algorithm>
#include <array>
#include <cstring>
#include <memory>
#include <vector>

#include "skel/parallel.hpp"

namespace skel::thinning {
namespace {

// ---------------------------------------------------------------- the 27-bit cube word
using cube::dilate26;
using cube::kCentre;
using cube::kCube;

// skimage's is_simple_point: the object voxels of the 26-neighbourhood (centre excluded) form at
// most one 26-component (its octree labelling is a flood fill: two neighbours of the centre are
// 26-adjacent exactly when one octant holds both).
inline bool one_component_or_none(uint32_t cube) {
  const uint32_t obj = cube & kCube & ~kCentre;
  if (obj == 0) return true;
  uint32_t c = obj & (~obj + 1);
  while (true) {
    const uint32_t g = dilate26(c) & obj;
    if (g == c) return c == obj;
    c = g;
  }
}

// ---------------------------------------------------------------- Euler invariance (Lee's table 2)
// skimage's LUT (column delta G_26 of Lee et al.'s table 2) at its odd indices n = 2i + 1, i.e. with
// the centre bit set: kEulerOdd[i] = LUT[2i + 1], i = the octant's seven neighbours as bits 6..0.
constexpr std::array<int8_t, 128> kEulerOdd = {
    1,  -1, -1, 1,  -3, -1, -1, 1,  -1, 1,  1,  -1, 3,  1,  1,  -1, -3, -1, 3,  1,  1,  -1, 3,  1,  -1, 1,
    1,  -1, 3,  1,  1,  -1, -3, 3,  -1, 1,  1,  3,  -1, 1,  -1, 1,  1,  -1, 3,  1,  1,  -1, 1,  3,  3,  1,
    5,  3,  3,  1,  -1, 1,  1,  -1, 3,  1,  1,  -1, -7, -1, -1, 1,  -3, -1, -1, 1,  -1, 1,  1,  -1, 3,  1,
    1,  -1, -3, -1, 3,  1,  1,  -1, 3,  1,  -1, 1,  1,  -1, 3,  1,  1,  -1, -3, 3,  -1, 1,  1,  3,  -1, 1,
    -1, 1,  1,  -1, 3,  1,  1,  -1, 1,  3,  3,  1,  5,  3,  3,  1,  -1, 1,  1,  -1, 3,  1,  1,  -1};

// skimage numbers the 27 voxels k = 9 (dp+1) + 3 (dc+1) + (dr+1) for an array [p][r][c]; with
// p = z, r = y, c = x that is the cube bit (dc+1) + 3 (dr+1) + 9 (dp+1).
constexpr int skimage_to_cube(int k) { return (k / 3) % 3 + 3 * (k % 3) + 9 * (k / 9); }

// The eight octants of is_Euler_invariant: the neighbour (skimage numbering) for the index bits
// 128, 64, 32, 16, 8, 4, 2 (in that order). Octants 0-3 lie in the planes dz = -1, 0; 4-7 in dz = 0, 1.
constexpr int kOctants[8][7] = {{2, 1, 11, 10, 5, 4, 14},    {0, 9, 3, 12, 1, 10, 4},
                                {8, 7, 17, 16, 5, 4, 14},    {6, 15, 7, 16, 3, 12, 4},
                                {20, 23, 19, 22, 11, 14, 10}, {18, 21, 9, 12, 19, 22, 10},
                                {26, 23, 17, 14, 25, 22, 16}, {24, 25, 15, 16, 21, 22, 12}};

// The LUT index of an octant (without the centre bit) from the cube word.
int octant_index(int octant, uint32_t cube) {
  int n = 0;
  for (int j = 0; j < 7; ++j)
    if (cube >> skimage_to_cube(kOctants[octant][j]) & 1u) n |= 64 >> j;
  return n;
}

// The sum over octants 0-3 depends on cube bits 0..17 only, over octants 4-7 on bits 9..26 only:
// two tables of 2^17 entries (the centre bit removed from the index).
inline uint32_t low_index(uint32_t cube) { return (cube & 0x1FFFu) | (((cube >> 14) & 0xFu) << 13); }
inline uint32_t high_index(uint32_t cube) {
  const uint32_t h = cube >> 9;
  return (h & 0xFu) | ((h >> 5) << 4);
}
constexpr uint32_t low_cube(uint32_t i) { return (i & 0x1FFFu) | ((i >> 13) << 14); }
constexpr uint32_t high_cube(uint32_t i) { return ((i & 0xFu) | ((i >> 4) << 5)) << 9; }

struct EulerTables {
  std::vector<int8_t> low, high;
  EulerTables() : low(size_t{1} << 17), high(size_t{1} << 17) {
    // An octant's index is the OR of the indices of the low 9 and the high 8 bits of the table index.
    for (int half = 0; half < 2; ++half) {
      std::array<std::array<uint8_t, 512>, 4> a{};
      std::array<std::array<uint8_t, 256>, 4> b{};
      auto cube_of = [half](uint32_t i) { return half == 0 ? low_cube(i) : high_cube(i); };
      for (int o = 0; o < 4; ++o) {
        for (uint32_t i = 0; i < 512; ++i)
          a[static_cast<size_t>(o)][i] = static_cast<uint8_t>(octant_index(4 * half + o, cube_of(i)));
        for (uint32_t i = 0; i < 256; ++i)
          b[static_cast<size_t>(o)][i] = static_cast<uint8_t>(octant_index(4 * half + o, cube_of(i << 9)));
      }
      std::vector<int8_t>& t = half == 0 ? low : high;
      for (uint32_t i = 0; i < (1u << 17); ++i) {
        int sum = 0;
        for (size_t o = 0; o < 4; ++o) sum += kEulerOdd[a[o][i & 511u] | b[o][i >> 9]];
        t[i] = static_cast<int8_t>(sum);
      }
    }
  }
};

const EulerTables& euler_tables() {
  static const EulerTables t;
  return t;
}

inline bool euler_invariant_fast(const EulerTables& t, uint32_t cube) {
  return t.low[low_index(cube)] + t.high[high_index(cube)] == 0;
}

// ---------------------------------------------------------------- the padded working image
// The object as bits: row r = z (ny+2) + y of the padded grid holds bit x (0..nx+1) of its W words;
// the last word of a row is always zero (room for unaligned reads). 1/8 byte per voxel, so the
// image stays in cache where a byte image would not.
struct Work {
  int64_t nx = 0, ny = 0, nz = 0;  // mask dims
  int64_t px = 0, py = 0, pz = 0;  // padded dims
  int64_t words = 0;               // W: 64-bit words per row
  std::unique_ptr<uint64_t[]> bits;
  // Byte per group of eight voxels (bits 8j..8j+7 of a row; byte r 8W + j): bit d = "dirty for
  // direction d": a voxel of the 3x3x3 neighbourhood of a voxel of the group was deleted since
  // direction d last scanned the row, or the row was never scanned. Only border voxels of dirty
  // groups are examined. Collecting threads write the bytes of their own rows only.
  std::unique_ptr<uint8_t[]> dirty;
  std::unique_ptr<uint8_t[]> rows;  // per row r: bit d = row must be scanned for direction d

  [[nodiscard]] const uint64_t* row(int64_t r) const { return bits.get() + r * words; }
  // Bits x-1, x, x+1 of row r -> bits 0, 1, 2.
  [[nodiscard]] uint32_t three(int64_t r, int64_t x) const {
    const auto* bytes = reinterpret_cast<const unsigned char*>(row(r));
    uint64_t v;
    std::memcpy(&v, bytes + ((x - 1) >> 3), 8);
    return static_cast<uint32_t>(v >> ((x - 1) & 7)) & 7u;
  }
  [[nodiscard]] uint32_t cube(int64_t r, int64_t x) const {
    uint32_t c = 0;
    int shift = 0;
    for (int64_t dz = -1; dz <= 1; ++dz)
      for (int64_t dy = -1; dy <= 1; ++dy, shift += 3) c |= three(r + dy + dz * py, x) << shift;
    return c;
  }
};

constexpr uint64_t kOnes = 0x0101010101010101ull;
constexpr uint8_t kDirty = 0x3F;  // dirty for the six directions

// Byte i of kBitsToBytes[b] = bit i of b.
constexpr std::array<uint64_t, 256> kBitsToBytes = [] {
  std::array<uint64_t, 256> t{};
  for (uint64_t b = 0; b < 256; ++b)
    for (int i = 0; i < 8; ++i) t[b] |= ((b >> i) & 1u) << (8 * i);
  return t;
}();

struct Candidate {
  int64_t r, x;   // padded row and x
  uint32_t cube;  // its neighbourhood word when collected
};
constexpr int64_t kSlack = 16;

}  // namespace

namespace lee94_detail {
bool euler_invariant(uint32_t cube) { return euler_invariant_fast(euler_tables(), cube | kCentre); }
bool at_most_one_component(uint32_t cube) { return one_component_or_none(cube); }
}  // namespace lee94_detail

Lee94Result thin_lee94(const VolumeU8& mask, const Lee94Options& options) {
  Lee94Result result;
  Lee94Statistics& st = result.stats;
  const int threads = effective_threads(options.threads);
  if (mask.size() == 0) {
    result.skeleton = VolumeU8(mask.grid(), 0);
    return result;
  }
  Work w;
  w.nx = mask.nx();
  w.ny = mask.ny();
  w.nz = mask.nz();
  w.px = w.nx + 2;
  w.py = w.ny + 2;
  w.pz = w.nz + 2;
  w.words = (w.px + 63) / 64 + 1;
  const int64_t nrows = w.py * w.pz;
  w.bits.reset(new uint64_t[static_cast<size_t>(nrows * w.words)]());
  const int64_t group_bytes = nrows * w.words * 8;
  w.dirty.reset(new uint8_t[static_cast<size_t>(group_bytes)]);
  w.rows.reset(new uint8_t[static_cast<size_t>(nrows)]);
  std::fill_n(w.rows.get(), nrows, uint8_t{0x3F});
  const EulerTables& euler = euler_tables();
  st.bytes = static_cast<uint64_t>(2 * group_bytes + nrows);
  const int64_t py = w.py;

  // Bits of the mask (non-zero -> 1), every voxel dirty for every direction; object voxel count per
  // plane, summed in plane order.
  parallel_for(0, w.pz, threads, [&](int64_t z0, int64_t z1) {
    std::memset(w.dirty.get() + z0 * py * w.words * 8, kDirty, static_cast<size_t>((z1 - z0) * py * w.words * 8));
  });
  std::vector<int64_t> plane_count(static_cast<size_t>(w.nz), 0);
  parallel_for(0, w.nz, threads, [&](int64_t z0, int64_t z1) {
    for (int64_t z = z0; z < z1; ++z) {
      int64_t count = 0;
      for (int64_t y = 0; y < w.ny; ++y) {
        const uint8_t* s = mask.data() + mask.index(0, y, z);
        uint64_t* row = w.bits.get() + ((z + 1) * py + y + 1) * w.words;
        for (int64_t x = 0; x < w.nx;) {  // voxel x -> padded bit x + 1
          if (x + 8 <= w.nx) {  // eight bytes at a time: non-zero -> 1, packed to 8 bits
            uint64_t v;
            std::memcpy(&v, s + x, 8);
            v = ((((v & (kOnes * 0x7F)) + kOnes * 0x7F) | v) >> 7) & kOnes;
            const uint64_t b8 = (v * 0x0102040810204080ull) >> 56;
            const int64_t bit = x + 1;
            row[bit >> 6] |= b8 << (bit & 63);
            if ((bit & 63) > 56) row[(bit >> 6) + 1] |= b8 >> (64 - (bit & 63));
            x += 8;
          } else {
            if (s[x] != 0) row[(x + 1) >> 6] |= uint64_t{1} << ((x + 1) & 63);
            ++x;
          }
        }
        for (int64_t k = 0; k < w.words; ++k) count += __builtin_popcountll(row[k]);
      }
      plane_count[static_cast<size_t>(z)] = count;
    }
  });
  for (int64_t c : plane_count) st.object_voxels += c;

  // skimage/Fiji border order 4, 3, 2, 1, 5, 6 = W (y-1), E (y+1), S (x+1), N (x-1), U (z+1), B (z-1).
  const int directions = w.nz == 1 ? 4 : 6;  // skimage: padded shape[0] == 3 -> four borders

  const int64_t rows = w.ny * w.nz;
  const int64_t chunks = std::min<int64_t>(rows, threads == 1 ? 1 : 8 * static_cast<int64_t>(threads));
  std::vector<int64_t> st_rows(static_cast<size_t>(chunks), 0);
  std::vector<std::vector<Candidate>> cand(static_cast<size_t>(chunks));

  auto collect = [&](int dir) {
    const uint8_t bit = static_cast<uint8_t>(1u << dir);
    const int64_t row_off = dir == 0 ? -1 : dir == 1 ? 1 : dir == 4 ? py : dir == 5 ? -py : 0;
    // Border voxels of flagged rows, 64 at a time, in raster order; the dirty ones are examined. A
    // thread reads the image anywhere (unchanged during collection) and writes the row flags and dirty
    // bytes of its own rows only.
    parallel_chunks(0, rows, chunks, threads, [&](int64_t c, int64_t r0, int64_t r1) {
      std::vector<Candidate>& out = cand[static_cast<size_t>(c)];
      out.clear();
      int64_t scanned = 0;
      for (int64_t rr = r0; rr < r1; ++rr) {
        const int64_t r = (rr / w.ny + 1) * py + rr % w.ny + 1;
        uint8_t& flag = w.rows[static_cast<size_t>(r)];
        if (!(flag & bit)) continue;
        flag = static_cast<uint8_t>(flag & ~bit);
        ++scanned;
        const uint64_t* a_row = w.row(r);
        const uint64_t* b_row = w.row(r + row_off);
        uint8_t* drow = w.dirty.get() + r * w.words * 8;
        for (int64_t k = 0; k + 1 < w.words; ++k) {
          uint64_t g;  // the eight groups of this word
          std::memcpy(&g, drow + 8 * k, 8);
          const uint64_t gd = (g >> dir) & kOnes;
          if (gd == 0) continue;
          g &= ~(kOnes << dir);
          std::memcpy(drow + 8 * k, &g, 8);
          const uint64_t a = a_row[k];
          if (a == 0) continue;
          uint64_t b;
          if (dir == 2) b = (a >> 1) | (a_row[k + 1] << 63);
          else if (dir == 3) b = (a << 1) | (k > 0 ? a_row[k - 1] >> 63 : 0);
          else b = b_row[k];
          uint64_t m = a & ~b & (gd * 0xFF);
          while (m != 0) {
            const int64_t x = 64 * k + __builtin_ctzll(m);
            m &= m - 1;
            const uint32_t cube = w.cube(r, x);
            if (__builtin_popcount(cube) == 2) continue;  // end point (the centre is counted)
            if (!euler_invariant_fast(euler, cube)) continue;
            if (!one_component_or_none(cube)) continue;
            out.push_back({r, x, cube});
          }
        }
      }
      st_rows[static_cast<size_t>(c)] += scanned;
    });
  };

  // After a deletion: the groups of the 3x3x3 block around it are dirty for every direction, and so
  // are its rows.
  auto mark = [&](const Candidate& k) {
    for (int64_t dz = -1; dz <= 1; ++dz) {
      uint8_t* f = w.rows.get() + k.r + dz * py;
      f[-1] = f[0] = f[1] = 0x3F;
      for (int64_t dy = -1; dy <= 1; ++dy) {
        uint8_t* g = w.dirty.get() + (k.r + dy + dz * py) * w.words * 8;
        g[(k.x - 1) >> 3] = kDirty;  // the groups of x-1 and x+1 (the same one or neighbours)
        g[(k.x + 1) >> 3] = kDirty;
      }
    }
  };

  int unchanged = 0;
  while (unchanged < directions) {
    unchanged = 0;
    ++st.passes;
    for (int dir = 0; dir < directions; ++dir) {
      collect(dir);
      bool changed = false;
      for (const auto& list : cand) {
        st.candidates += static_cast<int64_t>(list.size());
        for (const Candidate& k : list) {
          // Only deletions happen here: an unchanged neighbourhood word is still one component.
          const uint32_t cube = w.cube(k.r, k.x);
          if (cube != k.cube && !one_component_or_none(cube)) {
            ++st.rejected;
            continue;
          }
          w.bits[static_cast<size_t>(k.r * w.words + (k.x >> 6))] &= ~(uint64_t{1} << (k.x & 63));
          ++st.removed;
          if ((cube & ~kCentre) == 0) ++st.vanished_components;
          mark(k);
          changed = true;
        }
      }
      if (!changed) ++unchanged;
      options.interrupter.check(
          st.object_voxels > 0 ? std::min(0.99, static_cast<double>(st.removed) / static_cast<double>(st.object_voxels))
                               : 0.99);
    }
  }
  for (int64_t c : st_rows) st.scanned_rows += c;
  size_t cand_bytes = 0;
  for (const auto& list : cand) cand_bytes += list.capacity() * sizeof(Candidate);
  st.bytes += cand_bytes;

  result.skeleton = VolumeU8::uninitialized(mask.grid());
  std::vector<int64_t> plane_left(static_cast<size_t>(w.nz), 0);
  parallel_for(0, w.nz, threads, [&](int64_t z0, int64_t z1) {
    for (int64_t z = z0; z < z1; ++z) {
      int64_t count = 0;
      for (int64_t y = 0; y < w.ny; ++y) {
        uint8_t* d = result.skeleton.data() + result.skeleton.index(0, y, z);
        const uint64_t* row = w.row((z + 1) * py + y + 1);
        const auto* bytes = reinterpret_cast<const unsigned char*>(row);
        int64_t x = 0;
        for (; x + 8 <= w.nx; x += 8) {  // padded bits x+1..x+8 -> eight bytes
          uint64_t v;
          std::memcpy(&v, bytes + ((x + 1) >> 3), 8);
          const uint64_t e = kBitsToBytes[(v >> ((x + 1) & 7)) & 0xFFu];
          std::memcpy(d + x, &e, 8);
        }
        for (; x < w.nx; ++x) d[x] = static_cast<uint8_t>((row[(x + 1) >> 6] >> ((x + 1) & 63)) & 1u);
        for (int64_t k = 0; k < w.words; ++k) count += __builtin_popcountll(row[k]);
      }
      plane_left[static_cast<size_t>(z)] = count;
    }
  });
  for (int64_t c : plane_left) st.skeleton_voxels += c;
  options.interrupter.check(1.0);
  return result;
}

}  // namespace skel::thinning
