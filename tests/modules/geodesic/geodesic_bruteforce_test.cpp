// Geodesic boundary distance against an independent brute force that shares no code with the module
// (no bitmaps, ranks, buckets or searches of geodesic.cpp): plain arrays over the array plus its
// one-voxel outside ring, the documented nearest-point rule applied literally ring by ring, and a
// plain breadth-first search over the layer for every considered pair.
#include <gtest/gtest.h>

#include <array>
#include <cmath>
#include <deque>
#include <limits>
#include <random>
#include <vector>

#include "geodesic/geodesic.hpp"
#include "geodesic/geodesic_phases.hpp"

using namespace skel;
using namespace skel::geodesic;

namespace {

// The array with a one-voxel ring around it: index of (x, y, z) for x in [-1, nx], ...
struct Brute {
  int64_t nx, ny, nz, ex, ey, ez;
  Vec3 sp;
  std::vector<uint8_t> obj, layer;
  std::vector<int> ring;                      // object voxels: ring number (1 = touches L), else 0
  std::vector<std::array<int64_t, 3>> base;   // object voxels: coordinates of b(p)
  explicit Brute(const VolumeU8& m)
      : nx(m.nx()), ny(m.ny()), nz(m.nz()), ex(nx + 2), ey(ny + 2), ez(nz + 2), sp(m.spacing()) {
    const size_t n = static_cast<size_t>(ex * ey * ez);
    obj.assign(n, 0);
    layer.assign(n, 0);
    ring.assign(n, 0);
    base.assign(n, {0, 0, 0});
    for (int64_t z = 0; z < nz; ++z)
      for (int64_t y = 0; y < ny; ++y)
        for (int64_t x = 0; x < nx; ++x) obj[idx(x, y, z)] = m(x, y, z) ? 1 : 0;
    // L: background (inside or on the ring) with an object voxel among its 26 neighbours.
    for_all([&](int64_t x, int64_t y, int64_t z) {
      if (obj[idx(x, y, z)]) return;
      for_26(x, y, z, [&](int64_t a, int64_t b, int64_t c) {
        if (inside(a, b, c) && obj[idx(a, b, c)]) layer[idx(x, y, z)] = 1;
      });
    });
    // Rings and b(p) by the documented rule: ring r + 1 = unreached object voxels 26-adjacent to ring
    // r (ring 0 = L); each takes, among its L neighbours and its object neighbours of earlier rings,
    // the candidate nearest in physical distance, ties to the lower L position (z, then y, then x).
    for (int r = 1;; ++r) {
      std::vector<std::array<int64_t, 3>> now;
      for_all([&](int64_t x, int64_t y, int64_t z) {
        if (!obj[idx(x, y, z)] || ring[idx(x, y, z)]) return;
        bool adj = false;
        for_26(x, y, z, [&](int64_t a, int64_t b, int64_t c) {
          if (!inside(a, b, c)) return;
          const size_t j = idx(a, b, c);
          if (r == 1 ? layer[j] != 0 : (obj[j] && ring[j] == r - 1)) adj = true;
        });
        if (adj) now.push_back({x, y, z});
      });
      if (now.empty()) break;
      std::vector<std::array<int64_t, 3>> pick;
      for (const auto& p : now) {
        std::array<int64_t, 3> best{};
        double bd = std::numeric_limits<double>::infinity();
        for_26(p[0], p[1], p[2], [&](int64_t a, int64_t b, int64_t c) {
          if (!inside(a, b, c)) return;
          const size_t j = idx(a, b, c);
          std::array<int64_t, 3> cand;
          if (layer[j]) cand = {a, b, c};
          else if (obj[j] && ring[j] > 0 && ring[j] < r) cand = base[j];
          else return;
          const double dx = static_cast<double>(p[0] - cand[0]) * sp[0], dy = static_cast<double>(p[1] - cand[1]) * sp[1],
                       dz = static_cast<double>(p[2] - cand[2]) * sp[2];
          const double d = dx * dx + dy * dy + dz * dz;
          const auto key = [](const std::array<int64_t, 3>& q) { return std::array<int64_t, 3>{q[2], q[1], q[0]}; };
          if (d < bd || (d == bd && key(cand) < key(best))) {
            bd = d;
            best = cand;
          }
        });
        pick.push_back(best);
      }
      for (size_t i = 0; i < now.size(); ++i) {
        ring[idx(now[i][0], now[i][1], now[i][2])] = r;
        base[idx(now[i][0], now[i][1], now[i][2])] = pick[i];
      }
    }
  }
  [[nodiscard]] size_t idx(int64_t x, int64_t y, int64_t z) const {
    return static_cast<size_t>((x + 1) + ex * ((y + 1) + ey * (z + 1)));
  }
  [[nodiscard]] bool inside(int64_t x, int64_t y, int64_t z) const {
    return x >= -1 && y >= -1 && z >= -1 && x <= nx && y <= ny && z <= nz;
  }
  template <class F>
  void for_all(F&& f) const {
    for (int64_t z = -1; z <= nz; ++z)
      for (int64_t y = -1; y <= ny; ++y)
        for (int64_t x = -1; x <= nx; ++x) f(x, y, z);
  }
  template <class F>
  static void for_26(int64_t x, int64_t y, int64_t z, F&& f) {
    for (int64_t c = -1; c <= 1; ++c)
      for (int64_t b = -1; b <= 1; ++b)
        for (int64_t a = -1; a <= 1; ++a)
          if (a || b || c) f(x + a, y + b, z + c);
  }
  // 6-path lengths in L from `s` to every voxel (-1: no path).
  [[nodiscard]] std::vector<int64_t> bfs(const std::array<int64_t, 3>& s) const {
    std::vector<int64_t> d(obj.size(), -1);
    std::deque<std::array<int64_t, 3>> q{s};
    d[idx(s[0], s[1], s[2])] = 0;
    while (!q.empty()) {
      const auto p = q.front();
      q.pop_front();
      const int64_t dp = d[idx(p[0], p[1], p[2])];
      const int64_t nb[6][3] = {{-1, 0, 0}, {1, 0, 0}, {0, -1, 0}, {0, 1, 0}, {0, 0, -1}, {0, 0, 1}};
      for (const auto& o : nb) {
        const int64_t a = p[0] + o[0], b = p[1] + o[1], c = p[2] + o[2];
        if (!inside(a, b, c) || !layer[idx(a, b, c)] || d[idx(a, b, c)] >= 0) continue;
        d[idx(a, b, c)] = dp + 1;
        q.push_back({a, b, c});
      }
    }
    return d;
  }
  // The importance by the definition (geodesic.hpp).
  [[nodiscard]] VolumeF32 importance(const VolumeU8& m, Mode mode, int64_t t) const {
    VolumeF32 out(m.grid(), 0.0f);
    const float inf = std::numeric_limits<float>::infinity();
    for (int64_t z = 0; z < nz; ++z)
      for (int64_t y = 0; y < ny; ++y)
        for (int64_t x = 0; x < nx; ++x) {
          if (!obj[idx(x, y, z)]) continue;
          const auto d = bfs(base[idx(x, y, z)]);
          float v = 0.0f;
          auto consider = [&](const std::array<int64_t, 3>& c) {
            const int64_t g = d[idx(c[0], c[1], c[2])];
            float gv = g < 0 ? inf : static_cast<float>(g);
            if (mode == Mode::Threshold) gv = std::min(gv, static_cast<float>(t));
            v = std::max(v, gv);
          };
          const int64_t up[3][3] = {{1, 0, 0}, {0, 1, 0}, {0, 0, 1}};
          for (const auto& o : up) {
            const int64_t lx = x - o[0], ly = y - o[1], lz = z - o[2];  // lower: always
            consider(obj[idx(lx, ly, lz)] ? base[idx(lx, ly, lz)] : std::array<int64_t, 3>{lx, ly, lz});
            const int64_t ux = x + o[0], uy = y + o[1], uz = z + o[2];  // upper: where background
            if (!obj[idx(ux, uy, uz)]) consider({ux, uy, uz});
          }
          out(x, y, z) = v;
        }
    return out;
  }
};

VolumeU8 blobs(Dims d, uint64_t seed, double fill, int smooth) {
  std::mt19937_64 rng(seed);
  std::uniform_real_distribution<double> u(0, 1);
  VolumeU8 v(d, 0);
  for (auto& x : v) x = u(rng) < fill ? 1 : 0;
  for (int s = 0; s < smooth; ++s) {
    VolumeU8 w(d, 0);
    for (int64_t z = 0; z < d[2]; ++z)
      for (int64_t y = 0; y < d[1]; ++y)
        for (int64_t x = 0; x < d[0]; ++x) {
          int c = v(x, y, z) + v.at_or(x - 1, y, z, 0) + v.at_or(x + 1, y, z, 0) + v.at_or(x, y - 1, z, 0) +
                  v.at_or(x, y + 1, z, 0) + v.at_or(x, y, z - 1, 0) + v.at_or(x, y, z + 1, 0);
          w(x, y, z) = c >= 4 ? 1 : 0;
        }
    v = std::move(w);
  }
  return v;
}

// Mask coordinates of the nearest background point b(p) that `P` holds for the object voxel (x, y, z).
std::array<int64_t, 3> base_coords(const detail::Prepared& P, int64_t x, int64_t y, int64_t z) {
  const int64_t bp = P.base_pos(P.dom.pos(x + 2, y + 2, z + 2));
  const int64_t bz = bp / P.dom.plane, rem = bp % P.dom.plane;
  return {rem % P.dom.BX - 2, rem / P.dom.BX - 2, bz - 2};
}

}  // namespace

