#pragma once
// Shapes, a chamfer (3, 4, 5) distance and small brute-force helpers shared by the thinning tests.
#include <algorithm>
#include <cmath>
#include <cstdint>
#include <random>
#include <vector>

#include "skel/volume.hpp"

namespace skel::test {

// Chamfer (3, 4, 5) distance to the background (outside the array = background), by Dijkstra-like
// relaxation until stable: plain two raster scans, repeated until nothing changes.
inline VolumeU32 chamfer345(const VolumeU8& m) {
  const int64_t nx = m.nx(), ny = m.ny(), nz = m.nz();
  VolumeU32 d(m.dims(), 0);
  const uint32_t inf = 1u << 30;
  for (int64_t i = 0; i < m.size(); ++i) d[i] = m[i] ? inf : 0;
  auto get = [&](int64_t x, int64_t y, int64_t z) -> uint32_t {
    if (x < 0 || y < 0 || z < 0 || x >= nx || y >= ny || z >= nz) return 0;
    return d(x, y, z);
  };
  bool changed = true;
  while (changed) {
    changed = false;
    for (int pass = 0; pass < 2; ++pass) {
      for (int64_t zz = 0; zz < nz; ++zz)
        for (int64_t yy = 0; yy < ny; ++yy)
          for (int64_t xx = 0; xx < nx; ++xx) {
            const int64_t x = pass ? nx - 1 - xx : xx, y = pass ? ny - 1 - yy : yy, z = pass ? nz - 1 - zz : zz;
            if (!m(x, y, z)) continue;
            uint32_t best = d(x, y, z);
            for (int dz = -1; dz <= 1; ++dz)
              for (int dy = -1; dy <= 1; ++dy)
                for (int dx = -1; dx <= 1; ++dx) {
                  const int k = std::abs(dx) + std::abs(dy) + std::abs(dz);
                  if (k == 0) continue;
                  best = std::min(best, get(x + dx, y + dy, z + dz) + static_cast<uint32_t>(k + 2));
                }
            if (best < d(x, y, z)) {
              d(x, y, z) = best;
              changed = true;
            }
          }
    }
  }
  return d;
}

// Smooth random blobs: box-filtered uniform noise above a threshold.
inline VolumeU8 random_blobs(int64_t n, uint32_t seed, double threshold, int radius = 2) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<double> u(0.0, 1.0);
  std::vector<double> noise(static_cast<size_t>(n * n * n));
  for (auto& v : noise) v = u(rng);
  VolumeU8 m(Dims{n, n, n}, 0);
  for (int64_t z = 0; z < n; ++z)
    for (int64_t y = 0; y < n; ++y)
      for (int64_t x = 0; x < n; ++x) {
        double s = 0;
        int c = 0;
        for (int dz = -radius; dz <= radius; ++dz)
          for (int dy = -radius; dy <= radius; ++dy)
            for (int dx = -radius; dx <= radius; ++dx) {
              const int64_t a = (x + dx + n) % n, b = (y + dy + n) % n, e = (z + dz + n) % n;
              s += noise[static_cast<size_t>(a + n * (b + n * e))];
              ++c;
            }
        // keep a one-voxel background margin so the outside is well defined
        const bool inner = x > 0 && y > 0 && z > 0 && x < n - 1 && y < n - 1 && z < n - 1;
        m(x, y, z) = inner && s / c > threshold ? 1 : 0;
      }
  return m;
}

// Solid cylinder with axis from (x0, cy, cz) to (x1, cy, cz), radius r (voxel centres).
inline void add_cylinder_x(VolumeU8& m, int64_t x0, int64_t x1, double cy, double cz, double r) {
  for (int64_t z = 0; z < m.nz(); ++z)
    for (int64_t y = 0; y < m.ny(); ++y)
      for (int64_t x = x0; x <= x1; ++x)
        if ((y - cy) * (y - cy) + (z - cz) * (z - cz) <= r * r) m(x, y, z) = 1;
}

// Solid capsule (cylinder with round ends) between two points.
inline void add_capsule(VolumeU8& m, const std::array<double, 3>& a, const std::array<double, 3>& b, double r) {
  const double ab[3] = {b[0] - a[0], b[1] - a[1], b[2] - a[2]};
  const double len2 = ab[0] * ab[0] + ab[1] * ab[1] + ab[2] * ab[2];
  for (int64_t z = 0; z < m.nz(); ++z)
    for (int64_t y = 0; y < m.ny(); ++y)
      for (int64_t x = 0; x < m.nx(); ++x) {
        const double p[3] = {x - a[0], y - a[1], z - a[2]};
        double t = len2 > 0 ? (p[0] * ab[0] + p[1] * ab[1] + p[2] * ab[2]) / len2 : 0.0;
        t = std::clamp(t, 0.0, 1.0);
        const double q[3] = {p[0] - t * ab[0], p[1] - t * ab[1], p[2] - t * ab[2]};
        if (q[0] * q[0] + q[1] * q[1] + q[2] * q[2] <= r * r) m(x, y, z) = 1;
      }
}

