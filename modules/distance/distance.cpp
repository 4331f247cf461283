// Distance transforms: chamfer raster scans, chamfer b(p), separable exact Euclidean DT and feature
// transform, seeded Euclidean distance. See distance.hpp for conventions.
#include "distance/distance.hpp"

#include <algorithm>
#include <array>
#include <cmath>
#include <cstring>
#include <memory>
#include <vector>

#if defined(__SSE4_1__)
#include <smmintrin.h>
#endif

#include "skel/block_journal.hpp"
#include "skel/distributed.hpp"
#include "skel/error.hpp"
#include "skel/mask.hpp"
#include "skel/parallel.hpp"

namespace skel::distance {
namespace {

// ============================================================================================ chamfer

// Outputs are allocated uninitialised; Volume's allocator already asks for transparent huge pages
// (skel::advise_huge_pages), so the first touch of a 512³ output costs few page faults.
template <class T> Volume<T> new_output(const Grid& g) { return Volume<T>::uninitialized(g); }

struct Weights64 {
  uint64_t fx, fy, fz, exy, exz, eyz, v;
};

Weights64 effective_weights(const Grid& grid, const ChamferOptions& o) {
  const ChamferWeights w =
      o.derive_from_spacing ? chamfer_weights_from_spacing(grid.spacing, o.spacing_scale) : o.weights;
  const uint32_t all[7] = {w.face_x, w.face_y, w.face_z, w.edge_xy, w.edge_xz, w.edge_yz, w.vertex};
  for (uint32_t v : all)
    if (v == 0) throw InputError("weights: chamfer weights must be >= 1");
  return {w.face_x, w.face_y, w.face_z, w.edge_xy, w.edge_xz, w.edge_yz, w.vertex};
}

uint64_t upper_bound(const Grid& grid, const Weights64& w, bool border_is_object) {
  const auto& d = grid.dims;
  const uint64_t f[3] = {w.fx, w.fy, w.fz};
  if (!border_is_object) {
    uint64_t best = std::numeric_limits<uint64_t>::max();
    for (int a = 0; a < 3; ++a) best = std::min(best, f[a] * static_cast<uint64_t>((d[a] + 1) / 2));
    return best;
  }
  uint64_t sum = 0;
  for (int a = 0; a < 3; ++a) sum += f[a] * static_cast<uint64_t>(std::max<int64_t>(0, d[a] - 1));
  return sum;
}

// Accumulator type: 32 bits for uint8 and uint16 output (INF + weight cannot overflow), 64 bits for uint32.
template <class T> using Acc = std::conditional_t<sizeof(T) <= 2, uint32_t, uint64_t>;

// Forward raster scan of one row: r[x] = min over the forward mask (z-1 plane, row y-1, x-1).
// py: row (y-1, z); zm, z0, zp: rows (y-1, y, y+1) of plane z-1; missing rows point to a row of B.
template <class T>
void forward_row(const uint8_t* m, T* r, const T* py, const T* zm, const T* z0, const T* zp, int64_t nx,
                 const Weights64& w64, Acc<T> B, Acc<T>* tmp) {
  using A = Acc<T>;
  const A fx = static_cast<A>(w64.fx), fy = static_cast<A>(w64.fy), fz = static_cast<A>(w64.fz);
  const A exy = static_cast<A>(w64.exy), exz = static_cast<A>(w64.exz), eyz = static_cast<A>(w64.eyz);
  const A vv = static_cast<A>(w64.v);
  const A INF = std::numeric_limits<T>::max();
  auto at = [&](const T* row, int64_t x) -> A { return (x < 0 || x >= nx) ? B : static_cast<A>(row[x]); };
  auto edge_voxel = [&](int64_t x) {
    A c = std::min({at(py, x - 1) + exy, at(py, x) + fy, at(py, x + 1) + exy, at(zm, x - 1) + vv,
                    at(zm, x) + eyz, at(zm, x + 1) + vv, at(z0, x - 1) + exz, at(z0, x) + fz,
                    at(z0, x + 1) + exz, at(zp, x - 1) + vv, at(zp, x) + eyz, at(zp, x + 1) + vv});
    tmp[x] = m[x] ? std::min(c, INF) : 0;
  };
  edge_voxel(0);
  for (int64_t x = 1; x < nx - 1; ++x) {
    A c0 = std::min(static_cast<A>(py[x - 1]) + exy, static_cast<A>(py[x + 1]) + exy);
    A c1 = std::min(static_cast<A>(py[x]) + fy, static_cast<A>(z0[x]) + fz);
    A c2 = std::min(static_cast<A>(zm[x - 1]) + vv, static_cast<A>(zm[x + 1]) + vv);
    A c3 = std::min(static_cast<A>(zp[x - 1]) + vv, static_cast<A>(zp[x + 1]) + vv);
    A c4 = std::min(static_cast<A>(zm[x]) + eyz, static_cast<A>(zp[x]) + eyz);
    A c5 = std::min(static_cast<A>(z0[x - 1]) + exz, static_cast<A>(z0[x + 1]) + exz);
    A c = std::min(std::min(std::min(c0, c1), std::min(c2, c3)), std::min(std::min(c4, c5), INF));
    tmp[x] = m[x] ? c : A(0);
  }
  if (nx > 1) edge_voxel(nx - 1);
  A prev = B;
  for (int64_t x = 0; x < nx; ++x) {
    A v = std::min(tmp[x], prev + fx);
    r[x] = static_cast<T>(v);
    prev = v;
  }
}

// Backward raster scan of one row: r[x] = min(r[x], backward mask (z+1 plane, row y+1, x+1)).
template <class T>
void backward_row(T* r, const T* py, const T* zm, const T* z0, const T* zp, int64_t nx, const Weights64& w64,
                  Acc<T> B, Acc<T>* tmp) {
  using A = Acc<T>;
  const A fx = static_cast<A>(w64.fx), fy = static_cast<A>(w64.fy), fz = static_cast<A>(w64.fz);
  const A exy = static_cast<A>(w64.exy), exz = static_cast<A>(w64.exz), eyz = static_cast<A>(w64.eyz);
  const A vv = static_cast<A>(w64.v);
  auto at = [&](const T* row, int64_t x) -> A { return (x < 0 || x >= nx) ? B : static_cast<A>(row[x]); };
  auto edge_voxel = [&](int64_t x) {
    A c = std::min({at(py, x - 1) + exy, at(py, x) + fy, at(py, x + 1) + exy, at(zm, x - 1) + vv,
                    at(zm, x) + eyz, at(zm, x + 1) + vv, at(z0, x - 1) + exz, at(z0, x) + fz,
                    at(z0, x + 1) + exz, at(zp, x - 1) + vv, at(zp, x) + eyz, at(zp, x + 1) + vv});
    tmp[x] = std::min(c, static_cast<A>(r[x]));
  };
  edge_voxel(0);
  for (int64_t x = 1; x < nx - 1; ++x) {
    A c0 = std::min(static_cast<A>(py[x - 1]) + exy, static_cast<A>(py[x + 1]) + exy);
    A c1 = std::min(static_cast<A>(py[x]) + fy, static_cast<A>(z0[x]) + fz);
    A c2 = std::min(static_cast<A>(zm[x - 1]) + vv, static_cast<A>(zm[x + 1]) + vv);
    A c3 = std::min(static_cast<A>(zp[x - 1]) + vv, static_cast<A>(zp[x + 1]) + vv);
    A c4 = std::min(static_cast<A>(zm[x]) + eyz, static_cast<A>(zp[x]) + eyz);
    A c5 = std::min(static_cast<A>(z0[x - 1]) + exz, static_cast<A>(z0[x + 1]) + exz);
    A c = std::min(std::min(std::min(c0, c1), std::min(c2, c3)), std::min(c4, c5));
    tmp[x] = std::min(c, static_cast<A>(r[x]));
  }
  if (nx > 1) edge_voxel(nx - 1);
  A prev = B;
  for (int64_t x = nx - 1; x >= 0; --x) {
    A v = std::min(tmp[x], prev + fx);
    r[x] = static_cast<T>(v);
    prev = v;
  }
}

#if defined(__SSE4_1__)
// uint16 rows with SSE4.1: saturating adds (65535 stays "unreached") and unsigned minima, 8 voxels per
// step; the x-1 (x+1) dependency is a log-step prefix minimum plus the carry from the previous vector.
struct SimdWeights {
  __m128i fy, fz, exy, exz, eyz, v, inf;
  __m128i fx1, fx2, fx4, ramp_fwd, ramp_bwd;  // ramp_fwd: (1..8)*fx; ramp_bwd: (8..1)*fx
  uint32_t fx;
};
SimdWeights simd_weights(const Weights64& w) {
  auto s = [](uint64_t x) { return _mm_set1_epi16(static_cast<short>(static_cast<uint16_t>(std::min<uint64_t>(x, 65535)))); };
  auto k = [&](uint64_t i) { return static_cast<short>(static_cast<uint16_t>(std::min<uint64_t>(i * w.fx, 65535))); };
  SimdWeights r;
  r.fy = s(w.fy);
  r.fz = s(w.fz);
  r.exy = s(w.exy);
  r.exz = s(w.exz);
  r.eyz = s(w.eyz);
  r.v = s(w.v);
  r.inf = _mm_set1_epi16(-1);
  r.fx1 = s(w.fx);
  r.fx2 = s(2 * w.fx);
  r.fx4 = s(4 * w.fx);
  r.ramp_fwd = _mm_setr_epi16(k(1), k(2), k(3), k(4), k(5), k(6), k(7), k(8));
  r.ramp_bwd = _mm_setr_epi16(k(8), k(7), k(6), k(5), k(4), k(3), k(2), k(1));
  r.fx = static_cast<uint32_t>(w.fx);
  return r;
}

inline __m128i ld(const uint16_t* p) { return _mm_loadu_si128(reinterpret_cast<const __m128i*>(p)); }

// Minimum over the 12 plane/row neighbours of voxels x..x+7 (1 <= x, x + 8 <= nx - 1).
inline __m128i neighbours12(const uint16_t* py, const uint16_t* zm, const uint16_t* z0, const uint16_t* zp, int64_t x,
                            const SimdWeights& s) {
  const __m128i vtx = _mm_adds_epu16(
      _mm_min_epu16(_mm_min_epu16(ld(zm + x - 1), ld(zm + x + 1)), _mm_min_epu16(ld(zp + x - 1), ld(zp + x + 1))), s.v);
  const __m128i eyz = _mm_adds_epu16(_mm_min_epu16(ld(zm + x), ld(zp + x)), s.eyz);
  const __m128i exz = _mm_adds_epu16(_mm_min_epu16(ld(z0 + x - 1), ld(z0 + x + 1)), s.exz);
  const __m128i fz = _mm_adds_epu16(ld(z0 + x), s.fz);
  const __m128i exy = _mm_adds_epu16(_mm_min_epu16(ld(py + x - 1), ld(py + x + 1)), s.exy);
  const __m128i fy = _mm_adds_epu16(ld(py + x), s.fy);
  return _mm_min_epu16(_mm_min_epu16(_mm_min_epu16(vtx, eyz), _mm_min_epu16(exz, fz)), _mm_min_epu16(exy, fy));
}

void forward_row_u16(const uint8_t* m, uint16_t* r, const uint16_t* py, const uint16_t* zm, const uint16_t* z0,
                     const uint16_t* zp, int64_t nx, const Weights64& w64, const SimdWeights& s, uint32_t B,
                     uint16_t* tmp) {
  const uint32_t fy = static_cast<uint32_t>(w64.fy), fz = static_cast<uint32_t>(w64.fz);
  const uint32_t exy = static_cast<uint32_t>(w64.exy), exz = static_cast<uint32_t>(w64.exz);
  const uint32_t eyz = static_cast<uint32_t>(w64.eyz), vv = static_cast<uint32_t>(w64.v);
  auto at = [&](const uint16_t* row, int64_t x) -> uint32_t { return (x < 0 || x >= nx) ? B : row[x]; };
  auto scalar = [&](int64_t x) {
    uint32_t c = std::min({at(py, x - 1) + exy, at(py, x) + fy, at(py, x + 1) + exy, at(zm, x - 1) + vv,
                           at(zm, x) + eyz, at(zm, x + 1) + vv, at(z0, x - 1) + exz, at(z0, x) + fz,
                           at(z0, x + 1) + exz, at(zp, x - 1) + vv, at(zp, x) + eyz, at(zp, x + 1) + vv});
    tmp[x] = m[x] ? static_cast<uint16_t>(std::min<uint32_t>(c, 65535)) : 0;
  };
  scalar(0);
  int64_t x = 1;
  const __m128i zero = _mm_setzero_si128();
  for (; x + 8 <= nx - 1; x += 8) {
    uint64_t m8;
    std::memcpy(&m8, m + x, 8);
    if (m8 == 0) {  // eight background voxels: nothing to propagate
      _mm_storeu_si128(reinterpret_cast<__m128i*>(tmp + x), zero);
      continue;
    }
    const __m128i c = neighbours12(py, zm, z0, zp, x, s);
    const __m128i mk = _mm_cvtepu8_epi16(_mm_loadl_epi64(reinterpret_cast<const __m128i*>(m + x)));
    const __m128i bg = _mm_cmpeq_epi16(mk, zero);
    _mm_storeu_si128(reinterpret_cast<__m128i*>(tmp + x), _mm_andnot_si128(bg, c));
  }
  for (; x < nx; ++x) scalar(x);
  // prefix: r[x] = min(tmp[x], r[x-1] + fx)
  uint32_t prev = B;
  __m128i carry = _mm_set1_epi16(static_cast<short>(static_cast<uint16_t>(std::min<uint32_t>(B, 65535))));
  x = 0;
  for (; x + 8 <= nx; x += 8) {
    __m128i v = ld(tmp + x);
    if (_mm_testz_si128(v, v)) {  // all background: zeros, and the carry is 0
      _mm_storeu_si128(reinterpret_cast<__m128i*>(r + x), v);
      carry = v;
      continue;
    }
    v = _mm_min_epu16(v, _mm_adds_epu16(_mm_alignr_epi8(v, s.inf, 14), s.fx1));
    v = _mm_min_epu16(v, _mm_adds_epu16(_mm_alignr_epi8(v, s.inf, 12), s.fx2));
    v = _mm_min_epu16(v, _mm_adds_epu16(_mm_alignr_epi8(v, s.inf, 8), s.fx4));
    v = _mm_min_epu16(v, _mm_adds_epu16(carry, s.ramp_fwd));
    _mm_storeu_si128(reinterpret_cast<__m128i*>(r + x), v);
    const __m128i hi = _mm_shufflehi_epi16(v, 0xFF);  // broadcast lane 7 without leaving the vector unit
    carry = _mm_unpackhi_epi64(hi, hi);
  }
  if (x > 0) prev = r[x - 1];
  for (; x < nx; ++x) {
    const uint32_t v = std::min<uint32_t>(tmp[x], prev + s.fx);
    r[x] = static_cast<uint16_t>(v);
    prev = v;
  }
}

void backward_row_u16(uint16_t* r, const uint16_t* py, const uint16_t* zm, const uint16_t* z0, const uint16_t* zp,
                      int64_t nx, const Weights64& w64, const SimdWeights& s, uint32_t B, uint16_t* tmp) {
  const uint32_t fy = static_cast<uint32_t>(w64.fy), fz = static_cast<uint32_t>(w64.fz);
  const uint32_t exy = static_cast<uint32_t>(w64.exy), exz = static_cast<uint32_t>(w64.exz);
  const uint32_t eyz = static_cast<uint32_t>(w64.eyz), vv = static_cast<uint32_t>(w64.v);
  auto at = [&](const uint16_t* row, int64_t x) -> uint32_t { return (x < 0 || x >= nx) ? B : row[x]; };
  auto scalar = [&](int64_t x) {
    uint32_t c = std::min({at(py, x - 1) + exy, at(py, x) + fy, at(py, x + 1) + exy, at(zm, x - 1) + vv,
                           at(zm, x) + eyz, at(zm, x + 1) + vv, at(z0, x - 1) + exz, at(z0, x) + fz,
                           at(z0, x + 1) + exz, at(zp, x - 1) + vv, at(zp, x) + eyz, at(zp, x + 1) + vv});
    tmp[x] = static_cast<uint16_t>(std::min<uint32_t>(c, r[x]));
  };
  scalar(0);
  int64_t x = 1;
  for (; x + 8 <= nx - 1; x += 8) {
    const __m128i cur = ld(r + x);
    if (_mm_testz_si128(cur, cur)) {  // eight background voxels (0 after the forward scan) stay 0
      _mm_storeu_si128(reinterpret_cast<__m128i*>(tmp + x), cur);
      continue;
    }
    const __m128i c = neighbours12(py, zm, z0, zp, x, s);
    _mm_storeu_si128(reinterpret_cast<__m128i*>(tmp + x), _mm_min_epu16(c, cur));
  }
  for (; x < nx; ++x) scalar(x);
  // suffix: r[x] = min(tmp[x], r[x+1] + fx), right to left
  uint32_t prev = B;
  const int64_t full = nx / 8 * 8;
  for (x = nx - 1; x >= full; --x) {
    const uint32_t v = std::min<uint32_t>(tmp[x], prev + s.fx);
    r[x] = static_cast<uint16_t>(v);
    prev = v;
  }
  __m128i carry = _mm_set1_epi16(static_cast<short>(static_cast<uint16_t>(std::min<uint32_t>(prev, 65535))));
  for (x = full - 8; x >= 0; x -= 8) {
    __m128i v = ld(tmp + x);
    if (_mm_testz_si128(v, v)) {
      _mm_storeu_si128(reinterpret_cast<__m128i*>(r + x), v);
      carry = v;
      continue;
    }
    v = _mm_min_epu16(v, _mm_adds_epu16(_mm_alignr_epi8(s.inf, v, 2), s.fx1));
    v = _mm_min_epu16(v, _mm_adds_epu16(_mm_alignr_epi8(s.inf, v, 4), s.fx2));
    v = _mm_min_epu16(v, _mm_adds_epu16(_mm_alignr_epi8(s.inf, v, 8), s.fx4));
    v = _mm_min_epu16(v, _mm_adds_epu16(carry, s.ramp_bwd));
    _mm_storeu_si128(reinterpret_cast<__m128i*>(r + x), v);
    const __m128i lo = _mm_shufflelo_epi16(v, 0x00);  // broadcast lane 0
    carry = _mm_unpacklo_epi64(lo, lo);
  }
}
// uint8 rows (chamfer with `narrow`): the same kernels on 16 voxels per step with saturating uint8
// adds, so every value is min(d, 255) of the uint16 result d (min and d + w are monotone; 255 + w stays
// 255). chamfer_u8 rejects the volume if any value reached 255.
struct SimdWeights8 {
  __m128i fy, fz, exy, exz, eyz, v, inf;
  __m128i fx1, fx2, fx4, fx8, ramp_fwd, ramp_bwd;  // ramp_fwd: (1..16)*fx; ramp_bwd: (16..1)*fx
  uint32_t fx;
};
SimdWeights8 simd_weights8(const Weights64& w) {
  auto b = [](uint64_t x) { return static_cast<char>(static_cast<uint8_t>(std::min<uint64_t>(x, 255))); };
  auto s = [&](uint64_t x) { return _mm_set1_epi8(b(x)); };
  SimdWeights8 r;
  r.fy = s(w.fy);
  r.fz = s(w.fz);
  r.exy = s(w.exy);
  r.exz = s(w.exz);
  r.eyz = s(w.eyz);
  r.v = s(w.v);
  r.inf = _mm_set1_epi8(-1);
  r.fx1 = s(w.fx);
  r.fx2 = s(2 * w.fx);
  r.fx4 = s(4 * w.fx);
  r.fx8 = s(8 * w.fx);
  alignas(16) char f[16], g[16];
  for (int i = 0; i < 16; ++i) {
    f[i] = b(static_cast<uint64_t>(i + 1) * w.fx);
    g[i] = b(static_cast<uint64_t>(16 - i) * w.fx);
  }
  r.ramp_fwd = _mm_load_si128(reinterpret_cast<const __m128i*>(f));
  r.ramp_bwd = _mm_load_si128(reinterpret_cast<const __m128i*>(g));
  r.fx = static_cast<uint32_t>(w.fx);
  return r;
}

inline __m128i ld8(const uint8_t* p) { return _mm_loadu_si128(reinterpret_cast<const __m128i*>(p)); }

// Minimum over the 12 plane/row neighbours of voxels x..x+15 (1 <= x, x + 16 <= nx - 1).
inline __m128i neighbours12_u8(const uint8_t* py, const uint8_t* zm, const uint8_t* z0, const uint8_t* zp, int64_t x,
                               const SimdWeights8& s) {
  const __m128i vtx = _mm_adds_epu8(
      _mm_min_epu8(_mm_min_epu8(ld8(zm + x - 1), ld8(zm + x + 1)), _mm_min_epu8(ld8(zp + x - 1), ld8(zp + x + 1))), s.v);
  const __m128i eyz = _mm_adds_epu8(_mm_min_epu8(ld8(zm + x), ld8(zp + x)), s.eyz);
  const __m128i exz = _mm_adds_epu8(_mm_min_epu8(ld8(z0 + x - 1), ld8(z0 + x + 1)), s.exz);
  const __m128i fz = _mm_adds_epu8(ld8(z0 + x), s.fz);
  const __m128i exy = _mm_adds_epu8(_mm_min_epu8(ld8(py + x - 1), ld8(py + x + 1)), s.exy);
  const __m128i fy = _mm_adds_epu8(ld8(py + x), s.fy);
  return _mm_min_epu8(_mm_min_epu8(_mm_min_epu8(vtx, eyz), _mm_min_epu8(exz, fz)), _mm_min_epu8(exy, fy));
}

void forward_row_u8(const uint8_t* m, uint8_t* r, const uint8_t* py, const uint8_t* zm, const uint8_t* z0,
                    const uint8_t* zp, int64_t nx, const Weights64& w64, const SimdWeights8& s, uint32_t B,
                    uint8_t* tmp) {
  const uint32_t fy = static_cast<uint32_t>(w64.fy), fz = static_cast<uint32_t>(w64.fz);
  const uint32_t exy = static_cast<uint32_t>(w64.exy), exz = static_cast<uint32_t>(w64.exz);
  const uint32_t eyz = static_cast<uint32_t>(w64.eyz), vv = static_cast<uint32_t>(w64.v);
  auto at = [&](const uint8_t* row, int64_t x) -> uint32_t { return (x < 0 || x >= nx) ? B : row[x]; };
  auto scalar = [&](int64_t x) {
    uint32_t c = std::min({at(py, x - 1) + exy, at(py, x) + fy, at(py, x + 1) + exy, at(zm, x - 1) + vv,
                           at(zm, x) + eyz, at(zm, x + 1) + vv, at(z0, x - 1) + exz, at(z0, x) + fz,
                           at(z0, x + 1) + exz, at(zp, x - 1) + vv, at(zp, x) + eyz, at(zp, x + 1) + vv});
    tmp[x] = m[x] ? static_cast<uint8_t>(std::min<uint32_t>(c, 255)) : 0;
  };
  scalar(0);
  int64_t x = 1;
  const __m128i zero = _mm_setzero_si128();
  for (; x + 16 <= nx - 1; x += 16) {
    const __m128i mk = ld8(m + x);
    if (_mm_testz_si128(mk, mk)) {  // sixteen background voxels: nothing to propagate
      _mm_storeu_si128(reinterpret_cast<__m128i*>(tmp + x), zero);
      continue;
    }
    const __m128i c = neighbours12_u8(py, zm, z0, zp, x, s);
    const __m128i bg = _mm_cmpeq_epi8(mk, zero);
    _mm_storeu_si128(reinterpret_cast<__m128i*>(tmp + x), _mm_andnot_si128(bg, c));
  }
  for (; x < nx; ++x) scalar(x);
  // prefix: r[x] = min(tmp[x], r[x-1] + fx)
  uint32_t prev = B;
  __m128i carry = _mm_set1_epi8(static_cast<char>(static_cast<uint8_t>(std::min<uint32_t>(B, 255))));
  const __m128i last = _mm_set1_epi8(15);
  x = 0;
  for (; x + 16 <= nx; x += 16) {
    __m128i v = ld8(tmp + x);
    if (_mm_testz_si128(v, v)) {  // all background: zeros, and the carry is 0
      _mm_storeu_si128(reinterpret_cast<__m128i*>(r + x), v);
      carry = v;
      continue;
    }
    v = _mm_min_epu8(v, _mm_adds_epu8(_mm_alignr_epi8(v, s.inf, 15), s.fx1));
    v = _mm_min_epu8(v, _mm_adds_epu8(_mm_alignr_epi8(v, s.inf, 14), s.fx2));
    v = _mm_min_epu8(v, _mm_adds_epu8(_mm_alignr_epi8(v, s.inf, 12), s.fx4));
    v = _mm_min_epu8(v, _mm_adds_epu8(_mm_alignr_epi8(v, s.inf, 8), s.fx8));
    v = _mm_min_epu8(v, _mm_adds_epu8(carry, s.ramp_fwd));
    _mm_storeu_si128(reinterpret_cast<__m128i*>(r + x), v);
    carry = _mm_shuffle_epi8(v, last);  // broadcast lane 15
  }
  if (x > 0) prev = r[x - 1];
  for (; x < nx; ++x) {
    const uint32_t v = std::min<uint32_t>({tmp[x], prev + s.fx, 255});
    r[x] = static_cast<uint8_t>(v);
    prev = v;
  }
}

void backward_row_u8(uint8_t* r, const uint8_t* py, const uint8_t* zm, const uint8_t* z0, const uint8_t* zp,
                     int64_t nx, const Weights64& w64, const SimdWeights8& s, uint32_t B, uint8_t* tmp) {
  const uint32_t fy = static_cast<uint32_t>(w64.fy), fz = static_cast<uint32_t>(w64.fz);
  const uint32_t exy = static_cast<uint32_t>(w64.exy), exz = static_cast<uint32_t>(w64.exz);
  const uint32_t eyz = static_cast<uint32_t>(w64.eyz), vv = static_cast<uint32_t>(w64.v);
  auto at = [&](const uint8_t* row, int64_t x) -> uint32_t { return (x < 0 || x >= nx) ? B : row[x]; };
  auto scalar = [&](int64_t x) {
    uint32_t c = std::min({at(py, x - 1) + exy, at(py, x) + fy, at(py, x + 1) + exy, at(zm, x - 1) + vv,
                           at(zm, x) + eyz, at(zm, x + 1) + vv, at(z0, x - 1) + exz, at(z0, x) + fz,
                           at(z0, x + 1) + exz, at(zp, x - 1) + vv, at(zp, x) + eyz, at(zp, x + 1) + vv});
    tmp[x] = static_cast<uint8_t>(std::min<uint32_t>(c, r[x]));
  };
  scalar(0);
  int64_t x = 1;
  for (; x + 16 <= nx - 1; x += 16) {
    const __m128i cur = ld8(r + x);
    if (_mm_testz_si128(cur, cur)) {  // sixteen background voxels (0 after the forward scan) stay 0
      _mm_storeu_si128(reinterpret_cast<__m128i*>(tmp + x), cur);
      continue;
    }
    const __m128i c = neighbours12_u8(py, zm, z0, zp, x, s);
    _mm_storeu_si128(reinterpret_cast<__m128i*>(tmp + x), _mm_min_epu8(c, cur));
  }
  for (; x < nx; ++x) scalar(x);
  // suffix: r[x] = min(tmp[x], r[x+1] + fx), right to left
  uint32_t prev = B;
  const int64_t full = nx / 16 * 16;
  for (x = nx - 1; x >= full; --x) {
    const uint32_t v = std::min<uint32_t>({tmp[x], prev + s.fx, 255});
    r[x] = static_cast<uint8_t>(v);
    prev = v;
  }
  __m128i carry = _mm_set1_epi8(static_cast<char>(static_cast<uint8_t>(std::min<uint32_t>(prev, 255))));
  const __m128i first = _mm_setzero_si128();
  for (x = full - 16; x >= 0; x -= 16) {
    __m128i v = ld8(tmp + x);
    if (_mm_testz_si128(v, v)) {
      _mm_storeu_si128(reinterpret_cast<__m128i*>(r + x), v);
      carry = v;
      continue;
    }
    v = _mm_min_epu8(v, _mm_adds_epu8(_mm_alignr_epi8(s.inf, v, 1), s.fx1));
    v = _mm_min_epu8(v, _mm_adds_epu8(_mm_alignr_epi8(s.inf, v, 2), s.fx2));
    v = _mm_min_epu8(v, _mm_adds_epu8(_mm_alignr_epi8(s.inf, v, 4), s.fx4));
    v = _mm_min_epu8(v, _mm_adds_epu8(_mm_alignr_epi8(s.inf, v, 8), s.fx8));
    v = _mm_min_epu8(v, _mm_adds_epu8(carry, s.ramp_bwd));
    _mm_storeu_si128(reinterpret_cast<__m128i*>(r + x), v);
    carry = _mm_shuffle_epi8(v, first);  // broadcast lane 0
  }
}
#endif

template <class T>
Volume<T> chamfer_impl(const VolumeU8& mask, const Weights64& w, const ChamferOptions& o) {
  using A = Acc<T>;
  const int64_t nx = mask.nx(), ny = mask.ny(), nz = mask.nz();
  Volume<T> out = new_output<T>(mask.grid());
  if (out.size() == 0) return out;
  const T INF = std::numeric_limits<T>::max();
  const A B = o.border_is_object ? A(INF) : A(0);
  std::vector<T> const_row(static_cast<size_t>(nx), static_cast<T>(B));
  std::vector<A> tmp(static_cast<size_t>(nx));
#if defined(__SSE4_1__)
  std::vector<uint16_t> tmp16(static_cast<size_t>(nx));
  const SimdWeights sw = simd_weights(w);
  std::vector<uint8_t> tmp8(std::is_same_v<T, uint8_t> ? static_cast<size_t>(nx) : size_t{0});
  const SimdWeights8 sw8 = simd_weights8(w);
#endif
  const T* cr = const_row.data();
  const int64_t plane = nx * ny;
  const uint8_t* m = mask.data();
  T* d = out.data();
  auto row = [&](int64_t y, int64_t z) -> const T* {
    return (y < 0 || y >= ny || z < 0 || z >= nz) ? cr : d + y * nx + z * plane;
  };
  const int64_t check_every = std::max<int64_t>(1, (int64_t{4} << 20) / std::max<int64_t>(1, plane));
  // Rows without object voxels are 0 after the forward scan and stay 0 in the backward scan (it only
  // lowers values): the forward scan writes them with one memset, the backward scan skips them.
  std::vector<uint8_t> has_object(static_cast<size_t>(ny * nz), 0);
  auto row_has_object = [nx](const uint8_t* mr) {
    int64_t x = 0;
    for (; x + 32 <= nx; x += 32) {
      uint64_t a, b, c, e;
      std::memcpy(&a, mr + x, 8);
      std::memcpy(&b, mr + x + 8, 8);
      std::memcpy(&c, mr + x + 16, 8);
      std::memcpy(&e, mr + x + 24, 8);
      if ((a | b | c | e) != 0) return true;
    }
    for (; x < nx; ++x)
      if (mr[x]) return true;
    return false;
  };
  for (int64_t z = 0; z < nz; ++z) {
    if (z % check_every == 0) o.interrupter.check(0.5 * static_cast<double>(z) / static_cast<double>(nz));
    for (int64_t y = 0; y < ny; ++y) {
      if (!row_has_object(m + y * nx + z * plane)) {
        std::memset(d + y * nx + z * plane, 0, static_cast<size_t>(nx) * sizeof(T));
        continue;
      }
      has_object[static_cast<size_t>(y + ny * z)] = 1;
#if defined(__SSE4_1__)
      if constexpr (std::is_same_v<T, uint16_t>)
        forward_row_u16(m + y * nx + z * plane, d + y * nx + z * plane, row(y - 1, z), row(y - 1, z - 1),
                        row(y, z - 1), row(y + 1, z - 1), nx, w, sw, B, tmp16.data());
      else if constexpr (std::is_same_v<T, uint8_t>)
        forward_row_u8(m + y * nx + z * plane, d + y * nx + z * plane, row(y - 1, z), row(y - 1, z - 1),
                       row(y, z - 1), row(y + 1, z - 1), nx, w, sw8, B, tmp8.data());
      else
#endif
      forward_row<T>(m + y * nx + z * plane, d + y * nx + z * plane, row(y - 1, z), row(y - 1, z - 1),
                     row(y, z - 1), row(y + 1, z - 1), nx, w, B, tmp.data());
    }
  }
  constexpr int64_t kAheadRows = 4;  // measured at 512³: 2, 8, 16 rows ahead were slower
  for (int64_t z = nz - 1; z >= 0; --z) {
    if (z % check_every == 0)
      o.interrupter.check(0.5 + 0.5 * static_cast<double>(nz - 1 - z) / static_cast<double>(nz));
    for (int64_t y = ny - 1; y >= 0; --y) {
      // The backward scan walks the rows in descending order, which the hardware prefetchers follow
      // poorly: fetch the row kAheadRows ahead (reading the current row was the scan's main stall).
      const int64_t ahead = y + ny * z - kAheadRows;
      if (ahead >= 0 && has_object[static_cast<size_t>(ahead)]) {
        const char* a = reinterpret_cast<const char*>(d + ahead * nx);
        for (int64_t b = 0; b < nx * static_cast<int64_t>(sizeof(T)); b += 64) __builtin_prefetch(a + b, 1);
      }
      if (!has_object[static_cast<size_t>(y + ny * z)]) continue;
#if defined(__SSE4_1__)
      if constexpr (std::is_same_v<T, uint16_t>)
        backward_row_u16(d + y * nx + z * plane, row(y + 1, z), row(y + 1, z + 1), row(y, z + 1), row(y - 1, z + 1),
                         nx, w, sw, B, tmp16.data());
      else if constexpr (std::is_same_v<T, uint8_t>)
        backward_row_u8(d + y * nx + z * plane, row(y + 1, z), row(y + 1, z + 1), row(y, z + 1), row(y - 1, z + 1),
                        nx, w, sw8, B, tmp8.data());
      else
#endif
      backward_row<T>(d + y * nx + z * plane, row(y + 1, z), row(y + 1, z + 1), row(y, z + 1), row(y - 1, z + 1),
                      nx, w, B, tmp.data());
    }
  }
  o.interrupter.check(1.0);
  return out;
}

// Chamfer b(p): both raster scans, each voxel taking value and nearest point from the first
// neighbour (in mask order) giving a strictly smaller value.
template <class T, class Index>
void chamfer_nearest_impl(const VolumeU8& mask, const Weights64& w, const ChamferOptions& o, Volume<T>& dist,
                          Volume<Index>& near) {
  using A = uint64_t;
  const int64_t nx = mask.nx(), ny = mask.ny(), nz = mask.nz(), plane = nx * ny;
  const A INF = std::numeric_limits<T>::max();
  const Index OUT = std::numeric_limits<Index>::max();
  const bool outside_bg = !o.border_is_object;
  struct Off {
    int dx, dy, dz;
    A w;
  };
  // Forward mask in scan order: plane z-1 (rows y-1..y+1, x-1..x+1), row y-1 (x-1..x+1), then x-1.
  std::vector<Off> fwd;
  auto weight = [&](int dx, int dy, int dz) -> A {
    const int k = (dx != 0) + (dy != 0) + (dz != 0);
    if (k == 3) return w.v;
    if (k == 1) return dx ? w.fx : (dy ? w.fy : w.fz);
    if (dz == 0) return w.exy;
    if (dy == 0) return w.exz;
    return w.eyz;
  };
  for (int dy = -1; dy <= 1; ++dy)
    for (int dx = -1; dx <= 1; ++dx) fwd.push_back({dx, dy, -1, weight(dx, dy, -1)});
  for (int dx = -1; dx <= 1; ++dx) fwd.push_back({dx, -1, 0, weight(dx, -1, 0)});
  fwd.push_back({-1, 0, 0, w.fx});
  std::vector<Off> bwd;
  for (const Off& f : fwd) bwd.push_back({-f.dx, -f.dy, -f.dz, f.w});
  std::vector<int64_t> fwd_delta, bwd_delta;
  for (const Off& f : fwd) fwd_delta.push_back(f.dx + f.dy * nx + f.dz * plane);
  for (const Off& f : bwd) bwd_delta.push_back(f.dx + f.dy * nx + f.dz * plane);

  const uint8_t* m = mask.data();
  T* d = dist.data();
  Index* b = near.data();
  const int64_t check_every = std::max<int64_t>(1, (int64_t{2} << 20) / std::max<int64_t>(1, plane));
  auto scan = [&](const std::vector<Off>& offs, const std::vector<int64_t>& delta, int64_t x, int64_t y, int64_t z,
                  int64_t i, bool interior) {
    A best = d[i];
    Index bi = b[i];
    for (size_t k = 0; k < offs.size(); ++k) {
      A cand;
      Index cb;
      if (interior) {
        cand = static_cast<A>(d[i + delta[k]]);
        cb = b[i + delta[k]];
      } else {
        const int64_t xx = x + offs[k].dx, yy = y + offs[k].dy, zz = z + offs[k].dz;
        if (xx < 0 || yy < 0 || zz < 0 || xx >= nx || yy >= ny || zz >= nz) {
          if (!outside_bg) continue;
          cand = 0;
          cb = OUT;
        } else {
          cand = static_cast<A>(d[i + delta[k]]);
          cb = b[i + delta[k]];
        }
      }
      if (cand >= INF) continue;
      cand += offs[k].w;
      if (cand < best) {
        best = cand;
        bi = cb;
      }
    }
    d[i] = static_cast<T>(best);
    b[i] = bi;
  };
  for (int64_t z = 0; z < nz; ++z) {
    if (z % check_every == 0) o.interrupter.check(0.5 * static_cast<double>(z) / static_cast<double>(nz));
    for (int64_t y = 0; y < ny; ++y) {
      const bool yz_in = y > 0 && y < ny - 1 && z > 0 && z < nz - 1;
      for (int64_t x = 0; x < nx; ++x) {
        const int64_t i = x + y * nx + z * plane;
        if (!m[i]) {
          d[i] = 0;
          b[i] = static_cast<Index>(i);
          continue;
        }
        d[i] = static_cast<T>(INF);
        b[i] = OUT;
        scan(fwd, fwd_delta, x, y, z, i, yz_in && x > 0 && x < nx - 1);
      }
    }
  }
  for (int64_t z = nz - 1; z >= 0; --z) {
    if (z % check_every == 0)
      o.interrupter.check(0.5 + 0.5 * static_cast<double>(nz - 1 - z) / static_cast<double>(nz));
    for (int64_t y = ny - 1; y >= 0; --y) {
      const bool yz_in = y > 0 && y < ny - 1 && z > 0 && z < nz - 1;
      for (int64_t x = nx - 1; x >= 0; --x) {
        const int64_t i = x + y * nx + z * plane;
        if (!m[i]) continue;
        scan(bwd, bwd_delta, x, y, z, i, yz_in && x > 0 && x < nx - 1);
      }
    }
  }
  o.interrupter.check(1.0);
}

// ========================================================================================== Euclidean

constexpr float kInf = std::numeric_limits<float>::infinity();

// Per-thread scratch for the 1D lower envelope of n parabolas.
struct Envelope {
  std::vector<int64_t> v;   // site positions (-1 and n: virtual sites outside the array)
  std::vector<double> z;    // left boundary of each site's interval
  std::vector<double> fv;   // site values
  explicit Envelope(int64_t n) : v(static_cast<size_t>(n + 2)), z(static_cast<size_t>(n + 3)), fv(static_cast<size_t>(n + 2)) {}
};

// One run [a, e) of a line f[0, n) (element q at f[q * stride]) with f > 0 on the run: out[x - a] = min over sites s of
// (w (x - s)^2 + f[s]) for x in the run. Because f is 0 at a - 1 and e (or those are outside the line),
// no site beyond them can win, so the sites are: a - 1 (value 0; or the virtual site -1 if a == 0 and
// `outside`), the finite positions of the run, and e (value 0; or the virtual site n if e == n and
// `outside`). Ties go to the lower site position. site_out[x - a] receives the chosen site position
// (-1 or n for virtual sites). Returns false if there is no site at all (out untouched).
bool envelope_run(const float* f, int64_t stride, int64_t a, int64_t e, int64_t n, double w, bool outside,
                  Envelope& env, float* out, int64_t* site_out) {
  int64_t k = -1;
  int64_t* v = env.v.data();
  double* z = env.z.data();
  double* fv = env.fv.data();
  auto add = [&](int64_t q, double fq) {
    const double qd = static_cast<double>(q);
    const double cq = fq + w * qd * qd;
    double s = -std::numeric_limits<double>::infinity();
    while (k >= 0) {
      const double vk = static_cast<double>(v[k]);
      s = (cq - (fv[k] + w * vk * vk)) / (2.0 * w * (qd - vk));
      if (s > z[k]) break;
      --k;
      s = -std::numeric_limits<double>::infinity();
    }
    ++k;
    v[k] = q;
    fv[k] = fq;
    z[k] = s;
  };
  if (a > 0 || outside) add(a - 1, 0.0);
  for (int64_t q = a; q < e; ++q)
    if (f[q * stride] != kInf) add(q, static_cast<double>(f[q * stride]));
  if (e < n || outside) add(e, 0.0);
  if (k < 0) return false;
  z[k + 1] = std::numeric_limits<double>::infinity();
  int64_t j = 0;
  for (int64_t x = a; x < e; ++x) {
    const double xd = static_cast<double>(x);
    while (z[j + 1] < xd) ++j;
    const double dx = xd - static_cast<double>(v[j]);
    out[x - a] = static_cast<float>(w * dx * dx + fv[j]);
    site_out[x - a] = v[j];
  }
  return true;
}

struct NoIndex {};

// Pass x of squared_edt, one z-plane of a contiguous buffer of dims (nx, ny, nz): per row, the squared
// distance along x to the nearest site (distances only: per run of non-sites; with features: two
// scans). is_site(i) takes buffer indices; feat receives
// them. `left` is per-thread scratch of nx elements (feature transforms only). `seg` (distances only;
// may be null): this plane's segment flags, [y][x / 64], set to 1 where the 64 voxels of the row from
// x / 64 * 64 hold a non-site (the only voxels with a non-zero value in any pass), else 0.
template <class Index, class IsSite>
void edt_plane_x(const Dims& dims, const IsSite& is_site, bool outside_site, double wx, int64_t z,
                 std::vector<int64_t>& left, float* sq, Index* feat, uint8_t* seg = nullptr) {
  constexpr bool with_feat = !std::is_same_v<Index, NoIndex>;
  using Idx = std::conditional_t<with_feat, Index, uint32_t>;
  const Idx OUT = std::numeric_limits<Idx>::max();
  (void)OUT;
  const int64_t nx = dims[0], ny = dims[1], plane = nx * ny;
  for (int64_t y = 0; y < ny; ++y) {
    const int64_t base = y * nx + z * plane;
    float* r = sq + base;
    if constexpr (!with_feat) {
      // Distances only: the row is cleared (sites are 0), then each run [a, e) of non-sites gets
      // min(q - a + 1, e - q) squared: the distance to the site before it (a - 1) and after it (e),
      // where those exist (a virtual site outside the array with `outside_site`). The same values as
      // two scans over the row, with no work per site beyond the test.
      constexpr int64_t kFar = int64_t{1} << 30;
      const float wxf = static_cast<float>(wx);
      std::memset(r, 0, static_cast<size_t>(nx) * sizeof(float));
      uint8_t* row_seg = seg ? seg + y * ((nx + 63) / 64) : nullptr;
      if (row_seg) std::memset(row_seg, 0, static_cast<size_t>((nx + 63) / 64));
      for (int64_t x = 0; x < nx;) {
        if (is_site(base + x)) {
          ++x;
          continue;
        }
        const int64_t a = x;
        while (x < nx && !is_site(base + x)) ++x;
        const int64_t e = x;
        if (row_seg) std::memset(row_seg + a / 64, 1, static_cast<size_t>((e - 1) / 64 - a / 64 + 1));
        const bool site_before = a > 0 || outside_site, site_after = e < nx || outside_site;
        for (int64_t q = a; q < e; ++q) {
          const int64_t d = std::min(site_before ? q - a + 1 : kFar, site_after ? e - q : kFar);
          const float fe = static_cast<float>(d);
          r[q] = d >= kFar ? kInf : wxf * fe * fe;
        }
      }
      continue;
    }
    int64_t last = outside_site ? -1 : std::numeric_limits<int64_t>::min();
    bool any = outside_site;
    for (int64_t x = 0; x < nx; ++x) {
      if (is_site(base + x)) {
        last = x;
        any = true;
      }
      left[static_cast<size_t>(x)] = last;
    }
    if (!any) {
      std::fill(r, r + nx, kInf);
      if constexpr (with_feat) std::fill(feat + base, feat + base + nx, OUT);
      continue;
    }
    int64_t next = outside_site ? nx : std::numeric_limits<int64_t>::max();
    for (int64_t x = nx - 1; x >= 0; --x) {
      const int64_t l = left[static_cast<size_t>(x)];
      if (l == x) {
        next = x;
        r[x] = 0.0f;
        if constexpr (with_feat) feat[base + x] = static_cast<Idx>(base + x);
        continue;
      }
      const bool has_l = l != std::numeric_limits<int64_t>::min();
      const bool has_r = next != std::numeric_limits<int64_t>::max();
      const int64_t dl = has_l ? x - l : std::numeric_limits<int64_t>::max();
      const int64_t dr = has_r ? next - x : std::numeric_limits<int64_t>::max();
      const bool use_l = dl <= dr;
      const double dd = static_cast<double>(use_l ? dl : dr);
      r[x] = static_cast<float>(wx * dd * dd);
      if constexpr (with_feat) {
        const int64_t s = use_l ? l : next;
        feat[base + x] = (s < 0 || s >= nx) ? OUT : static_cast<Idx>(base + s);
      }
    }
  }
}

// Pass x over the whole buffer, parallel over z-planes.
template <class Index, class IsSite>
void edt_pass_x(const Dims& dims, IsSite is_site, bool outside_site, double wx, int threads,
                const Interrupter& interrupter, float* sq, Index* feat) {
  parallel_for(0, dims[2], threads, [&](int64_t z0, int64_t z1) {
    std::vector<int64_t> left(static_cast<size_t>(dims[0]));
    for (int64_t z = z0; z < z1; ++z) {
      interrupter.check();
      edt_plane_x<Index>(dims, is_site, outside_site, wx, z, left, sq, feat);
    }
  });
}

// No conversion of the squared distances after the last pass.
struct NoFinish {
  static constexpr bool active = false;
  float operator()(float v) const { return v; }
};

// The conversion of finish_distances for one value (squared distances -> requested output); maps 0 to 0.
struct Finish {
  static constexpr bool active = true;
  bool squared = false, isotropic = true;
  float s1 = 1.0f, s2 = 1.0f;
  float operator()(float v) const {
    if (squared) return v * s2;
    return isotropic ? std::sqrt(v) * s1 : std::sqrt(v);
  }
};

// Per-thread scratch of a column pass with blocks of kB adjacent columns over lines of n_line.
template <class Index, int64_t kB>
struct ColumnScratch {
  using Bits = std::conditional_t<(kB > 32), uint64_t, uint32_t>;
  using Idx = std::conditional_t<std::is_same_v<Index, NoIndex>, uint32_t, Index>;
  std::vector<float> blk, fout;  // blk[t * kB + b]: the block stored line-major
  std::vector<Bits> nonzero;
  std::vector<int64_t> site;
  std::vector<Idx> iout;
  Envelope env;
  explicit ColumnScratch(int64_t n_line)
      : blk(static_cast<size_t>(kB * n_line)), fout(static_cast<size_t>(n_line)), nonzero(static_cast<size_t>(n_line)),
        site(static_cast<size_t>(n_line)),
        iout(std::is_same_v<Index, NoIndex> ? 0 : static_cast<size_t>(n_line)), env(n_line) {}
};

// Pass y or z of squared_edt for one group `o` of columns of a buffer whose rows are `nx` wide: columns of
// n_line elements `line_stride` apart, starting at o * outer_stride + x; the lower envelope of the
// parabolas w (x - s)² + f(s) per column. Blocks of kB adjacent columns are gathered into contiguous
// line buffers. `finish` (when active) converts every value of a block before it is written back.
// `sf.seg` (may be null): the segment flags of edt_plane_x for the whole buffer; flag of line element t
// of the block at x0: sf.seg[o * sf.outer + t * sf.line + x0 / 64] (kB divides 64). A row whose flag is
// 0 holds only zeros and is not read.
struct SegmentFlags {
  const uint8_t* seg = nullptr;
  int64_t outer = 0, line = 0;
};
template <class Index, int64_t kB, class Fin>
void edt_column_group(float* sq, Index* feat, int64_t nx, int64_t o, int64_t n_line, int64_t outer_stride,
                      int64_t line_stride, double w, bool outside_site, ColumnScratch<Index, kB>& s, const Fin& finish,
                      const SegmentFlags& sf = {}) {
  static_assert(64 % kB == 0);
  constexpr bool with_feat = !std::is_same_v<Index, NoIndex>;
  using Idx = typename ColumnScratch<Index, kB>::Idx;
  using Bits = typename ColumnScratch<Index, kB>::Bits;
  const Idx OUT = std::numeric_limits<Idx>::max();
  (void)OUT;
  for (int64_t x0 = 0; x0 < nx; x0 += kB) {
    const int64_t nb = std::min(kB, nx - x0);
    const int64_t base = o * outer_stride + x0;
    // Rows of the block without a non-zero value (all sites: the usual case away from the object)
    // are found with one OR over their bit patterns and neither copied, converted nor written back:
    // their values stay 0 (and finish maps 0 to 0). Only rows with a non-zero bit are in s.blk.
    Bits any = 0;
    const uint8_t* seg = sf.seg ? sf.seg + o * sf.outer + x0 / 64 : nullptr;
    for (int64_t t = 0; t < n_line; ++t) {
      if (seg && !seg[t * sf.line]) {
        s.nonzero[static_cast<size_t>(t)] = 0;
        continue;
      }
      const float* src = sq + base + t * line_stride;
      uint32_t acc = 0;
      for (int64_t b = 0; b < nb; ++b) {
        uint32_t u;
        std::memcpy(&u, src + b, sizeof u);
        acc |= u;
      }
      Bits bits = 0;
      if (acc != 0) {
        float* dst = s.blk.data() + t * kB;
        for (int64_t b = 0; b < nb; ++b) {
          dst[b] = src[b];
          bits |= static_cast<Bits>(src[b] != 0.0f) << b;
        }
      }
      s.nonzero[static_cast<size_t>(t)] = bits;
      any |= bits;
    }
    if (!any) continue;  // every voxel is a site: nothing changes (and finish maps 0 to 0)
    bool changed = false;
    for (int64_t b = 0; b < nb; ++b) {
      if (!((any >> b) & 1u)) continue;
      float* f = s.blk.data() + b;
      const int64_t col = base + b;
      for (int64_t a = 0; a < n_line;) {
        if (!((s.nonzero[static_cast<size_t>(a)] >> b) & 1u)) {
          ++a;
          continue;
        }
        int64_t e = a + 1;
        while (e < n_line && ((s.nonzero[static_cast<size_t>(e)] >> b) & 1u)) ++e;
        if (envelope_run(f, kB, a, e, n_line, w, outside_site, s.env, s.fout.data(), s.site.data())) {
          if constexpr (with_feat) {
            for (int64_t x = a; x < e; ++x) {
              const int64_t sx = s.site[static_cast<size_t>(x - a)];
              // A site of value 0 (its bit clear; its row was not copied into s.blk) is its own feature.
              s.iout[static_cast<size_t>(x - a)] =
                  (sx < 0 || sx >= n_line)                         ? OUT
                  : !((s.nonzero[static_cast<size_t>(sx)] >> b) & 1u) ? static_cast<Idx>(col + sx * line_stride)
                                                                    : feat[col + sx * line_stride];
            }
            for (int64_t x = a; x < e; ++x) feat[col + x * line_stride] = s.iout[static_cast<size_t>(x - a)];
          }
          for (int64_t x = a; x < e; ++x) f[x * kB] = s.fout[static_cast<size_t>(x - a)];
          changed = true;
        }
        a = e;
      }
    }
    if constexpr (!Fin::active) {
      if (!changed) continue;
    }
    for (int64_t t = 0; t < n_line; ++t) {
      if (!s.nonzero[static_cast<size_t>(t)]) continue;
      float* row = s.blk.data() + t * kB;
      if constexpr (Fin::active)
        for (int64_t b = 0; b < nb; ++b) row[b] = finish(row[b]);
      std::memcpy(sq + base + t * line_stride, row, static_cast<size_t>(nb) * sizeof(float));
    }
  }
}

// Pass y or z over the whole buffer: n_outer groups of columns, parallel over the groups.
template <class Index, int64_t kB = 16, class Fin = NoFinish>
void edt_column_pass(float* sq, Index* feat, int64_t nx, int64_t n_outer, int64_t n_line, int64_t outer_stride,
                     int64_t line_stride, double w, bool outside_site, int threads, const Interrupter& interrupter,
                     const Fin& finish = {}, const SegmentFlags& sf = {}) {
  parallel_for(0, n_outer, threads, [&](int64_t o0, int64_t o1) {
    ColumnScratch<Index, kB> s(n_line);
    for (int64_t o = o0; o < o1; ++o) {
      interrupter.check();
      edt_column_group<Index, kB>(sq, feat, nx, o, n_line, outer_stride, line_stride, w, outside_site, s, finish, sf);
    }
  });
}

// Squared distance (isotropic: voxel units; anisotropic: physical units) from every voxel to the
// nearest site, plus optionally the site's index. is_site(i) decides sites inside the array;
// `outside_site` whether the ring outside the array consists of sites. Passes x and y run plane by
// plane (the y pass reads a plane the x pass has just written, still in cache); the z pass gathers
// blocks of 64 columns (256 contiguous bytes per plane) and applies `finish` to its output. Returns
// whether `finish` was applied (false when there is no z pass: nz == 1 and no outside sites).
template <class Index, class IsSite, class Fin = NoFinish>
bool squared_edt(const Grid& grid, IsSite is_site, bool outside_site, bool isotropic, int threads,
                 const Interrupter& interrupter, float* sq, Index* feat, const Fin& finish = {}) {
  const int64_t nx = grid.dims[0], ny = grid.dims[1], nz = grid.dims[2], plane = nx * ny;
  if (nx * ny * nz == 0) return true;
  const double wx = isotropic ? 1.0 : grid.spacing[0] * grid.spacing[0];
  const double wy = isotropic ? 1.0 : grid.spacing[1] * grid.spacing[1];
  const double wz = isotropic ? 1.0 : grid.spacing[2] * grid.spacing[2];

  // ---- passes x and y, plane by plane. Distances only: the x pass flags the 64-voxel row segments
  // that hold a non-site (1 byte per 64 voxels), and the y and z passes read no other rows.
  interrupter.check(0.0);
  const bool pass_y = ny > 1 || outside_site;
  constexpr bool with_feat = !std::is_same_v<Index, NoIndex>;
  const int64_t nxs = (nx + 63) / 64;
  std::vector<uint8_t> seg(with_feat ? 0 : static_cast<size_t>(nxs * ny * nz));
  uint8_t* const segp = with_feat ? nullptr : seg.data();
  parallel_for(0, nz, threads, [&](int64_t z0, int64_t z1) {
    std::vector<int64_t> left(static_cast<size_t>(nx));
    ColumnScratch<Index, 16> s(pass_y ? ny : 0);
    for (int64_t z = z0; z < z1; ++z) {
      interrupter.check();
      edt_plane_x<Index>(grid.dims, is_site, outside_site, wx, z, left, sq, feat, segp ? segp + z * nxs * ny : nullptr);
      if (pass_y)
        edt_column_group<Index, 16>(sq, feat, nx, z, ny, plane, nx, wy, outside_site, s, NoFinish{},
                                    SegmentFlags{segp, nxs * ny, nxs});
    }
  });
  interrupter.check(2.0 / 3.0);

  // ---- pass z: blocks of 64 adjacent columns gathered into contiguous line buffers.
  if (nz > 1 || outside_site) {
    edt_column_pass<Index, 64>(sq, feat, nx, ny, nz, nx, plane, wz, outside_site, threads, interrupter, finish,
                               SegmentFlags{segp, nxs, nxs * ny});
    interrupter.check(1.0);
    return true;
  }
  interrupter.check(1.0);
  return false;
}

bool is_isotropic(const Grid& g) { return g.spacing[0] == g.spacing[1] && g.spacing[1] == g.spacing[2]; }

// The per-value conversion of finish_distances for a grid.
Finish make_finish(const Grid& g, bool isotropic, bool squared) {
  Finish f;
  f.squared = squared;
  f.isotropic = isotropic;
  f.s2 = isotropic ? static_cast<float>(g.spacing[0] * g.spacing[0]) : 1.0f;
  f.s1 = isotropic ? static_cast<float>(g.spacing[0]) : 1.0f;
  return f;
}

// Converts squared distances in place to the requested output (physical units, optionally rooted).
void finish_distances(VolumeF32& v, bool isotropic, bool squared, int threads) {
  const float s2 = isotropic ? static_cast<float>(v.spacing()[0] * v.spacing()[0]) : 1.0f;
  const float s1 = isotropic ? static_cast<float>(v.spacing()[0]) : 1.0f;
  float* d = v.data();
  parallel_for(0, v.size(), threads, [&](int64_t a, int64_t b) {
    if (squared) {
      if (s2 != 1.0f)
        for (int64_t i = a; i < b; ++i) d[i] *= s2;
    } else if (isotropic) {
      for (int64_t i = a; i < b; ++i) d[i] = std::sqrt(d[i]) * s1;  // sqrt of an exact integer, then scale
    } else {
      for (int64_t i = a; i < b; ++i) d[i] = std::sqrt(d[i]);
    }
  }, int64_t{1} << 20);
}

}  // namespace

// ============================================================================================ public

ChamferWeights chamfer_weights_from_spacing(const Vec3& spacing, double scale) {
  for (int a = 0; a < 3; ++a)
    if (!(spacing[a] > 0)) throw InputError("spacing: chamfer weights need spacing > 0 on every axis");
  if (!(scale >= 1.0)) throw InputError("spacing_scale: expected >= 1");
  const double smin = std::min({spacing[0], spacing[1], spacing[2]});
  auto wt = [&](double dx, double dy, double dz) {
    const double len = std::sqrt(dx * dx * spacing[0] * spacing[0] + dy * dy * spacing[1] * spacing[1] +
                                 dz * dz * spacing[2] * spacing[2]);
    const double r = std::round(scale * len / smin);
    if (r > 1e9) throw InputError("spacing: anisotropy too large for integer chamfer weights");
    return static_cast<uint32_t>(std::max(1.0, r));
  };
  ChamferWeights w;
  w.face_x = wt(1, 0, 0);
  w.face_y = wt(0, 1, 0);
  w.face_z = wt(0, 0, 1);
  w.edge_xy = wt(1, 1, 0);
  w.edge_xz = wt(1, 0, 1);
  w.edge_yz = wt(0, 1, 1);
  w.vertex = wt(1, 1, 1);
  return w;
}

uint64_t chamfer_upper_bound(const Grid& grid, const ChamferOptions& options) {
  return upper_bound(grid, effective_weights(grid, options), options.border_is_object);
}

int chamfer_output_bits(const Grid& grid, const ChamferOptions& options) {
  const uint64_t b = chamfer_upper_bound(grid, options);
  if (b < std::numeric_limits<uint16_t>::max()) return 16;
  if (b < std::numeric_limits<uint32_t>::max() - 1) return 32;
  throw InputError("weights: chamfer distances on this grid could exceed uint32; use smaller weights");
}

template <class T>
Volume<T> chamfer_as(const VolumeU8& mask, const ChamferOptions& options) {
  const Weights64 w = effective_weights(mask.grid(), options);
  const uint64_t bound = upper_bound(mask.grid(), w, options.border_is_object);
  if (bound >= std::numeric_limits<T>::max())
    throw InputError(std::string("chamfer: distances up to ") + std::to_string(bound) + " do not fit into " +
                     VoxelTraits<T>::name);
  return chamfer_impl<T>(mask, w, options);
}
template Volume<uint16_t> chamfer_as<uint16_t>(const VolumeU8&, const ChamferOptions&);
template Volume<uint32_t> chamfer_as<uint32_t>(const VolumeU8&, const ChamferOptions&);

std::optional<VolumeU8> chamfer_u8(const VolumeU8& mask, const ChamferOptions& options) {
  const Weights64 w = effective_weights(mask.grid(), options);
  VolumeU8 d = chamfer_impl<uint8_t>(mask, w, options);
  // 255 marks a saturated value (a distance >= 255, or unreached): then the uint8 values would tie
  // voxels whose distances differ.
  if (d.size() > 0 && std::memchr(d.data(), 255, static_cast<size_t>(d.size())) != nullptr) return std::nullopt;
  return d;
}

DataPtr chamfer(const VolumeU8& mask, const ChamferOptions& options) {
  if (options.narrow) {
    chamfer_output_bits(mask.grid(), options);  // the same InputError as without `narrow`
    if (auto d = chamfer_u8(mask, options)) return std::make_shared<VolumeU8>(std::move(*d));
  }
  if (chamfer_output_bits(mask.grid(), options) == 16)
    return std::make_shared<VolumeU16>(chamfer_as<uint16_t>(mask, options));
  return std::make_shared<VolumeU32>(chamfer_as<uint32_t>(mask, options));
}

namespace {
bool small_grid(const Grid& g) {
  return static_cast<uint64_t>(g.voxel_count()) < uint64_t{std::numeric_limits<uint32_t>::max()};
}
template <class T>
ChamferNearest chamfer_nearest_t(const VolumeU8& mask, const Weights64& w, const ChamferOptions& o) {
  ChamferNearest r;
  auto dist = std::make_shared<Volume<T>>(new_output<T>(mask.grid()));
  if (small_grid(mask.grid())) {
    auto near = std::make_shared<VolumeU32>(new_output<uint32_t>(mask.grid()));
    chamfer_nearest_impl<T, uint32_t>(mask, w, o, *dist, *near);
    r.nearest = near;
  } else {
    auto near = std::make_shared<VolumeU64>(new_output<uint64_t>(mask.grid()));
    chamfer_nearest_impl<T, uint64_t>(mask, w, o, *dist, *near);
    r.nearest = near;
  }
  r.distance = dist;
  return r;
}
}  // namespace

ChamferNearest chamfer_nearest(const VolumeU8& mask, const ChamferOptions& options) {
  const Weights64 w = effective_weights(mask.grid(), options);
  if (chamfer_output_bits(mask.grid(), options) == 16) return chamfer_nearest_t<uint16_t>(mask, w, options);
  return chamfer_nearest_t<uint32_t>(mask, w, options);
}

VolumeF32 euclidean(const VolumeU8& mask, const EuclideanOptions& options) {
  VolumeF32 out = new_output<float>(mask.grid());
  const uint8_t* m = mask.data();
  const bool iso = is_isotropic(mask.grid());
  // The z pass converts its output on the fly (no separate pass over the 4 bytes per voxel).
  if (!squared_edt<NoIndex>(mask.grid(), [m](int64_t i) { return m[i] == 0; }, !options.border_is_object, iso,
                            options.threads, options.interrupter, out.data(), nullptr,
                            make_finish(mask.grid(), iso, options.squared)))
    finish_distances(out, iso, options.squared, options.threads);
  return out;
}

template <class Index>
Volume<Index> feature_transform_as(const VolumeU8& mask, const DistanceOptions& options) {
  if (sizeof(Index) == 4 && !small_grid(mask.grid()))
    throw InputError("mask: grid has too many voxels for uint32 feature indices; use uint64");
  Volume<Index> feat = new_output<Index>(mask.grid());
  VolumeF32 sq = new_output<float>(mask.grid());
  const uint8_t* m = mask.data();
  squared_edt<Index>(mask.grid(), [m](int64_t i) { return m[i] == 0; }, !options.border_is_object,
                     is_isotropic(mask.grid()), options.threads, options.interrupter, sq.data(), feat.data());
  return feat;
}
template Volume<uint32_t> feature_transform_as<uint32_t>(const VolumeU8&, const DistanceOptions&);
template Volume<uint64_t> feature_transform_as<uint64_t>(const VolumeU8&, const DistanceOptions&);

DataPtr feature_transform(const VolumeU8& mask, const DistanceOptions& options) {
  if (small_grid(mask.grid())) return std::make_shared<VolumeU32>(feature_transform_as<uint32_t>(mask, options));
  return std::make_shared<VolumeU64>(feature_transform_as<uint64_t>(mask, options));
}

VolumeF32 seeded(const VolumeU8& seeds, const SeededOptions& options) {
  VolumeF32 out = new_output<float>(seeds.grid());
  const uint8_t* s = seeds.data();
  const bool iso = is_isotropic(seeds.grid());
  if (!squared_edt<NoIndex>(seeds.grid(), [s](int64_t i) { return s[i] != 0; }, false, iso, options.threads,
                            options.interrupter, out.data(), nullptr, make_finish(seeds.grid(), iso, options.squared)))
    finish_distances(out, iso, options.squared, options.threads);
  return out;
}

// ============================================================================ block-wise chamfer (ch. 5.1)
namespace {

struct Step {
  int dx, dy, dz;
  uint64_t w;
};

// The 13 steps of the forward mask (plane z-1, row y-1, voxel x-1) with their weights; the backward
// mask is their mirror.
std::array<Step, 13> forward_steps(const Weights64& w) {
  auto weight = [&](int dx, int dy, int dz) -> uint64_t {
    const int n = std::abs(dx) + std::abs(dy) + std::abs(dz);
    if (n == 1) return dx ? w.fx : dy ? w.fy : w.fz;
    if (n == 2) return dz == 0 ? w.exy : dy == 0 ? w.exz : w.eyz;
    return w.v;
  };
  std::array<Step, 13> s{};
  int k = 0;
  for (int dy = -1; dy <= 1; ++dy)
    for (int dx = -1; dx <= 1; ++dx) s[static_cast<size_t>(k++)] = {dx, dy, -1, weight(dx, dy, -1)};
  for (int dx = -1; dx <= 1; ++dx) s[static_cast<size_t>(k++)] = {dx, -1, 0, weight(dx, -1, 0)};
  s[static_cast<size_t>(k)] = {-1, 0, 0, w.fx};
  return s;
}

// One chamfer raster scan (forward: z, y, x increasing over the forward mask; backward: the mirror)
// of a box of the grid: d(p) = min(d(p), d(n) + w) over the mask's neighbours n of every object
// voxel p. Neighbours outside the grid count as `B` (the ring outside the array); neighbours outside
// the box but inside the grid are left to the block order of Algorithm 4. Values stay <= INF.
template <class T>
void scan_box(VolumeView<const uint8_t> m, VolumeView<T> d, const Dims& grid, const std::array<Step, 13>& steps,
              bool forward, Acc<T> B) {
  using A = Acc<T>;
  const A INF = std::numeric_limits<T>::max();
  const int64_t nx = d.dims[0], ny = d.dims[1], nz = d.dims[2];
  const int sign = forward ? 1 : -1;
  std::array<int64_t, 13> offset{};
  for (size_t k = 0; k < steps.size(); ++k)
    offset[k] = sign * (steps[k].dx * d.strides[0] + steps[k].dy * d.strides[1] + steps[k].dz * d.strides[2]);
  for (int64_t zi = 0; zi < nz; ++zi) {
    const int64_t z = forward ? zi : nz - 1 - zi;
    for (int64_t yi = 0; yi < ny; ++yi) {
      const int64_t y = forward ? yi : ny - 1 - yi;
      for (int64_t xi = 0; xi < nx; ++xi) {
        const int64_t x = forward ? xi : nx - 1 - xi;
        if (!m(x, y, z)) continue;  // background stays 0
        T* p = &d(x, y, z);
        A c = *p;
        if (x > 0 && y > 0 && z > 0 && x < nx - 1 && y < ny - 1 && z < nz - 1) {
          for (size_t k = 0; k < steps.size(); ++k) c = std::min(c, static_cast<A>(p[offset[k]]) + static_cast<A>(steps[k].w));
        } else {
          for (const Step& s : steps) {
            const int64_t lx = x + sign * s.dx, ly = y + sign * s.dy, lz = z + sign * s.dz;
            const int64_t gx = d.offset[0] + lx, gy = d.offset[1] + ly, gz = d.offset[2] + lz;
            if (gx < 0 || gy < 0 || gz < 0 || gx >= grid[0] || gy >= grid[1] || gz >= grid[2])
              c = std::min(c, B + static_cast<A>(s.w));
            else if (lx >= 0 && ly >= 0 && lz >= 0 && lx < nx && ly < ny && lz < nz)
              c = std::min(c, static_cast<A>(d(lx, ly, lz)) + static_cast<A>(s.w));
          }
        }
        *p = static_cast<T>(std::min(c, INF));
      }
    }
  }
}

// The box [begin, begin + size) of an integer mask (in memory or on disk) as 0/1 bytes.
VolumeU8 read_mask_box(const DataObject& mask, const Dims& begin, const Dims& size) {
  return read_mask_block(mask, begin, size, "input 'mask'");
}

// Block order of Algorithm 4 along one axis: 0, 1, ..., n-1, n-2, ..., 0 (up) or its mirror.
std::vector<int64_t> there_and_back(int64_t n, bool up) {
  std::vector<int64_t> s;
  for (int64_t i = 0; i < n; ++i) s.push_back(up ? i : n - 1 - i);
  for (int64_t i = n - 2; i >= 0; --i) s.push_back(up ? i : n - 1 - i);
  return s;
}

template <class T>
void chamfer_blocks_t(const DataObject& mask, const ChunkedVolume& out, const Weights64& w, const ChamferOptions& o,
                      const Dims& block) {
  const Grid& g = out.grid();
  const BlockLayout layout(g.dims, block, 1);
  const Dims n = layout.count();
  const int64_t total = layout.total() + 2 * n[2] * (2 * n[0] - 1) * (2 * n[1] - 1);
  const T INF = std::numeric_limits<T>::max();
  const Acc<T> B = o.border_is_object ? Acc<T>(INF) : Acc<T>(0);
  const auto steps = forward_steps(w);
  int64_t done = 0;
  report_blocks(o.interrupter, "chamfer", 0, total);
  // Resumable per block (--resume): the start and the two sweeps are passes of the journal, a
  // block's index is its place in the pass's fixed order, and the state between blocks is the
  // distance volume alone (replayed).
  // Start: 0 on background, INF on object.
  ResumablePass start;
  int64_t index = 0;
  for (int64_t bz = 0; bz < n[2]; ++bz)
    for (int64_t by = 0; by < n[1]; ++by)
      for (int64_t bx = 0; bx < n[0]; ++bx, ++index) {
        if (start.kept(index)) {
          ++done;
          continue;
        }
        const Block b = layout.at(bx, by, bz);
        const VolumeU8 m = read_mask_box(mask, b.begin, b.size);
        Volume<T> d = Volume<T>::uninitialized(m.grid());
        for (int64_t i = 0; i < m.size(); ++i) d[i] = m[i] ? INF : T(0);
        out.write(d, b.begin);
        start.commit(index);
        report_blocks(o.interrupter, "chamfer", ++done, total);
      }
  // Eight block-wise scans: each block with a one-voxel overlap (its halo), visited there and back
  // along x within each row of blocks, along y within each layer, layers in scan order.
  auto visit = [&](ResumablePass& sweep, int64_t& visit_index, int64_t bx, int64_t by, int64_t bz, bool forward) {
    const int64_t at = visit_index++;
    if (sweep.kept(at)) {
      ++done;
      return;
    }
    const Block b = layout.at(bx, by, bz);
    const VolumeU8 m = read_mask_box(mask, b.outer_begin, b.outer_size);
    Volume<T> d = out.read<T>(b.outer_begin, b.outer_size);
    VolumeView<const uint8_t> mv = m.view();
    VolumeView<T> dv = d.view();
    mv.offset = dv.offset = b.outer_begin;
    scan_box<T>(mv, dv, g.dims, steps, forward, B);
    out.write(d, b.outer_begin);
    sweep.commit(at);
    report_blocks(o.interrupter, "chamfer", ++done, total);
  };
  {
    ResumablePass sweep;
    int64_t at = 0;
    for (int64_t bz = 0; bz < n[2]; ++bz)
      for (int64_t by : there_and_back(n[1], true))
        for (int64_t bx : there_and_back(n[0], true)) visit(sweep, at, bx, by, bz, true);
  }
  {
    ResumablePass sweep;
    int64_t at = 0;
    for (int64_t bz = n[2] - 1; bz >= 0; --bz)
      for (int64_t by : there_and_back(n[1], false))
        for (int64_t bx : there_and_back(n[0], false)) visit(sweep, at, bx, by, bz, false);
  }
}

}  // namespace

const char* chamfer_output_type(const Grid& grid, const ChamferOptions& options) {
  return chamfer_output_bits(grid, options) == 16 ? type_ids::volume_u16 : type_ids::volume_u32;
}

void chamfer_blocks(const DataObject& mask, const ChunkedVolume& out, const ChamferOptions& options, const Dims& block) {
  const Grid& g = any_volume_grid(mask, "input 'mask'");
  if (out.grid().dims != g.dims) throw Error("chamfer_blocks: the output's grid differs from the mask's");
  const Weights64 w = effective_weights(g, options);
  if (out.type_id() != chamfer_output_type(g, options))
    throw Error("chamfer_blocks: the output must be " + std::string(chamfer_output_type(g, options)));
  if (out.type_id() == type_ids::volume_u16) chamfer_blocks_t<uint16_t>(mask, out, w, options, block);
  else chamfer_blocks_t<uint32_t>(mask, out, w, options, block);
}

// ========================================================================== block-wise Euclidean DT
void euclidean_blocks(const DataObject& mask, const ChunkedVolume& out, const EuclideanOptions& o, const Dims& cross) {
  const Grid& g = any_volume_grid(mask, "input 'mask'");
  if (out.grid().dims != g.dims || out.type_id() != type_ids::volume_f32)
    throw Error("euclidean_blocks: the output must be float32 on the mask's grid");
  const int64_t nx = g.dims[0], ny = g.dims[1], nz = g.dims[2];
  if (g.voxel_count() == 0) return;
  const bool iso = is_isotropic(g);
  const bool outside = !o.border_is_object;
  const double wx = iso ? 1.0 : g.spacing[0] * g.spacing[0];
  const double wy = iso ? 1.0 : g.spacing[1] * g.spacing[1];
  const double wz = iso ? 1.0 : g.spacing[2] * g.spacing[2];
  const Interrupter inner;  // progress and cancellation between slabs, below
  // Slabs of whole lines along the pass's axis, `cross` voxels across it. When a slab of the
  // allowed size (cross[0]·cross[1] lines of the longest axis) holds whole xy-planes, the x and y
  // passes run together on slabs of whole planes (the planes hold whole x-lines and y-lines): one
  // write of the float volume and one read less than three separate passes.
  const int64_t longest = std::max({nx, ny, nz});
  const int64_t allowed = cross[0] * cross[1] * longest;
  const bool fused = allowed >= nx * ny;
  const BlockLayout sx({nx, ny, nz}, fused ? Dims{nx, ny, std::clamp<int64_t>(allowed / (nx * ny), 1, nz)}
                                           : Dims{nx, cross[1], cross[2]});
  const BlockLayout sy({nx, ny, nz}, {cross[0], ny, cross[2]});
  const BlockLayout sz({nx, ny, nz}, {cross[0], cross[1], nz});
  const int64_t total = sx.total() + (fused ? 0 : sy.total()) + sz.total();
  int64_t done = 0;
  auto each = [&](const BlockLayout& l, auto&& f) {
    if (distributing()) {  // skelflow-mpi: the slabs of a pass are independent; each rank does its own
      for_each_owned_block(l, Interrupter(), "euclidean", [&](const Block& b) {
        f(b);
        report_blocks(o.interrupter, "euclidean", ++done, total);
      });
      return;
    }
    // Resumable per slab (--resume): each pass is a pass of the journal; a slab reads and writes
    // only its own lines, the previous pass's values in them replayed.
    ResumablePass pass;
    const Dims c = l.count();
    int64_t index = 0;
    for (int64_t bz = 0; bz < c[2]; ++bz)
      for (int64_t by = 0; by < c[1]; ++by)
        for (int64_t bx = 0; bx < c[0]; ++bx, ++index) {
          if (pass.kept(index)) {
            ++done;
            continue;
          }
          f(l.at(bx, by, bz));
          pass.commit(index);
          report_blocks(o.interrupter, "euclidean", ++done, total);
        }
  };
  report_blocks(o.interrupter, "euclidean", 0, total);
  each(sx, [&](const Block& b) {
    const VolumeU8 m = read_mask_box(mask, b.begin, b.size);
    VolumeF32 f = VolumeF32::uninitialized(m.grid());
    const uint8_t* mp = m.data();
    edt_pass_x<NoIndex>(b.size, [mp](int64_t i) { return mp[i] == 0; }, outside, wx, o.threads, inner, f.data(), nullptr);
    if (fused && (ny > 1 || outside))
      edt_column_pass<NoIndex>(f.data(), nullptr, b.size[0], b.size[2], ny, b.size[0] * ny, b.size[0], wy, outside,
                               o.threads, inner);
    out.write(f, b.begin);
  });
  if (!fused && (ny > 1 || outside))  // (fused: the y pass ran with the x pass)
    each(sy, [&](const Block& b) {
      VolumeF32 f = out.read<float>(b.begin, b.size);
      edt_column_pass<NoIndex>(f.data(), nullptr, b.size[0], b.size[2], ny, b.size[0] * ny, b.size[0], wy, outside,
                               o.threads, inner);
      out.write(f, b.begin);
    });
  else if (!fused)
    done += sy.total();
  each(sz, [&](const Block& b) {
    VolumeF32 f = out.read<float>(b.begin, b.size);
    if (nz > 1 || outside)
      edt_column_pass<NoIndex>(f.data(), nullptr, b.size[0], b.size[1], nz, b.size[0], b.size[0] * b.size[1], wz,
                               outside, o.threads, inner);
    finish_distances(f, iso, o.squared, o.threads);
    out.write(f, b.begin);
  });
}

Dims euclidean_cross_section(uint64_t budget, const Dims& grid_dims) {
  const int64_t longest = std::max<int64_t>({grid_dims[0], grid_dims[1], grid_dims[2], 1});
  // One slab of whole lines: 5 bytes per voxel (float32 distances, the mask), a quarter of the budget.
  const double voxels = static_cast<double>(budget) / 4.0 / 5.0;
  const auto side = static_cast<int64_t>(std::sqrt(voxels / static_cast<double>(longest)));
  const int64_t s = std::max<int64_t>(1, side);
  return {s, s, s};
}

}  // namespace skel::distance