// b(p) of the module (kept as offsets, detail::Prepared::base_pos) equals the brute force for every
// object voxel, with isotropic and anisotropic spacing; in ring 1 it is the exact nearest L voxel,
// and nowhere is it nearer than the exact nearest L voxel.
TEST(GeodesicBruteForce, NearestBackgroundPointEqualsTheDocumentedRule) {
  int64_t compared = 0, ring1 = 0, deeper = 0;
  for (uint64_t seed = 1; seed <= 10; ++seed) {
    const Dims d{11 + static_cast<int64_t>(seed % 5), 12, 9 + static_cast<int64_t>(seed % 4)};
    VolumeU8 m = blobs(d, seed, 0.55 + 0.03 * static_cast<double>(seed % 4), 2);
    if (seed % 3 == 0) m.set_spacing({1.0, 1.5, 0.7});
    const Brute br(m);
    detail::Prepared P(m.dims());
    detail::prepare(m, P, 1 + static_cast<int>(seed % 2), {}, false);
    for (int64_t z = 0; z < d[2]; ++z)
      for (int64_t y = 0; y < d[1]; ++y)
        for (int64_t x = 0; x < d[0]; ++x) {
          if (!m(x, y, z)) continue;
          const auto& want = br.base[br.idx(x, y, z)];
          ASSERT_EQ(base_coords(P, x, y, z), want) << "seed " << seed << " at " << x << "," << y << "," << z;
          ++compared;
          // Against the exact nearest L voxel (minimum over all of L).
          double exact = std::numeric_limits<double>::infinity();
          br.for_all([&](int64_t a, int64_t b, int64_t c) {
            if (!br.layer[br.idx(a, b, c)]) return;
            const double dx = static_cast<double>(x - a) * br.sp[0], dy = static_cast<double>(y - b) * br.sp[1],
                         dz = static_cast<double>(z - c) * br.sp[2];
            exact = std::min(exact, dx * dx + dy * dy + dz * dz);
          });
          const double dx = static_cast<double>(x - want[0]) * br.sp[0], dy = static_cast<double>(y - want[1]) * br.sp[1],
                       dz = static_cast<double>(z - want[2]) * br.sp[2];
          const double got_d = dx * dx + dy * dy + dz * dz;
          EXPECT_GE(got_d, exact);
          if (br.ring[br.idx(x, y, z)] == 1 && m.spacing() == Vec3{1.0, 1.0, 1.0}) {
            EXPECT_EQ(got_d, exact) << "ring 1 takes the nearest L neighbour";
            ++ring1;
          } else {
            ++deeper;
          }
        }
  }
  EXPECT_GT(compared, 2000);
  EXPECT_GT(ring1, 500);
  EXPECT_GT(deeper, 200);  // the rule is exercised beyond the first ring
}

