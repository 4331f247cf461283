// Simple-voxel test (Characterization 2, bit-parallel) with a lazily memoised 2^26 table.
#include "thinning/local_topology.hpp"

#include "thinning/cube_word.hpp"

#include <array>
#include <atomic>
#include <memory>
#include <mutex>
#include <vector>

#include "segmentation/segmentation.hpp"
#include "skel/parallel.hpp"

namespace skel::thinning {
namespace {

struct LocalTables {
  std::array<uint32_t, 26> adj26{};  // neighbour bits 26-adjacent to bit k (within the 26 positions)
  std::array<uint32_t, 26> adj6{};   // neighbour bits 6-adjacent to bit k
  uint32_t n18 = 0;                  // bits of the 18-neighbourhood (centre excluded)
  uint32_t n6 = 0;                   // bits of the six face neighbours
};

LocalTables make_local_tables() {
  LocalTables t;
  auto offset = [](int k, int& dx, int& dy, int& dz) {
    const int c = k < 13 ? k : k + 1;
    dx = c % 3 - 1;
    dy = (c / 3) % 3 - 1;
    dz = c / 9 - 1;
  };
  for (int a = 0; a < 26; ++a) {
    int ax, ay, az;
    offset(a, ax, ay, az);
    const int la = std::abs(ax) + std::abs(ay) + std::abs(az);
    if (la <= 2) t.n18 |= 1u << a;
    if (la == 1) t.n6 |= 1u << a;
    for (int b = 0; b < 26; ++b) {
      if (a == b) continue;
      int bx, by, bz;
      offset(b, bx, by, bz);
      const int dx = std::abs(ax - bx), dy = std::abs(ay - by), dz = std::abs(az - bz);
      if (dx <= 1 && dy <= 1 && dz <= 1) t.adj26[a] |= 1u << b;
      if (dx + dy + dz == 1) t.adj6[a] |= 1u << b;
    }
  }
  return t;
}

const LocalTables& local_tables() {
  static const LocalTables t = make_local_tables();
  return t;
}

// Grows `seed` to its component inside `set` using the adjacency masks `adj`.
inline uint32_t grow_component(uint32_t seed, uint32_t set, const std::array<uint32_t, 26>& adj) {
  uint32_t comp = seed, frontier = seed;
  while (frontier != 0) {
    uint32_t next = 0;
    for (uint32_t f = frontier; f != 0; f &= f - 1) next |= adj[static_cast<unsigned>(__builtin_ctz(f))];
    next &= set & ~comp;
    comp |= next;
    frontier = next;
  }
  return comp;
}

// Memo table: 2 bits per configuration (known, value), 32 configurations per word.
constexpr uint64_t kConfigs = uint64_t{1} << 26;
std::atomic<uint64_t>* simple_table() {
  static std::unique_ptr<std::atomic<uint64_t>[]> table;
  static std::once_flag once;
  std::call_once(once, [] {
    table.reset(new std::atomic<uint64_t>[kConfigs / 32]);
    for (uint64_t i = 0; i < kConfigs / 32; ++i) table[i].store(0, std::memory_order_relaxed);
  });
  return table.get();
}

}  // namespace

int object_components26(uint32_t nb) {
  const LocalTables& t = local_tables();
  nb &= (1u << 26) - 1;
  int count = 0;
  while (nb != 0) {
    nb &= ~grow_component(nb & (~nb + 1), nb, t.adj26);
    ++count;
  }
  return count;
}

int background_components6(uint32_t nb) {
  const LocalTables& t = local_tables();
  const uint32_t bg = ~nb & t.n18;
  uint32_t seeds = bg & t.n6;
  int count = 0;
  while (seeds != 0) {
    const uint32_t comp = grow_component(seeds & (~seeds + 1), bg, t.adj6);
    seeds &= ~comp;
    ++count;
  }
  return count;
}

using cube::dilate26;
using cube::dilate6;
using cube::kCentre;
using cube::kCube;
// Face neighbours of the centre and the 18-neighbourhood (centre excluded) in cube bits.
constexpr uint32_t kCubeN6 = (1u << 4) | (1u << 10) | (1u << 12) | (1u << 14) | (1u << 16) | (1u << 22);
constexpr uint32_t kCubeCorners = (1u << 0) | (1u << 2) | (1u << 6) | (1u << 8) | (1u << 18) | (1u << 20) |
                                  (1u << 24) | (1u << 26);
constexpr uint32_t kCubeN18 = kCube & ~kCubeCorners & ~kCentre;

bool is_simple_direct(uint32_t nb) {
  nb &= (1u << 26) - 1;
  const uint32_t obj = (nb & 0x1FFFu) | ((nb >> 13) << 14);  // 26-bit word -> cube bits, centre clear
  const uint32_t bg = ~obj & kCubeN18;
  const uint32_t bg6 = bg & kCubeN6;
  if (bg6 == 0 || obj == 0) return false;  // no background 6-neighbour / isolated voxel
  // The background 6-neighbours must lie in one 6-component of the background in N18.
  uint32_t c = bg6 & (~bg6 + 1);
  while (true) {
    const uint32_t g = dilate6(c) & bg;
    if (g == c) break;
    c = g;
  }
  if ((c & kCubeN6) != bg6) return false;
  // The object voxels must form one 26-component.
  c = obj & (~obj + 1);
  while (true) {
    const uint32_t g = dilate26(c) & obj;
    if (g == c) break;
    c = g;
  }
  return c == obj;
}

bool is_simple(uint32_t nb) {
  nb &= (1u << 26) - 1;
  static std::atomic<uint64_t>* table = simple_table();
  std::atomic<uint64_t>& word = table[nb >> 5];
  const unsigned shift = (nb & 31u) * 2u;
  const uint64_t w = word.load(std::memory_order_relaxed);
  if ((w >> shift) & 2u) return ((w >> shift) & 1u) != 0;
  const bool s = is_simple_direct(nb);
  word.fetch_or((uint64_t{2} | uint64_t{s}) << shift, std::memory_order_relaxed);
  return s;
}

uint32_t neighbourhood_at(const VolumeU8& mask, int64_t x, int64_t y, int64_t z) {
  uint32_t nb = 0;
  for (int dz = -1; dz <= 1; ++dz)
    for (int dy = -1; dy <= 1; ++dy)
      for (int dx = -1; dx <= 1; ++dx) {
        if (dx == 0 && dy == 0 && dz == 0) continue;
        if (mask.at_or(x + dx, y + dy, z + dz, 0) != 0) nb |= 1u << neighbour_bit(dx, dy, dz);
      }
  return nb;
}

}  // namespace skel::thinning
