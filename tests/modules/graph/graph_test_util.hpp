#pragma once
// Small helpers for graph tests: digital lines, rings, and a brute-force (26, 6) topology reference.
#include <array>
#include <cmath>
#include <cstdint>
#include <cstdlib>
#include <deque>
#include <vector>

#include "skel/volume.hpp"

namespace skel::test {

// 26-connected digital segment from a to b (inclusive).
inline void draw_line(VolumeU8& v, std::array<int64_t, 3> a, std::array<int64_t, 3> b) {
  int64_t steps = 0;
  for (int k = 0; k < 3; ++k) steps = std::max<int64_t>(steps, std::llabs(b[k] - a[k]));
  for (int64_t s = 0; s <= steps; ++s) {
    std::array<int64_t, 3> p{};
    for (int k = 0; k < 3; ++k)
      p[k] = a[k] + static_cast<int64_t>(std::lround(steps == 0 ? 0.0 : double(b[k] - a[k]) * s / steps));
    v(p[0], p[1], p[2]) = 1;
  }
}

// 6-connected square ring in the plane spanned by axes u and w through `corner`, side `n` voxels.
inline void draw_square_ring(VolumeU8& v, std::array<int64_t, 3> corner, int u, int w, int64_t n) {
  for (int64_t i = 0; i < n; ++i)
    for (int64_t j = 0; j < n; ++j) {
      if (i != 0 && j != 0 && i != n - 1 && j != n - 1) continue;
      auto p = corner;
      p[u] += i;
      p[w] += j;
      v(p[0], p[1], p[2]) = 1;
    }
}

struct Topology {
  int64_t components = 0, cavities = 0, tunnels = 0, euler = 0;
};

// b0 (26-components), b2 (6-components of the background minus the outside), χ of the union of
// closed voxel cubes, b1 = b0 + b2 - χ.
inline Topology topology_26_6(const VolumeU8& v) {
  const int64_t nx = v.nx(), ny = v.ny(), nz = v.nz();
  // Euler characteristic on the doubled grid.
  const int64_t dx = 2 * nx + 1, dy = 2 * ny + 1, dz = 2 * nz + 1;
  std::vector<uint8_t> cell(static_cast<size_t>(dx * dy * dz), 0);
  for (int64_t z = 0; z < nz; ++z)
    for (int64_t y = 0; y < ny; ++y)
      for (int64_t x = 0; x < nx; ++x) {
        if (!v(x, y, z)) continue;
        for (int c = -1; c <= 1; ++c)
          for (int b = -1; b <= 1; ++b)
            for (int a = -1; a <= 1; ++a)
              cell[(2 * x + 1 + a) + dx * ((2 * y + 1 + b) + dy * (2 * z + 1 + c))] = 1;
      }
  Topology t;
  for (int64_t z = 0; z < dz; ++z)
    for (int64_t y = 0; y < dy; ++y)
      for (int64_t x = 0; x < dx; ++x) {
        if (!cell[x + dx * (y + dy * z)]) continue;
        const int dim = int(x % 2) + int(y % 2) + int(z % 2);
        t.euler += (dim % 2 == 0) ? 1 : -1;
      }
  // Components: 26 for the object, 6 for the background padded by one voxel.
  auto count = [&](bool object, bool six) {
    const int64_t px = nx + 2, py = ny + 2, pz = nz + 2;
    std::vector<uint8_t> seen(static_cast<size_t>(px * py * pz), 0);
    auto in = [&](int64_t x, int64_t y, int64_t z) {
      const bool inside = x >= 1 && y >= 1 && z >= 1 && x <= nx && y <= ny && z <= nz;
      const bool fg = inside && v(x - 1, y - 1, z - 1) != 0;
      return fg == object;
    };
    int64_t comps = 0;
    std::deque<std::array<int64_t, 3>> q;
    for (int64_t z = 0; z < pz; ++z)
      for (int64_t y = 0; y < py; ++y)
        for (int64_t x = 0; x < px; ++x) {
          const int64_t i = x + px * (y + py * z);
          if (seen[i] || !in(x, y, z)) continue;
          ++comps;
          seen[i] = 1;
          q.push_back({x, y, z});
          while (!q.empty()) {
            auto p = q.front();
            q.pop_front();
            for (int c = -1; c <= 1; ++c)
              for (int b = -1; b <= 1; ++b)
                for (int a = -1; a <= 1; ++a) {
                  const int m = std::abs(a) + std::abs(b) + std::abs(c);
                  if (m == 0 || (six && m > 1)) continue;
                  const int64_t X = p[0] + a, Y = p[1] + b, Z = p[2] + c;
                  if (X < 0 || Y < 0 || Z < 0 || X >= px || Y >= py || Z >= pz) continue;
                  const int64_t j = X + px * (Y + py * Z);
                  if (seen[j] || !in(X, Y, Z)) continue;
                  seen[j] = 1;
                  q.push_back({X, Y, Z});
                }
          }
        }
    return comps;
  };
  t.components = count(true, false);
  t.cavities = count(false, true) - 1;
  t.tunnels = t.components + t.cavities - t.euler;
  return t;
}

}  // namespace skel::test