// The first ring is found 64 voxels at a time (dilations across the words of a row, the L bits at
// each offset extracted across word boundaries): rows of several words, both spacings.
TEST(GeodesicBruteForce, NearestBackgroundPointInRowsOfSeveralWords) {
  for (uint64_t seed = 21; seed <= 24; ++seed) {
    const Dims d{131 + static_cast<int64_t>(seed % 3), 7, 6};
    VolumeU8 m = blobs(d, seed, 0.6, 2);
    if (seed % 2 == 0) m.set_spacing({0.8, 1.0, 1.7});
    const Brute br(m);
    for (int threads : {1, 2}) {
      detail::Prepared P(m.dims());
      detail::prepare(m, P, threads, {}, false);
      for (int64_t z = 0; z < d[2]; ++z)
        for (int64_t y = 0; y < d[1]; ++y)
          for (int64_t x = 0; x < d[0]; ++x) {
            if (!m(x, y, z)) continue;
            ASSERT_EQ(base_coords(P, x, y, z), br.base[br.idx(x, y, z)])
                << "seed " << seed << ", threads " << threads << " at " << x << "," << y << "," << z;
          }
    }
  }
}

// Offsets beyond +-127 (objects more than 254 voxels thick all round) go to the side table; such an
// object is too slow for a unit test, so one offset is moved there by hand: the accessors must give
// the same position and L-id as the offset did.
TEST(GeodesicBruteForce, NearestPointThroughTheSideTable) {
  VolumeU8 m(Dims{40, 9, 9}, 1);
  detail::Prepared P(m.dims());
  detail::prepare(m, P, 1, {}, true);
  EXPECT_TRUE(P.bfar.empty());
  int64_t moved = 0;
  for (int64_t x = 0; x < 40; x += 3) {
    const int64_t pos = P.dom.pos(2 + x, 2 + 4, 2 + 4);
    const uint64_t oid = P.obj.rank(pos);
    const int64_t before = P.base_pos(pos);
    EXPECT_EQ(before, P.lpos(P.b[oid]));
    P.boff[oid] = detail::BaseOffset{detail::kFar, 0, 0};
    P.bfar.emplace_back(static_cast<uint32_t>(oid), before);
    EXPECT_EQ(P.base_pos(pos), before);
    EXPECT_EQ(P.base_of(pos), P.b[oid]);
    ++moved;
  }
  // Every other voxel still answers from its offset.
  for (int64_t pos = 0; pos < P.dom.bits(); ++pos)
    if (P.obj.test(pos)) {
      ASSERT_EQ(P.base_of(pos), P.b[P.obj.rank(pos)]);
    }
  EXPECT_EQ(static_cast<int64_t>(P.bfar.size()), moved);
}

