// Global topology numbers (components, cavities, Euler characteristic, tunnels) of a binary volume.
#include "analysis/topology.hpp"

#include <array>
#include <atomic>
#include <memory>
#include <mutex>
#include <vector>

#include "segmentation/segmentation.hpp"
#include "skel/parallel.hpp"

namespace skel::analysis {
namespace {

// Euler characteristic contribution of the grid vertex at the centre of a 2x2x2 window: the vertex
// itself plus the three edges, three faces and the cube "owned" by it (those extending towards +x,
// +y, +z), each counted if any incident voxel is object. Window bit i = x + 2y + 4z.
std::array<int8_t, 256> make_euler_lut() {
  std::array<int8_t, 256> lut{};
  for (int m = 0; m < 256; ++m) {
    auto v = [m](int x, int y, int z) { return (m >> (x + 2 * y + 4 * z)) & 1; };
    const int vertex = m != 0 ? 1 : 0;
    // The edge from the vertex towards +x touches the four voxels with window x = 1, and so on.
    const int ex = (v(1, 0, 0) | v(1, 1, 0) | v(1, 0, 1) | v(1, 1, 1));
    const int ey = (v(0, 1, 0) | v(1, 1, 0) | v(0, 1, 1) | v(1, 1, 1));
    const int ez = (v(0, 0, 1) | v(1, 0, 1) | v(0, 1, 1) | v(1, 1, 1));
    const int fxy = v(1, 1, 0) | v(1, 1, 1);
    const int fxz = v(1, 0, 1) | v(1, 1, 1);
    const int fyz = v(0, 1, 1) | v(1, 1, 1);
    const int cube = v(1, 1, 1);
    lut[static_cast<size_t>(m)] = static_cast<int8_t>(vertex - (ex + ey + ez) + (fxy + fxz + fyz) - cube);
  }
  return lut;
}

}  // namespace

TopologyNumbers topology(const VolumeU8& mask, const TopologyOptions& options) {
  TopologyNumbers r;
  const int64_t nx = mask.nx(), ny = mask.ny(), nz = mask.nz();
  if (mask.size() == 0) return r;
  // Padded copy: 0 background, 1 object; the one-voxel shell is background.
  const int64_t px = nx + 2, py = ny + 2, pz = nz + 2;
  const int64_t sy = px, sz = px * py;
  std::vector<uint8_t> a(static_cast<size_t>(px * py * pz), 0);
  const uint8_t* src = mask.data();
  std::vector<int64_t> counts(static_cast<size_t>(nz), 0);
  parallel_for(0, nz, options.threads, [&](int64_t z0, int64_t z1) {
    for (int64_t z = z0; z < z1; ++z) {
      int64_t c = 0;
      for (int64_t y = 0; y < ny; ++y) {
        const uint8_t* s = src + nx * (y + ny * z);
        uint8_t* d = a.data() + (z + 1) * sz + (y + 1) * sy + 1;
        for (int64_t x = 0; x < nx; ++x) {
          d[x] = s[x] != 0 ? 1 : 0;
          c += d[x];
        }
      }
      counts[static_cast<size_t>(z)] = c;
    }
  });
  for (int64_t c : counts) r.object_voxels += c;
  options.interrupter.check(0.1);

  // Euler characteristic over all 2x2x2 windows of the padded array (window origin = lower corner).
  static const std::array<int8_t, 256> lut = make_euler_lut();
  std::vector<int64_t> eul(static_cast<size_t>(pz - 1), 0);
  parallel_for(0, pz - 1, options.threads, [&](int64_t z0, int64_t z1) {
    for (int64_t z = z0; z < z1; ++z) {
      int64_t e = 0;
      for (int64_t y = 0; y + 1 < py; ++y) {
        const uint8_t* p = a.data() + z * sz + y * sy;
        for (int64_t x = 0; x + 1 < px; ++x) {
          const uint8_t* q = p + x;
          const unsigned m = q[0] | (q[1] << 1) | (q[sy] << 2) | (q[sy + 1] << 3) | (q[sz] << 4) |
                             (q[sz + 1] << 5) | (q[sz + sy] << 6) | (q[sz + sy + 1] << 7);
          e += lut[m];
        }
      }
      eul[static_cast<size_t>(z)] = e;
    }
  });
  for (int64_t e : eul) r.euler += e;
  options.interrupter.check(0.3);

  // Components (26) and cavities (bounded 6-components of the background) by union-find over
  // x-runs of the mask: memory ~ 24 bytes per run, no flood-fill stack.
  std::vector<uint8_t>().swap(a);
  const auto objects = segmentation::count_components(mask, 26, false, options.threads, {});
  options.interrupter.check(0.6);
  const auto background = segmentation::count_components(mask, 6, true, options.threads, {});
  r.components = objects.components;
  r.cavities = background.components - background.touching_border;
  r.tunnels = r.components + r.cavities - r.euler;
  options.interrupter.check(1.0);
  return r;
}

}  // namespace skel::analysis