inline void add_ball(VolumeU8& m, double cx, double cy, double cz, double r, uint8_t value = 1) {
  for (int64_t z = 0; z < m.nz(); ++z)
    for (int64_t y = 0; y < m.ny(); ++y)
      for (int64_t x = 0; x < m.nx(); ++x)
        if ((x - cx) * (x - cx) + (y - cy) * (y - cy) + (z - cz) * (z - cz) <= r * r) m(x, y, z) = value;
}

// Torus around the z axis through (cx, cy, cz): major radius R, minor radius r.
inline VolumeU8 torus(int64_t n, double R, double r) {
  VolumeU8 m(Dims{n, n, n}, 0);
  const double c = (n - 1) / 2.0;
  for (int64_t z = 0; z < n; ++z)
    for (int64_t y = 0; y < n; ++y)
      for (int64_t x = 0; x < n; ++x) {
        const double dx = x - c, dy = y - c, dz = z - c;
        const double q = std::sqrt(dx * dx + dy * dy) - R;
        if (q * q + dz * dz <= r * r) m(x, y, z) = 1;
      }
  return m;
}

}  // namespace skel::test

namespace skel::test {

// Bing's house with two rooms (thesis fig. 2.23 is of this kind): a closed box split by a floor; the
// upper room is entered through a tube from the bottom that crosses the lower room, the lower room
// through a tube from the top that crosses the upper room; a wall joins each tube to the outer wall.
// Contractible (one component, no cavity, no tunnel), yet thinning in the grid point model gets
// stuck on it. Built on a 9^3 plan of w^3 blocks with a one-voxel background margin.
inline VolumeU8 bing_house(int w) {
  const int S = 9;
  std::vector<uint8_t> c(S * S * S, 0);
  auto C = [&](int x, int y, int z) -> uint8_t& { return c[static_cast<size_t>(x + S * (y + S * z))]; };
  for (int z = 0; z < S; ++z)
    for (int y = 0; y < S; ++y)
      for (int x = 0; x < S; ++x)
        if (x == 0 || y == 0 || z == 0 || x == S - 1 || y == S - 1 || z == S - 1 || z == 4) C(x, y, z) = 1;
  for (int z = 1; z <= 3; ++z)
    for (int y = 2; y <= 4; ++y)
      for (int x = 2; x <= 4; ++x)
        if (!(x == 3 && y == 3)) C(x, y, z) = 1;  // tube to the upper room
  for (int z = 5; z <= 7; ++z)
    for (int y = 4; y <= 6; ++y)
      for (int x = 4; x <= 6; ++x)
        if (!(x == 5 && y == 5)) C(x, y, z) = 1;  // tube to the lower room
  C(3, 3, 0) = 0;
  C(3, 3, 4) = 0;
  C(5, 5, 8) = 0;
  C(5, 5, 4) = 0;
  for (int z = 1; z <= 3; ++z)
    for (int x = 5; x <= 7; ++x) C(x, 3, z) = 1;  // support walls
  for (int z = 5; z <= 7; ++z)
    for (int x = 1; x <= 3; ++x) C(x, 5, z) = 1;
  const int64_t n = S * w + 2;
  VolumeU8 m(Dims{n, n, n}, 0);
  for (int64_t z = 0; z < S * w; ++z)
    for (int64_t y = 0; y < S * w; ++y)
      for (int64_t x = 0; x < S * w; ++x) m(x + 1, y + 1, z + 1) = C(static_cast<int>(x / w), static_cast<int>(y / w), static_cast<int>(z / w));
  return m;
}

// Rods with one loop and four free branches (clean), and the same with small surface bumps that
// keep the topology (noisy), as in thesis fig. 4.1.
inline VolumeU8 rods_clean() {
  VolumeU8 m(Dims{64, 64, 64}, 0);
  const double r = 3.2;
  add_capsule(m, {20, 20, 20}, {44, 20, 20}, r);
  add_capsule(m, {44, 20, 20}, {44, 44, 20}, r);
  add_capsule(m, {44, 44, 20}, {20, 44, 20}, r);
  add_capsule(m, {20, 44, 20}, {20, 20, 20}, r);
  add_capsule(m, {20, 20, 20}, {6, 6, 40}, r);
  add_capsule(m, {44, 20, 20}, {58, 6, 40}, r);
  add_capsule(m, {44, 44, 20}, {58, 58, 50}, r);
  add_capsule(m, {32, 20, 20}, {32, 32, 56}, r);
  return m;
}

}  // namespace skel::test
