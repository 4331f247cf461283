// Lee94 thinning, voxel-for-voxel compatible with scikit-image skeletonize_3d / Fiji Skeletonize3D
// (see lee94.hpp for the algorithm and the implementation notes).
#include "thinning/lee94.hpp"

#include <algorithm>
#include <array>
#include <cstring>
#include <memory>
#include <vector>

#include "skel/parallel.hpp"

namespace skel::thinning {
namespace {

// ---------------------------------------------------------------- the 27-bit cube word
// Bit (dx+1) + 3 (dy+1) + 9 (dz+1) is the voxel at offset (dx, dy, dz); centre = bit 13.
constexpr uint32_t kCube = (1u << 27) - 1;
constexpr uint32_t kCentre = 1u << 13;

constexpr uint32_t cube_plane_mask(int axis, int value) {
  uint32_t m = 0;
  for (int c = 0; c < 27; ++c) {
    const int v = axis == 0 ? c % 3 : axis == 1 ? (c / 3) % 3 : c / 9;
    if (v == value) m |= 1u << c;
  }
  return m;
}
constexpr uint32_t kNotX0 = kCube & ~cube_plane_mask(0, 0), kNotX2 = kCube & ~cube_plane_mask(0, 2);
constexpr uint32_t kNotY0 = kCube & ~cube_plane_mask(1, 0), kNotY2 = kCube & ~cube_plane_mask(1, 2);

// 26-dilation of a set of cube bits (masked shifts; a shift must not wrap into the next row/plane).
inline uint32_t dilate26(uint32_t s) {
  s |= ((s << 1) & kNotX0) | ((s >> 1) & kNotX2);
  s |= ((s << 3) & kNotY0) | ((s >> 3) & kNotY2);
  return (s | (s << 9) | (s >> 9)) & kCube;
}

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
// skimage's LUT: column delta G_26 of Lee et al.'s table 2, indexed by an octant's eight voxels
// (bit 0 = the centre, always set).
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
        for (uint32_t i = 0; i < 512; ++i) a[static_cast<size_t>(o)][i] = static_cast<uint8_t>(octant_index(4 * half + o, cube_of(i)));
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
// Three bytes (0/1) at p-1, p, p+1 -> bits 0, 1, 2.
inline uint32_t row3(const uint8_t* p) {
  uint32_t v;
  std::memcpy(&v, p - 1, 4);
  return (((v & 0x010101u) * 0x10204u) >> 16) & 7u;
}

struct Work {
  int64_t nx = 0, ny = 0, nz = 0;  // mask dims
  int64_t sy = 0, sz = 0;          // padded strides
  std::unique_ptr<uint8_t[]> img;  // (nx+2)(ny+2)(nz+2) + slack, 0/1
  // Same layout: bit d = "dirty for direction d": a voxel of the 3x3x3 neighbourhood was deleted
  // since direction d last collected candidates. A separate array, so that collecting threads write
  // only the bytes of their own rows while they read the image around them.
  std::unique_ptr<uint8_t[]> dirty;
  std::unique_ptr<uint8_t[]> rows; // (ny+2)(nz+2): bit d = row must be scanned for direction d

  [[nodiscard]] uint32_t cube(int64_t i) const {
    const uint8_t* p = img.get() + i;
    uint32_t c = 0;
    int shift = 0;
    for (int64_t dz = -1; dz <= 1; ++dz)
      for (int64_t dy = -1; dy <= 1; ++dy, shift += 3) c |= row3(p + dy * sy + dz * sz) << shift;
    return c;
  }
};

constexpr uint64_t kOnes = 0x0101010101010101ull;
constexpr uint8_t kDirty = 0x3F;  // dirty for the six directions

struct Candidate {
  int64_t index;  // padded index
  int64_t row;    // its row in Work::rows: z (ny+2) + y
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
  Work w;
  w.nx = mask.nx();
  w.ny = mask.ny();
  w.nz = mask.nz();
  const int64_t px = w.nx + 2, py = w.ny + 2, pz = w.nz + 2;
  w.sy = px;
  w.sz = px * py;
  if (mask.size() == 0) {
    result.skeleton = VolumeU8(mask.grid(), 0);
    return result;
  }
  const int64_t padded = px * py * pz;
  w.img.reset(new uint8_t[static_cast<size_t>(padded + kSlack)]());
  w.dirty.reset(new uint8_t[static_cast<size_t>(padded + kSlack)]);
  w.rows.reset(new uint8_t[static_cast<size_t>(py * pz)]);
  std::fill_n(w.rows.get(), py * pz, uint8_t{0x3F});
  const EulerTables& euler = euler_tables();
  st.bytes = static_cast<uint64_t>(2 * (padded + kSlack) + py * pz);

  // Padded 0/1 copy, every voxel dirty for every direction; object voxel count per plane, summed in
  // plane order.
  std::vector<int64_t> plane_count(static_cast<size_t>(w.nz), 0);
  parallel_for(0, pz, threads, [&](int64_t z0, int64_t z1) {
    std::memset(w.dirty.get() + z0 * w.sz, kDirty, static_cast<size_t>((z1 - z0) * w.sz));
  });
  parallel_for(0, w.nz, threads, [&](int64_t z0, int64_t z1) {
    for (int64_t z = z0; z < z1; ++z) {
      int64_t count = 0;
      for (int64_t y = 0; y < w.ny; ++y) {
        const uint8_t* s = mask.data() + mask.index(0, y, z);
        uint8_t* d = w.img.get() + (z + 1) * w.sz + (y + 1) * w.sy + 1;
        int64_t x = 0;
        for (; x + 8 <= w.nx; x += 8) {  // eight bytes at a time: non-zero -> 1
          uint64_t v;
          std::memcpy(&v, s + x, 8);
          v = ((((v & (kOnes * 0x7F)) + kOnes * 0x7F) | v) >> 7) & kOnes;
          std::memcpy(d + x, &v, 8);
          count += __builtin_popcountll(v);
        }
        for (; x < w.nx; ++x) {
          d[x] = s[x] != 0;
          count += d[x];
        }
      }
      plane_count[static_cast<size_t>(z)] = count;
    }
  });
  for (int64_t c : plane_count) st.object_voxels += c;

