#include "synthetic/altered.hpp"

#include <algorithm>
#include <atomic>
#include <cmath>
#include <numbers>

#include "segmentation/segmentation.hpp"
#include "skel/error.hpp"
#include "skel/parallel.hpp"

namespace skel::synthetic {

namespace {

using Capsule = NetworkElements::Capsule;
using Plate = NetworkElements::Plate;

constexpr uint64_t kCapsuleSalt = 0x6a09e667f3bcc909ull;
constexpr uint64_t kPlateSalt = 0xbb67ae8584caa73bull;
constexpr uint64_t kLandmarkSalt = 0x3c6ef372fe94f82bull;

int64_t floor_i(double v) { return static_cast<int64_t>(std::floor(v)); }
int64_t ceil_i(double v) { return static_cast<int64_t>(std::ceil(v)); }

// Sets image = 1 inside every capsule (coordinates already local to the image). Fixed z-chunks.
void draw_capsules(VolumeF32& img, const std::vector<Capsule>& caps, const std::vector<uint8_t>* removed, int threads) {
  const int64_t nx = img.nx(), ny = img.ny(), nz = img.nz();
  const int64_t chunks = std::max<int64_t>(1, (nz + 7) / 8);
  parallel_chunks(0, nz, chunks, threads, [&](int64_t, int64_t z0, int64_t z1) {
    for (size_t k = 0; k < caps.size(); ++k) {
      if (removed && (*removed)[k]) continue;
      const Capsule& c = caps[k];
      double lo[3], hi[3];
      for (int a = 0; a < 3; ++a) {
        lo[a] = std::min(c.a[a], c.b[a]) - c.r;
        hi[a] = std::max(c.a[a], c.b[a]) + c.r;
      }
      const int64_t za = std::max<int64_t>(z0, ceil_i(lo[2]));
      const int64_t zb = std::min<int64_t>(z1 - 1, floor_i(hi[2]));
      if (za > zb) continue;
      const int64_t ya = std::max<int64_t>(0, ceil_i(lo[1]));
      const int64_t yb = std::min<int64_t>(ny - 1, floor_i(hi[1]));
      const int64_t xa = std::max<int64_t>(0, ceil_i(lo[0]));
      const int64_t xb = std::min<int64_t>(nx - 1, floor_i(hi[0]));
      if (ya > yb || xa > xb) continue;
      const Vec3 ab{c.b[0] - c.a[0], c.b[1] - c.a[1], c.b[2] - c.a[2]};
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
  });
}

// Sets image = 1 inside every plate (outside its holes and removed cells); `off` is the network
// voxel of local voxel (0, 0, 0). Parallel over fixed y-chunks.
void draw_plates(VolumeF32& img, const Dims& off, const std::vector<Plate>& plates, uint64_t seed,
                 const Alteration* alt, int threads) {
  const Dims& d = img.dims();
  parallel_chunks(0, d[1], std::max<int64_t>(1, (d[1] + 7) / 8), threads, [&](int64_t, int64_t y0, int64_t y1) {
    int64_t p[3];
    for (const Plate& pl : plates) {
      const int64_t u_lo = pl.u == 1 ? y0 : 0, u_hi = pl.u == 1 ? y1 : d[pl.u];
      const int64_t v_lo = pl.v == 1 ? y0 : 0, v_hi = pl.v == 1 ? y1 : d[pl.v];
      const int64_t ou = off[pl.u], ov = off[pl.v], ow = off[pl.w];
      for (int64_t v = v_lo; v < v_hi; ++v)
        for (int64_t u = u_lo; u < u_hi; ++u) {
          const double U = static_cast<double>(u + ou), Vv = static_cast<double>(v + ov);
          const double wc = pl.c + pl.su * U + pl.sv * Vv;
          const int64_t wa = std::max<int64_t>(0, ceil_i(wc - pl.h) - ow);
          const int64_t wb = std::min<int64_t>(d[pl.w] - 1, floor_i(wc + pl.h) - ow);
          if (wa > wb) continue;
          const int64_t cu = floor_i(U / pl.cell), cv = floor_i(Vv / pl.cell);
          if (hash_uniform(seed, pl.id * 4 + 1, cu, cv) < pl.hole_p) {
            const double hu = (static_cast<double>(cu) + 0.3 + 0.4 * hash_uniform(seed, pl.id * 4 + 2, cu, cv)) * pl.cell;
            const double hv = (static_cast<double>(cv) + 0.3 + 0.4 * hash_uniform(seed, pl.id * 4 + 3, cu, cv)) * pl.cell;
            if ((U - hu) * (U - hu) + (Vv - hv) * (Vv - hv) < pl.hole_r * pl.hole_r) continue;
          }
          if (alt && alt->plate_cell_removed(pl, cu, cv)) continue;
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

double normal(uint64_t seed, int64_t a, int64_t b, int64_t c) {
  const double u1 = std::max(1e-300, hash_uniform(seed, a, b, 2 * c));
  const double u2 = hash_uniform(seed, a, b, 2 * c + 1);
  return std::sqrt(-2.0 * std::log(u1)) * std::cos(2.0 * std::numbers::pi * u2);
}

Matrix3 rotation_xyz(const Vec3& deg) {
  const double a = deg[0] * std::numbers::pi / 180, b = deg[1] * std::numbers::pi / 180, c = deg[2] * std::numbers::pi / 180;
  const Matrix3 rx{{{1, 0, 0}, {0, std::cos(a), -std::sin(a)}, {0, std::sin(a), std::cos(a)}}};
  const Matrix3 ry{{{std::cos(b), 0, std::sin(b)}, {0, 1, 0}, {-std::sin(b), 0, std::cos(b)}}};
  const Matrix3 rz{{{std::cos(c), -std::sin(c), 0}, {std::sin(c), std::cos(c), 0}, {0, 0, 1}}};
  auto mul = [](const Matrix3& p, const Matrix3& q) {
    Matrix3 r{};
    for (int i = 0; i < 3; ++i)
      for (int j = 0; j < 3; ++j)
        for (int k = 0; k < 3; ++k) r[i][j] += p[i][k] * q[k][j];
    return r;
  };
  return mul(rz, mul(ry, rx));
}

}  // namespace

bool Alteration::plate_cell_removed(const Plate& p, int64_t cu, int64_t cv) const {
  return plate_fraction > 0 && hash_uniform(seed ^ kPlateSalt, p.id * 7 + 3, cu, cv) < plate_fraction;
}

NetworkElements network_elements(const NetworkOptions& o, const Vec3& lo, const Vec3& hi) {
  const double P = o.period, R = o.radius;
  const uint64_t seed = o.seed;
  auto u = [&](int64_t tag, int64_t a, int64_t b, int64_t c) { return hash_uniform(seed, tag * 1000003 + a, b, c); };
  // Lattice index ranges reaching beyond the box (elements are at most ~2 periods long).
  int64_t c0[3], c1[3];
  for (int k = 0; k < 3; ++k) {
    c0[k] = std::min<int64_t>(-1, floor_i(lo[k] / P) - 2);
    c1[k] = ceil_i(hi[k] / P) + 2;
  }
  NetworkElements el;
  auto keep = [&](const Vec3& a, const Vec3& b, double r) {
    for (int k = 0; k < 3; ++k)
      if (std::max(a[k], b[k]) + r < lo[k] || std::min(a[k], b[k]) - r > hi[k]) return;
    el.capsules.push_back({a, b, r});
  };
  if (o.shape == Shape::rods) {
    auto node = [&](int64_t i, int64_t j, int64_t k) {
      return Vec3{(static_cast<double>(i) + 0.5 + 0.4 * (u(1, i, j, k) - 0.5)) * P,
                  (static_cast<double>(j) + 0.5 + 0.4 * (u(2, i, j, k) - 0.5)) * P,
                  (static_cast<double>(k) + 0.5 + 0.4 * (u(3, i, j, k) - 0.5)) * P};
    };
    for (int64_t k = c0[2]; k < c1[2]; ++k)
      for (int64_t j = c0[1]; j < c1[1]; ++j)
        for (int64_t i = c0[0]; i < c1[0]; ++i)
          for (int axis = 0; axis < 3; ++axis) {
            if (u(10 + axis, i, j, k) >= 0.8) continue;
            keep(node(i, j, k), node(i + (axis == 0), j + (axis == 1), k + (axis == 2)),
                 R * (0.8 + 0.4 * u(20 + axis, i, j, k)));
          }
  } else if (o.shape == Shape::spheres) {
    const double rmin = 1.5 * R, rmax = std::max(rmin, 0.35 * P - 1.5);
    for (int64_t k = c0[2]; k < c1[2]; ++k)
      for (int64_t j = c0[1]; j < c1[1]; ++j)
        for (int64_t i = c0[0]; i < c1[0]; ++i) {
          if (u(30, i, j, k) >= 0.85) continue;
          const Vec3 c{(static_cast<double>(i) + 0.5 + 0.3 * (u(31, i, j, k) - 0.5)) * P,
                       (static_cast<double>(j) + 0.5 + 0.3 * (u(32, i, j, k) - 0.5)) * P,
                       (static_cast<double>(k) + 0.5 + 0.3 * (u(33, i, j, k) - 0.5)) * P};
          keep(c, c, rmin + (rmax - rmin) * u(34, i, j, k));
        }
  } else if (o.shape == Shape::plates) {
    for (int64_t k = c0[2]; k < c1[2]; ++k)
      el.plates.push_back({2, 0, 1, (static_cast<double>(k) + 0.5 + 0.2 * (u(40, k, 0, 0) - 0.5)) * P,
                           0.3 * (u(41, k, 0, 0) - 0.5), 0.3 * (u(42, k, 0, 0) - 0.5), 0.0, k, 0.45, P / 3, P});
    for (int64_t i = c0[0] / 2 - 1; i < c1[0] / 2 + 1; ++i)
      el.plates.push_back({0, 1, 2, (2.0 * static_cast<double>(i) + 1.0 + 0.2 * (u(43, i, 0, 0) - 0.5)) * P,
                           0.2 * (u(44, i, 0, 0) - 0.5), 0.2 * (u(45, i, 0, 0) - 0.5), 0.0, 1000 + i, 0.45, P / 3, P});
  } else if (o.shape == Shape::mixed) {
    // Plate k sits at (2k + 1)·P; the rods between plates k and k + 1 use lattice layer k + 1 (as in
    // make_network, whose plate list starts at k = -1).
    const int64_t k0 = std::min<int64_t>(-1, floor_i(lo[2] / (2 * P)) - 2), k1 = ceil_i(hi[2] / (2 * P)) + 2;
    auto plate = [&](int64_t k) {
      return Plate{2, 0, 1, (2.0 * static_cast<double>(k) + 1.0 + 0.2 * (u(50, k, 0, 0) - 0.5)) * P,
                   0.2 * (u(51, k, 0, 0) - 0.5), 0.2 * (u(52, k, 0, 0) - 0.5), 0.0, k, 0.3, P / 3, P};
    };
    for (int64_t k = k0; k < k1; ++k) el.plates.push_back(plate(k));
    for (int64_t kp = k0; kp + 1 < k1; ++kp) {
      const Plate lower = plate(kp), upper = plate(kp + 1);
      const int64_t k = kp + 1;
      auto pz = [](const Plate& p, double x, double y) { return p.c + p.su * x + p.sv * y; };
      auto top = [&](int64_t i, int64_t j) {
        return Vec3{(static_cast<double>(i) + 0.5 + 0.4 * (u(53, i, j, k) - 0.5)) * P,
                    (static_cast<double>(j) + 0.5 + 0.4 * (u(54, i, j, k) - 0.5)) * P, 0.0};
      };
      auto rod_present = [&](int64_t i, int64_t j) { return u(55, i, j, k) < 0.6; };
      auto mid = [&](int64_t i, int64_t j) {
        Vec3 t = top(i, j);
        t[2] = 0.5 * (pz(lower, t[0], t[1]) + pz(upper, t[0], t[1]));
        return t;
      };
      for (int64_t j = c0[1]; j < c1[1]; ++j)
        for (int64_t i = c0[0]; i < c1[0]; ++i) {
          if (!rod_present(i, j)) continue;
          const Vec3 t = top(i, j);
          const double r = R * (0.8 + 0.4 * u(56, i, j, k));
          keep(Vec3{t[0], t[1], pz(lower, t[0], t[1])}, Vec3{t[0], t[1], pz(upper, t[0], t[1])}, r);
          for (int axis = 0; axis < 2; ++axis) {
            const int64_t i2 = i + (axis == 0), j2 = j + (axis == 1);
            if (rod_present(i2, j2) && u(57 + axis, i, j, k) < 0.35) keep(mid(i, j), mid(i2, j2), 0.8 * r);
          }
        }
    }
  } else {
    throw InputError("shape: not one of rods, plates, spheres, mixed");
  }
  const double H = 0.5 * o.plate_thickness;
  for (Plate& pl : el.plates) pl.h = H * std::sqrt(1 + pl.su * pl.su + pl.sv * pl.sv);
  return el;
}

VolumeF32 draw_network_elements(const NetworkOptions& o, const NetworkElements& el, const Dims& off, const Dims& dims,
                                const Alteration* alt) {
  VolumeF32 img(Grid(dims, o.spacing, {0.0, 0.0, 0.0}, o.unit), 0.0f);
  std::vector<Capsule> local = el.capsules;
  for (Capsule& c : local)
    for (int k = 0; k < 3; ++k) {
      c.a[k] -= static_cast<double>(off[k]);
      c.b[k] -= static_cast<double>(off[k]);
    }
  draw_capsules(img, local, alt ? &alt->removed_capsules : nullptr, o.threads);
  draw_plates(img, off, el.plates, o.seed, alt, o.threads);
  // As make_network smooths (same arithmetic), so an unaltered drawing reproduces its image.
  if (o.sigma > 0)
    segmentation::gaussian_in_place(img, {o.sigma, o.sigma, o.sigma}, 3.0, segmentation::GaussianSum::sequential,
                                    o.threads);
  return img;
}

AlteredNetworkResult make_altered_network(const AlteredNetworkOptions& o) {
  if (!(o.remove_fraction >= 0 && o.remove_fraction <= 1))
    throw InputError("remove_fraction: " + std::to_string(o.remove_fraction) + "; expected 0..1");
  if (o.landmarks < 3) throw InputError("landmarks: expected at least 3 landmark pairs");
  if (!(o.landmark_noise >= 0)) throw InputError("landmark_noise: expected >= 0 (physical units)");
  for (int k = 0; k < 3; ++k)
    if (!std::isfinite(o.rotation_degrees[static_cast<size_t>(k)]) || !std::isfinite(o.translation[static_cast<size_t>(k)]))
      throw InputError("rotation/translation: expected finite values");
  const NetworkOptions& no = o.network;
  const Interrupter& intr = no.interrupter;
  AlteredNetworkResult res;
  {
    NetworkOptions before = no;
    before.interrupter = intr.sub(0.0, 0.3);
    NetworkResult b = make_network(before);  // validates the network options
    res.before_image = std::move(b.image);
    res.before_mask = std::move(b.mask);
  }
  const Grid bg = res.before_mask.grid();
  const Dims n = bg.dims;
  const Vec3 s = bg.spacing;

  // Motion (before -> after): rotation about the volume centre, then translation.
  const Matrix3 rot = rotation_xyz(o.rotation_degrees);
  Vec3 centre{};
  for (int k = 0; k < 3; ++k) centre[static_cast<size_t>(k)] = bg.origin[static_cast<size_t>(k)] + 0.5 * static_cast<double>(n[static_cast<size_t>(k)] - 1) * s[static_cast<size_t>(k)];
  Vec3 t{};
  for (int i = 0; i < 3; ++i) {
    double rc = 0;
    for (int j = 0; j < 3; ++j) rc += rot[static_cast<size_t>(i)][static_cast<size_t>(j)] * centre[static_cast<size_t>(j)];
    t[static_cast<size_t>(i)] = centre[static_cast<size_t>(i)] - rc + o.translation[static_cast<size_t>(i)];
  }
  res.motion = Transform(rot, t, TransformKind::Rigid);
  res.transform = res.motion.inverse();
  res.transform.set_kind(TransformKind::Rigid);

  // After grid: covers the moved before volume (voxel boxes) plus one voxel.
  Vec3 amin{1e300, 1e300, 1e300}, amax{-1e300, -1e300, -1e300};
  for (int c = 0; c < 8; ++c) {
    Vec3 p{};
    for (int k = 0; k < 3; ++k)
      p[static_cast<size_t>(k)] = bg.origin[static_cast<size_t>(k)] +
                                  (((c >> k) & 1) ? static_cast<double>(n[static_cast<size_t>(k)]) - 0.5 : -0.5) * s[static_cast<size_t>(k)];
    const Vec3 q = res.motion.apply(p);
    for (int k = 0; k < 3; ++k) {
      amin[static_cast<size_t>(k)] = std::min(amin[static_cast<size_t>(k)], q[static_cast<size_t>(k)]);
      amax[static_cast<size_t>(k)] = std::max(amax[static_cast<size_t>(k)], q[static_cast<size_t>(k)]);
    }
  }
  Grid ag;
  ag.spacing = s;
  ag.unit = bg.unit;
  for (int k = 0; k < 3; ++k) {
    const size_t K = static_cast<size_t>(k);
    ag.origin[K] = amin[K] - 0.5 * s[K];  // one voxel margin below (voxel centre at amin - s/2 + ...)
    ag.dims[K] = ceil_i((amax[K] - amin[K]) / s[K]) + 2;
  }

  // Padded before-voxel box covering the after grid mapped back, plus the smoothing support.
  const double margin = std::ceil(3.0 * no.sigma) + 2.0;
  Vec3 plo{0, 0, 0}, phi{static_cast<double>(n[0] - 1), static_cast<double>(n[1] - 1), static_cast<double>(n[2] - 1)};
  for (int c = 0; c < 8; ++c) {
    Vec3 q{};
    for (int k = 0; k < 3; ++k)
      q[static_cast<size_t>(k)] = ag.origin[static_cast<size_t>(k)] +
                                  (((c >> k) & 1) ? static_cast<double>(ag.dims[static_cast<size_t>(k)]) - 0.5 : -0.5) * s[static_cast<size_t>(k)];
    const Vec3 p = res.transform.apply(q);
    for (int k = 0; k < 3; ++k) {
      const size_t K = static_cast<size_t>(k);
      const double v = (p[K] - bg.origin[K]) / s[K];
      plo[K] = std::min(plo[K], v);
      phi[K] = std::max(phi[K], v);
    }
  }
  Dims off{}, pd{};
  for (int k = 0; k < 3; ++k) {
    const size_t K = static_cast<size_t>(k);
    off[K] = floor_i(plo[K] - margin);
    pd[K] = ceil_i(phi[K] + margin) - off[K] + 1;
  }
  intr.check(0.35);

  // Elements and the alteration.
  const Vec3 elo{static_cast<double>(off[0]), static_cast<double>(off[1]), static_cast<double>(off[2])};
  const Vec3 ehi{static_cast<double>(off[0] + pd[0] - 1), static_cast<double>(off[1] + pd[1] - 1), static_cast<double>(off[2] + pd[2] - 1)};
  const NetworkElements el = network_elements(no, elo, ehi);
  Alteration alt;
  alt.seed = o.alter_seed;
  alt.plate_fraction = o.remove_fraction;
  alt.removed_capsules.resize(el.capsules.size());
  int64_t caps_inside = 0, caps_removed = 0;
  for (size_t k = 0; k < el.capsules.size(); ++k) {
    const Capsule& c = el.capsules[k];
    const double h = hash_uniform(o.alter_seed ^ kCapsuleSalt, std::llround((c.a[0] + c.b[0]) * 8), std::llround((c.a[1] + c.b[1]) * 8),
                                  std::llround((c.a[2] + c.b[2]) * 8));
    alt.removed_capsules[k] = h < o.remove_fraction ? 1 : 0;
    bool inside = true;
    for (int a = 0; a < 3; ++a)
      if (std::max(c.a[a], c.b[a]) + c.r < 0 || std::min(c.a[a], c.b[a]) - c.r > static_cast<double>(n[static_cast<size_t>(a)] - 1)) inside = false;
    caps_inside += inside;
    caps_removed += inside && alt.removed_capsules[k];
  }
  NetworkOptions draw = no;
  const VolumeF32 all = draw_network_elements(draw, el, off, pd, nullptr);
  intr.check(0.55);
  const VolumeF32 kept = draw_network_elements(draw, el, off, pd, &alt);
  intr.check(0.75);
  const float thr = static_cast<float>(no.threshold);

  // Removed ground truth on the before grid.
  res.removed = VolumeU8(bg, 0);
  int64_t removed_voxels = 0, object_voxels = 0;
  for (int64_t z = 0; z < n[2]; ++z)
    for (int64_t y = 0; y < n[1]; ++y)
      for (int64_t x = 0; x < n[0]; ++x) {
        const int64_t j = kept.index(x - off[0], y - off[1], z - off[2]);
        const bool in_all = all[j] > thr;
        object_voxels += in_all;
        if (in_all && !(kept[j] > thr)) {
          res.removed(x, y, z) = 1;
          ++removed_voxels;
        }
      }

  // After image: trilinear samples of the altered drawing at motion⁻¹ of each after voxel.
  res.after_image = VolumeF32(ag, 0.0f);
  parallel_for(0, ag.dims[2], no.threads, [&](int64_t z0, int64_t z1) {
    for (int64_t z = z0; z < z1; ++z)
      for (int64_t y = 0; y < ag.dims[1]; ++y)
        for (int64_t x = 0; x < ag.dims[0]; ++x) {
          const Vec3 p = res.transform.apply(ag.position(static_cast<double>(x), static_cast<double>(y), static_cast<double>(z)));
          double v[3];
          int64_t i0[3];
          double f[3];
          for (int k = 0; k < 3; ++k) {
            const size_t K = static_cast<size_t>(k);
            v[k] = std::clamp((p[K] - bg.origin[K]) / s[K] - static_cast<double>(off[K]), 0.0, static_cast<double>(pd[K] - 1));
            i0[k] = std::min<int64_t>(floor_i(v[k]), std::max<int64_t>(0, pd[K] - 2));
            f[k] = v[k] - static_cast<double>(i0[k]);
          }
          double acc = 0;
          for (int c = 0; c < 8; ++c) {
            int64_t ii[3];
            double w = 1;
            for (int k = 0; k < 3; ++k) {
              const int bit = (c >> k) & 1;
              ii[k] = std::min<int64_t>(i0[k] + bit, pd[static_cast<size_t>(k)] - 1);
              w *= bit ? f[k] : 1.0 - f[k];
            }
            if (w != 0) acc += w * static_cast<double>(kept(ii[0], ii[1], ii[2]));
          }
          res.after_image(x, y, z) = static_cast<float>(acc);
        }
  }, 1);
  const uint64_t after_seed = (no.seed * 0x9e3779b97f4a7c15ull) ^ (o.alter_seed + 0x5bd1e995ull);
  add_two_frequency_noise(res.after_image, after_seed, no.noise, no.threads);
  res.after_mask = VolumeU8::uninitialized(ag);
  for (int64_t i = 0; i < res.after_mask.size(); ++i) res.after_mask[i] = res.after_image[i] > thr ? 1 : 0;
  intr.check(0.9);

  // Landmark sites: centres of kept capsules (and of kept, hole-free plate cells) well inside the
  // before volume, ordered by a hash.
  const double m = std::max(4.0, no.period / 4);
  auto inside = [&](const Vec3& v) {
    for (int k = 0; k < 3; ++k)
      if (v[static_cast<size_t>(k)] < m || v[static_cast<size_t>(k)] > static_cast<double>(n[static_cast<size_t>(k)] - 1) - m) return false;
    return true;
  };
  std::vector<std::pair<double, Vec3>> sites;
  for (size_t k = 0; k < el.capsules.size(); ++k) {
    if (alt.removed_capsules[k]) continue;
    const Capsule& c = el.capsules[k];
    const Vec3 mid{0.5 * (c.a[0] + c.b[0]), 0.5 * (c.a[1] + c.b[1]), 0.5 * (c.a[2] + c.b[2])};
    if (inside(mid))
      sites.emplace_back(hash_uniform(o.alter_seed ^ kLandmarkSalt, std::llround(mid[0] * 8), std::llround(mid[1] * 8), std::llround(mid[2] * 8)), mid);
  }
  for (const Plate& pl : el.plates) {
    const int64_t cu_max = ceil_i(static_cast<double>(n[static_cast<size_t>(pl.u)]) / pl.cell);
    const int64_t cv_max = ceil_i(static_cast<double>(n[static_cast<size_t>(pl.v)]) / pl.cell);
    for (int64_t cv = 0; cv < cv_max; ++cv)
      for (int64_t cu = 0; cu < cu_max; ++cu) {
        if (alt.plate_cell_removed(pl, cu, cv) || hash_uniform(no.seed, pl.id * 4 + 1, cu, cv) < pl.hole_p) continue;
        const double U = (static_cast<double>(cu) + 0.5) * pl.cell, V = (static_cast<double>(cv) + 0.5) * pl.cell;
        Vec3 p{};
        p[static_cast<size_t>(pl.u)] = U;
        p[static_cast<size_t>(pl.v)] = V;
        p[static_cast<size_t>(pl.w)] = pl.c + pl.su * U + pl.sv * V;
        if (inside(p))
          sites.emplace_back(hash_uniform(o.alter_seed ^ kLandmarkSalt, pl.id * 7 + 5, cu, cv), p);
      }
  }
  std::sort(sites.begin(), sites.end());
  if (static_cast<int64_t>(sites.size()) < o.landmarks)
    throw InputError("landmarks: only " + std::to_string(sites.size()) + " landmark sites fit in the volume; ask for fewer or a larger size");
  std::vector<Vec3> fixed, moving;
  double noise2 = 0;
  const uint64_t nseed = o.alter_seed ^ kLandmarkSalt ^ 0x1234567ull;
  for (int64_t i = 0; i < o.landmarks; ++i) {
    const Vec3& v = sites[static_cast<size_t>(i)].second;
    const Vec3 p = bg.position(v[0], v[1], v[2]);
    const Vec3 q = res.motion.apply(p);
    Vec3 pf{}, pm{};
    for (int k = 0; k < 3; ++k) {
      const double e0 = o.landmark_noise * normal(nseed, i, k, 0), e1 = o.landmark_noise * normal(nseed, i, k, 1);
      pf[static_cast<size_t>(k)] = p[static_cast<size_t>(k)] + e0;
      pm[static_cast<size_t>(k)] = q[static_cast<size_t>(k)] + e1;
      noise2 += e0 * e0 + e1 * e1;
    }
    fixed.push_back(pf);
    moving.push_back(pm);
  }
  res.landmarks = LandmarkSet({fixed, moving});
  res.landmarks.unit = bg.unit;
  res.summary.add("capsules", std::vector<int64_t>{caps_inside})
      .add("removed_capsules", std::vector<int64_t>{caps_removed})
      .add("object_voxels", std::vector<int64_t>{object_voxels})
      .add("removed_voxels", std::vector<int64_t>{removed_voxels})
      .add("landmarks", std::vector<int64_t>{o.landmarks})
      .add("landmark_rms_noise", std::vector<double>{std::sqrt(noise2 / (6.0 * static_cast<double>(o.landmarks)))}, o.network.unit);
  intr.check(1.0);
  return res;
}

}  // namespace skel::synthetic