// The importance equals the definition, computed by brute force, in both modes, for thresholds below,
// near and above the largest distances, with 1 and 2 threads.
TEST(GeodesicBruteForce, ImportanceEqualsTheDefinition) {
  int64_t high = 0;
  for (uint64_t seed = 1; seed <= 8; ++seed) {
    const Dims d{12 + static_cast<int64_t>(seed % 3), 11, 10 + static_cast<int64_t>(seed % 2)};
    VolumeU8 m = blobs(d, 100 + seed, 0.5 + 0.03 * static_cast<double>(seed % 3), 1 + static_cast<int>(seed % 2));
    const Brute br(m);
    for (Mode mode : {Mode::Threshold, Mode::Full}) {
      for (int64_t t : {3, 8, 30}) {
        const VolumeF32 want = br.importance(m, mode, t);
        for (int th : {1, 2}) {
          Options o;
          o.mode = mode;
          o.threshold = t;
          o.threads = th;
          const Result r = boundary_distance(m, o);
          ASSERT_TRUE(r.importance == want) << "seed " << seed << " t " << t << " full " << (mode == Mode::Full)
                                            << " threads " << th;
          for (int64_t i = 0; i < m.size(); ++i) {
            ASSERT_EQ(r.surface_skeleton[i], want[i] >= static_cast<float>(t) ? 1 : 0);
            high += want[i] >= 8.0f && mode == Mode::Threshold;
          }
        }
        if (mode == Mode::Full) break;
      }
    }
  }
  EXPECT_GT(high, 50);  // long paths (around blobs) are part of the comparison
}