  // skimage/Fiji border order 4, 3, 2, 1, 5, 6 = W (y-1), E (y+1), S (x+1), N (x-1), U (z+1), B (z-1).
  const std::array<int64_t, 6> offsets = {-w.sy, w.sy, 1, -1, w.sz, -w.sz};
  const int directions = w.nz == 1 ? 4 : 6;  // skimage: padded shape[0] == 3 -> four borders

  const int64_t rows = w.ny * w.nz;
  const int64_t chunks = std::min<int64_t>(rows, threads == 1 ? 1 : 8 * static_cast<int64_t>(threads));
  std::vector<int64_t> st_rows(static_cast<size_t>(chunks), 0);
  // Per chunk: the candidates (padded index and the neighbourhood word seen when collected) and the
  // rows scanned.
  std::vector<std::vector<Candidate>> cand(static_cast<size_t>(chunks));

  auto collect = [&](int dir) {
    const int64_t off = offsets[static_cast<size_t>(dir)];
    const uint8_t bit = static_cast<uint8_t>(1u << dir);
    const uint64_t clear = ~(kOnes << dir);
    // Dirty voxels of flagged rows, in raster order; a thread reads the image anywhere (unchanged
    // during collection) and writes the flags and dirty bits of its own rows only.
    parallel_chunks(0, rows, chunks, threads, [&](int64_t c, int64_t r0, int64_t r1) {
      std::vector<Candidate>& out = cand[static_cast<size_t>(c)];
      out.clear();
      int64_t scanned = 0;
      for (int64_t r = r0; r < r1; ++r) {
        const int64_t y = r % w.ny + 1, z = r / w.ny + 1;
        uint8_t& flag = w.rows[static_cast<size_t>(z * py + y)];
        if (!(flag & bit)) continue;
        flag = static_cast<uint8_t>(flag & ~bit);
        ++scanned;
        const int64_t base = z * w.sz + y * w.sy;
        const uint8_t* row = w.img.get() + base;
        uint8_t* drow = w.dirty.get() + base;
        for (int64_t x0 = 1; x0 <= w.nx; x0 += 8) {
          uint64_t a, b, d;
          std::memcpy(&d, drow + x0, 8);
          const int64_t left = w.nx + 1 - x0;
          uint64_t m = (d >> dir) & kOnes;
          if (left >= 8) {
            if (m == 0) continue;
            d &= clear;
            std::memcpy(drow + x0, &d, 8);
          } else {
            m &= (uint64_t{1} << (8 * left)) - 1;
            if (m == 0) continue;
            for (int64_t k = 0; k < left; ++k) drow[x0 + k] = static_cast<uint8_t>(drow[x0 + k] & ~bit);
          }
          std::memcpy(&a, row + x0, 8);
          std::memcpy(&b, row + x0 + off, 8);
          m &= a & ~b;
          while (m != 0) {
            const int64_t x = x0 + (__builtin_ctzll(m) >> 3);
            m &= m - 1;
            const int64_t i = base + x;
            const uint32_t cube = w.cube(i);
            if (__builtin_popcount(cube) == 2) continue;  // end point (the centre is counted)
            if (!euler_invariant_fast(euler, cube)) continue;
            if (!one_component_or_none(cube)) continue;
            out.push_back({i, z * py + y, cube});
          }
        }
      }
      st_rows[static_cast<size_t>(c)] += scanned;
    });
  };

  // After a deletion: the 26 neighbours (and the deleted voxel, now background) are dirty for every
  // direction, and so are their rows.
  auto mark = [&](const Candidate& k) {
    for (int64_t dz = -1; dz <= 1; ++dz) {
      uint8_t* f = w.rows.get() + k.row + dz * py;
      f[-1] = f[0] = f[1] = 0x3F;
      for (int64_t dy = -1; dy <= 1; ++dy) {
        uint8_t* p = w.dirty.get() + k.index - 1 + dz * w.sz + dy * w.sy;
        uint32_t v;  // bytes x-1, x, x+1 (and x+2, rewritten unchanged: this runs on one thread)
        std::memcpy(&v, p, 4);
        v |= 0x003F3F3Fu;
        std::memcpy(p, &v, 4);
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
          const uint32_t cube = w.cube(k.index);
          if (cube != k.cube && !one_component_or_none(cube)) {
            ++st.rejected;
            continue;
          }
          w.img[static_cast<size_t>(k.index)] = 0;
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
        const uint8_t* s = w.img.get() + (z + 1) * w.sz + (y + 1) * w.sy + 1;
        std::memcpy(d, s, static_cast<size_t>(w.nx));
        for (int64_t x = 0; x < w.nx; ++x) count += s[x];
      }
      plane_left[static_cast<size_t>(z)] = count;
    }
  });
  for (int64_t c : plane_left) st.skeleton_voxels += c;
  options.interrupter.check(1.0);
  return result;
}

}  // namespace skel::thinning
