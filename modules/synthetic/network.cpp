#include "synthetic/network.hpp"

#include <algorithm>
#include <atomic>
#include <cmath>
#include <limits>
#include <vector>

#include "segmentation/segmentation.hpp"
#include "skel/error.hpp"
#include "skel/parallel.hpp"

namespace skel::synthetic {

namespace {

uint64_t splitmix(uint64_t x) {
  x += 0x9e3779b97f4a7c15ull;
  x = (x ^ (x >> 30)) * 0xbf58476d1ce4e5b9ull;
  x = (x ^ (x >> 27)) * 0x94d049bb133111ebull;
  return x ^ (x >> 31);
}

using V = std::array<double, 3>;

// Elements drawn on the grid (voxel coordinates).
struct Capsule {  // segment a–b with radius r (a == b: a ball)
  V a, b;
  double r;
  double lo[3], hi[3];  // bounding box
};
struct Plate {  // slab perpendicular to axis w: |w − (c + su·u + sv·v)| <= h, with round holes
  int w, u, v;  // axis indices
  double c, su, sv, h;
  int64_t id;   // for the hole hashes
  double hole_p, hole_r, cell;
};

Capsule capsule(V a, V b, double r) {
  Capsule c{a, b, r, {}, {}};
  for (int k = 0; k < 3; ++k) {
    c.lo[k] = std::min(a[k], b[k]) - r;
    c.hi[k] = std::max(a[k], b[k]) + r;
  }
  return c;
}

// Sets image = 1 inside every capsule. Parallel over fixed z-chunks (each voxel written by one
// chunk only), so the result is independent of the thread count.
void draw_capsules(VolumeF32& img, const std::vector<Capsule>& caps, int threads, const Interrupter& intr) {
  const int64_t nx = img.nx(), ny = img.ny(), nz = img.nz();
  const int64_t chunks = std::max<int64_t>(1, (nz + 7) / 8);
  std::atomic<int64_t> done{0};
  parallel_chunks(0, nz, chunks, threads, [&](int64_t, int64_t z0, int64_t z1) {
    for (const Capsule& c : caps) {
      const int64_t za = std::max<int64_t>(z0, static_cast<int64_t>(std::ceil(c.lo[2])));
      const int64_t zb = std::min<int64_t>(z1 - 1, static_cast<int64_t>(std::floor(c.hi[2])));
      if (za > zb) continue;
      const int64_t ya = std::max<int64_t>(0, static_cast<int64_t>(std::ceil(c.lo[1])));
      const int64_t yb = std::min<int64_t>(ny - 1, static_cast<int64_t>(std::floor(c.hi[1])));
      const int64_t xa = std::max<int64_t>(0, static_cast<int64_t>(std::ceil(c.lo[0])));
      const int64_t xb = std::min<int64_t>(nx - 1, static_cast<int64_t>(std::floor(c.hi[0])));
      if (ya > yb || xa > xb) continue;
      const V ab{c.b[0] - c.a[0], c.b[1] - c.a[1], c.b[2] - c.a[2]};
      const double l2 = ab[0] * ab[0] + ab[1] * ab[1] + ab[2] * ab[2];
      const double inv = l2 > 0 ? 1.0 / l2 : 0.0, r2 = c.r * c.r;
      for (int64_t z = za; z <= zb; ++z)
        for (int64_t y = ya; y <= yb; ++y) {
          float* row = img.data() + img.index(0, y, z);
          const double py = static_cast<double>(y) - c.a[1], pz = static_cast<double>(z) - c.a[2];
          for (int64_t x = xa; x <= xb; ++x) {
            const double px = static_cast<double>(x) - c.a[0];
            const double t = std::clamp((px * ab[0] + py * ab[1] + pz * ab[2]) * inv, 0.0, 1.0);
            const double dx = px - t * ab[0], dy = py - t * ab[1], dz = pz - t * ab[2];
            if (dx * dx + dy * dy + dz * dz <= r2) row[x] = 1.0f;
          }
        }
    }
    intr.check(0.3 * static_cast<double>(++done) / static_cast<double>(chunks));
  });
}

// Sets image = 1 inside every plate (outside its holes). Parallel over y-chunks.
void draw_plates(VolumeF32& img, const std::vector<Plate>& plates, uint64_t seed, int threads) {
  const Dims& d = img.dims();
  parallel_chunks(0, d[1], std::max<int64_t>(1, (d[1] + 7) / 8), threads, [&](int64_t, int64_t y0, int64_t y1) {
    int64_t p[3];
    for (const Plate& pl : plates) {
      // Loop over the voxels (u, v) of the plate's own plane that fall in this y-chunk.
      const int64_t u_lo = pl.u == 1 ? y0 : 0, u_hi = pl.u == 1 ? y1 : d[pl.u];
      const int64_t v_lo = pl.v == 1 ? y0 : 0, v_hi = pl.v == 1 ? y1 : d[pl.v];
      for (int64_t v = v_lo; v < v_hi; ++v)
        for (int64_t u = u_lo; u < u_hi; ++u) {
          const double U = static_cast<double>(u), Vv = static_cast<double>(v);
          const double wc = pl.c + pl.su * U + pl.sv * Vv;
          const int64_t wa = std::max<int64_t>(0, static_cast<int64_t>(std::ceil(wc - pl.h)));
          const int64_t wb = std::min<int64_t>(d[pl.w] - 1, static_cast<int64_t>(std::floor(wc + pl.h)));
          if (wa > wb) continue;
          // Hole of radius hole_r in the hashed fraction hole_p of the (u, v) cells.
          const int64_t cu = static_cast<int64_t>(std::floor(U / pl.cell)), cv = static_cast<int64_t>(std::floor(Vv / pl.cell));
          if (hash_uniform(seed, pl.id * 4 + 1, cu, cv) < pl.hole_p) {
            const double hu = (static_cast<double>(cu) + 0.3 + 0.4 * hash_uniform(seed, pl.id * 4 + 2, cu, cv)) * pl.cell;
            const double hv = (static_cast<double>(cv) + 0.3 + 0.4 * hash_uniform(seed, pl.id * 4 + 3, cu, cv)) * pl.cell;
            if ((U - hu) * (U - hu) + (Vv - hv) * (Vv - hv) < pl.hole_r * pl.hole_r) continue;
          }
          p[pl.u] = u;
          p[pl.v] = v;
          for (int64_t w = wa; w <= wb; ++w) {
            p[pl.w] = w;
            img(p[0], p[1], p[2]) = 1.0f;
          }
        }
    }
  });
}

}  // namespace

double hash_uniform(uint64_t seed, int64_t a, int64_t b, int64_t c) {
  uint64_t h = splitmix(seed ^ 0x51ed2701f3a5c9b1ull);
  h = splitmix(h ^ static_cast<uint64_t>(a));
  h = splitmix(h ^ static_cast<uint64_t>(b) * 0x9e3779b97f4a7c15ull);
  h = splitmix(h ^ static_cast<uint64_t>(c) * 0xc2b2ae3d27d4eb4full);
  return static_cast<double>(h >> 11) * 0x1.0p-53;
}

void add_two_frequency_noise(VolumeF32& image, uint64_t seed, double amplitude, int threads) {
  if (amplitude <= 0) return;
  const int64_t nx = image.nx(), ny = image.ny(), nz = image.nz();
  // Low frequency: smooth value noise on a lattice of 16 voxels (values hashed per lattice point,
  // smoothstep-interpolated).
  const double cell = 16.0;
  const int64_t gx = nx / 16 + 2, gy = ny / 16 + 2, gz = nz / 16 + 2;
  std::vector<float> g(static_cast<size_t>(gx * gy * gz));
  for (int64_t k = 0; k < gz; ++k)
    for (int64_t j = 0; j < gy; ++j)
      for (int64_t i = 0; i < gx; ++i)
        g[static_cast<size_t>(i + gx * (j + gy * k))] = static_cast<float>(2.0 * hash_uniform(seed ^ 0xabcdefull, i, j, k) - 1.0);
  const float low = static_cast<float>(0.35 * amplitude), high = static_cast<float>(0.25 * amplitude);
  const uint64_t hseed = splitmix(seed ^ 0x12345ull);
  parallel_for(0, nz, threads, [&](int64_t z0, int64_t z1) {
    auto s = [](double t) { return t * t * (3 - 2 * t); };
    for (int64_t z = z0; z < z1; ++z) {
      const double fz = static_cast<double>(z) / cell;
      const int64_t iz = static_cast<int64_t>(fz);
      const double tz = s(fz - static_cast<double>(iz));
      for (int64_t y = 0; y < ny; ++y) {
        const double fy = static_cast<double>(y) / cell;
        const int64_t iy = static_cast<int64_t>(fy);
        const double ty = s(fy - static_cast<double>(iy));
        const float* g00 = g.data() + gx * (iy + gy * iz);
        const float* g10 = g00 + gx;
        const float* g01 = g00 + gx * gy;
        const float* g11 = g01 + gx;
        float* row = image.data() + image.index(0, y, z);
        const int64_t base = image.index(0, y, z);
        for (int64_t x = 0; x < nx; ++x) {
          const double fx = static_cast<double>(x) / cell;
          const int64_t ix = static_cast<int64_t>(fx);
          const double tx = s(fx - static_cast<double>(ix));
          auto lerp = [](double a, double b, double t) { return a + (b - a) * t; };
          const double v = lerp(lerp(lerp(g00[ix], g00[ix + 1], tx), lerp(g10[ix], g10[ix + 1], tx), ty),
                                lerp(lerp(g01[ix], g01[ix + 1], tx), lerp(g11[ix], g11[ix + 1], tx), ty), tz);
          const double h = static_cast<double>(splitmix(hseed + static_cast<uint64_t>(base + x)) >> 11) * 0x1.0p-53;
          row[x] += low * static_cast<float>(v) + high * static_cast<float>(2.0 * h - 1.0);
        }
      }
    }
  });
}

NetworkResult make_network(const NetworkOptions& o) {
  const Grid grid(o.size, o.spacing, {0.0, 0.0, 0.0}, o.unit);
  grid.validate();
  if (static_cast<unsigned>(o.shape) > static_cast<unsigned>(Shape::mixed))
    throw InputError("shape: not one of rods, plates, spheres, mixed");
  if (!(o.period >= 8)) throw InputError("period: " + std::to_string(o.period) + " voxels; expected >= 8");
  if (!(o.radius > 0 && o.radius * 4 <= o.period))
    throw InputError("radius: " + std::to_string(o.radius) + " voxels; expected > 0 and <= period / 4");
  if (!(o.plate_thickness > 0 && o.plate_thickness * 2 <= o.period))
    throw InputError("plate_thickness: " + std::to_string(o.plate_thickness) + " voxels; expected > 0 and <= period / 2");
  if (!(o.sigma >= 0)) throw InputError("sigma: expected >= 0 voxels");
  if (!(o.threshold > 0 && o.threshold < 1)) throw InputError("threshold: expected a value in (0, 1)");
  if (!(o.noise >= 0 && o.noise <= 1)) throw InputError("noise: " + std::to_string(o.noise) + "; expected 0..1");
  const double P = o.period, R = o.radius, H = 0.5 * o.plate_thickness;
  const uint64_t seed = o.seed;
  const Dims& n = o.size;
  auto u = [&](int64_t tag, int64_t a, int64_t b, int64_t c) { return hash_uniform(seed, tag * 1000003 + a, b, c); };
  // Lattice cells covering the volume plus one on each side (elements cross the borders).
  int64_t cells[3];
  for (int k = 0; k < 3; ++k) cells[k] = static_cast<int64_t>(std::ceil(static_cast<double>(n[k]) / P)) + 1;

  std::vector<Capsule> caps;
  std::vector<Plate> plates;
  auto keep = [&](const Capsule& c) {
    for (int k = 0; k < 3; ++k)
      if (c.hi[k] < 0 || c.lo[k] > static_cast<double>(n[k] - 1)) return;
    caps.push_back(c);
  };

  if (o.shape == Shape::rods) {
    // Jittered lattice nodes; each joins its +x, +y, +z neighbour with probability 0.8.
    auto node = [&](int64_t i, int64_t j, int64_t k) {
      return V{(static_cast<double>(i) + 0.5 + 0.4 * (u(1, i, j, k) - 0.5)) * P,
               (static_cast<double>(j) + 0.5 + 0.4 * (u(2, i, j, k) - 0.5)) * P,
               (static_cast<double>(k) + 0.5 + 0.4 * (u(3, i, j, k) - 0.5)) * P};
    };
    for (int64_t k = -1; k < cells[2]; ++k)
      for (int64_t j = -1; j < cells[1]; ++j)
        for (int64_t i = -1; i < cells[0]; ++i)
          for (int axis = 0; axis < 3; ++axis) {
            if (u(10 + axis, i, j, k) >= 0.8) continue;
            const V a = node(i, j, k);
            const V b = node(i + (axis == 0), j + (axis == 1), k + (axis == 2));
            keep(capsule(a, b, R * (0.8 + 0.4 * u(20 + axis, i, j, k))));
          }
  } else if (o.shape == Shape::spheres) {
    // One ball per lattice cell (probability 0.85), jittered by ≤ 0.15 period; radii keep a gap of
    // ≥ 3 voxels between neighbours so they stay separate after smoothing.
    const double rmin = 1.5 * R, rmax = std::max(rmin, 0.35 * P - 1.5);
    for (int64_t k = -1; k < cells[2]; ++k)
      for (int64_t j = -1; j < cells[1]; ++j)
        for (int64_t i = -1; i < cells[0]; ++i) {
          if (u(30, i, j, k) >= 0.85) continue;
          const V c{(static_cast<double>(i) + 0.5 + 0.3 * (u(31, i, j, k) - 0.5)) * P,
                    (static_cast<double>(j) + 0.5 + 0.3 * (u(32, i, j, k) - 0.5)) * P,
                    (static_cast<double>(k) + 0.5 + 0.3 * (u(33, i, j, k) - 0.5)) * P};
          keep(capsule(c, c, rmin + (rmax - rmin) * u(34, i, j, k)));
        }
  } else if (o.shape == Shape::plates) {
    // Slabs perpendicular to z every period (tilted by up to ±0.15) and walls perpendicular to x
    // every 2 periods joining them; round holes (radius period / 3) in 45 % of the cells.
    for (int64_t k = -1; k < cells[2]; ++k)
      plates.push_back({2, 0, 1, (static_cast<double>(k) + 0.5 + 0.2 * (u(40, k, 0, 0) - 0.5)) * P,
                        0.3 * (u(41, k, 0, 0) - 0.5), 0.3 * (u(42, k, 0, 0) - 0.5), 0.0, k, 0.45, P / 3, P});
    for (int64_t i = -1; i < (cells[0] + 1) / 2; ++i)
      plates.push_back({0, 1, 2, (2.0 * static_cast<double>(i) + 1.0 + 0.2 * (u(43, i, 0, 0) - 0.5)) * P,
                        0.2 * (u(44, i, 0, 0) - 0.5), 0.2 * (u(45, i, 0, 0) - 0.5), 0.0, 1000 + i, 0.45, P / 3, P});
  } else {  // mixed: bone-like plates joined by rods
    // Plates perpendicular to z every 2 periods (holes in 30 % of the cells), vertical rods between
    // consecutive plates on a jittered (x, y) lattice, and horizontal struts between the rods.
    const int64_t layers = static_cast<int64_t>(std::ceil(static_cast<double>(n[2]) / (2 * P))) + 1;
    for (int64_t k = -1; k < layers; ++k)
      plates.push_back({2, 0, 1, (2.0 * static_cast<double>(k) + 1.0 + 0.2 * (u(50, k, 0, 0) - 0.5)) * P,
                        0.2 * (u(51, k, 0, 0) - 0.5), 0.2 * (u(52, k, 0, 0) - 0.5), 0.0, k, 0.3, P / 3, P});
    auto plate_z = [&](size_t p, double x, double y) { return plates[p].c + plates[p].su * x + plates[p].sv * y; };
    for (size_t p = 0; p + 1 < plates.size(); ++p) {
      const int64_t k = static_cast<int64_t>(p);
      auto top = [&](int64_t i, int64_t j) {
        return V{(static_cast<double>(i) + 0.5 + 0.4 * (u(53, i, j, k) - 0.5)) * P,
                 (static_cast<double>(j) + 0.5 + 0.4 * (u(54, i, j, k) - 0.5)) * P, 0.0};
      };
      auto rod_present = [&](int64_t i, int64_t j) { return u(55, i, j, k) < 0.6; };
      auto mid = [&](int64_t i, int64_t j) {
        V t = top(i, j);
        t[2] = 0.5 * (plate_z(p, t[0], t[1]) + plate_z(p + 1, t[0], t[1]));
        return t;
      };
      for (int64_t j = -1; j < cells[1]; ++j)
        for (int64_t i = -1; i < cells[0]; ++i) {
          if (!rod_present(i, j)) continue;
          const V t = top(i, j);
          const double r = R * (0.8 + 0.4 * u(56, i, j, k));
          keep(capsule(V{t[0], t[1], plate_z(p, t[0], t[1])}, V{t[0], t[1], plate_z(p + 1, t[0], t[1])}, r));
          for (int axis = 0; axis < 2; ++axis) {
            const int64_t i2 = i + (axis == 0), j2 = j + (axis == 1);
            if (rod_present(i2, j2) && u(57 + axis, i, j, k) < 0.35) keep(capsule(mid(i, j), mid(i2, j2), 0.8 * r));
          }
        }
    }
  }
  for (Plate& pl : plates) pl.h = H * std::sqrt(1 + pl.su * pl.su + pl.sv * pl.sv);  // along w

  NetworkResult res;
  res.image = VolumeF32(grid, 0.0f);
  o.interrupter.check(0.0);
  draw_capsules(res.image, caps, o.threads, o.interrupter);
  draw_plates(res.image, plates, seed, o.threads);
  // The phantoms' own arithmetic (GaussianSum::sequential), so that they stay bit-identical.
  if (o.sigma > 0)
    segmentation::gaussian_in_place(res.image, {o.sigma, o.sigma, o.sigma}, 3.0, segmentation::GaussianSum::sequential,
                                    o.threads, o.interrupter.sub(0.3, 0.9));
  add_two_frequency_noise(res.image, seed, o.noise, o.threads);
  res.mask = VolumeU8::uninitialized(grid);
  const float thr = static_cast<float>(o.threshold);
  parallel_for(0, grid.voxel_count(), o.threads, [&](int64_t i0, int64_t i1) {
    const float* s = res.image.data();
    uint8_t* m = res.mask.data();
    for (int64_t i = i0; i < i1; ++i) m[i] = s[i] > thr ? 1 : 0;
  }, 1 << 20);
  o.interrupter.check(1.0);
  return res;
}

}  // namespace skel::synthetic
