// Binary morphology with an exact digital ball via separable squared Euclidean distance transforms
// in integer voxel units (lower envelopes of parabolas, Felzenszwalb & Huttenlocher).
#include <cmath>
#include <limits>
#include <vector>

#include "segmentation/segmentation.hpp"
#include "skel/error.hpp"
#include "skel/parallel.hpp"

namespace skel::segmentation {
namespace {

constexpr int32_t kInf = std::numeric_limits<int32_t>::max();  // finite values are <= 3·n² < 2^31

// d[q] = min_p f[p] + (q - p)^2 over the finite f[p]; kInf where no f is finite. v, zb: scratch.
void envelope(const int32_t* f, int32_t* d, int64_t n, std::vector<int64_t>& v, std::vector<double>& zb) {
  v.resize(static_cast<size_t>(n));
  zb.resize(static_cast<size_t>(n) + 1);
  int64_t k = -1;
  for (int64_t q = 0; q < n; ++q) {
    if (f[q] >= kInf) continue;
    const double fq = static_cast<double>(f[q]) + static_cast<double>(q * q);
    while (k >= 0) {
      const int64_t p = v[static_cast<size_t>(k)];
      const double s = (fq - static_cast<double>(f[p]) - static_cast<double>(p * p)) / (2.0 * static_cast<double>(q - p));
      if (s <= zb[static_cast<size_t>(k)]) {
        --k;
      } else {
        ++k;
        v[static_cast<size_t>(k)] = q;
        zb[static_cast<size_t>(k)] = s;
        break;
      }
    }
    if (k < 0) {
      k = 0;
      v[0] = q;
      zb[0] = -std::numeric_limits<double>::infinity();
    }
  }
  if (k < 0) {
    for (int64_t q = 0; q < n; ++q) d[q] = kInf;
    return;
  }
  int64_t j = 0;
  for (int64_t q = 0; q < n; ++q) {
    while (j < k && zb[static_cast<size_t>(j + 1)] < static_cast<double>(q)) ++j;
    const int64_t p = v[static_cast<size_t>(j)];
    d[q] = static_cast<int32_t>(f[p] + (q - p) * (q - p));
  }
}

// Squared distance (voxels²) from every voxel to the nearest voxel with (mask[i] != 0) == seed_value.
std::vector<int32_t> squared_distance_to(const VolumeU8& mask, bool seed_value, const MorphologyOptions& o, double p0,
                                         double p1) {
  const int64_t nx = mask.nx(), ny = mask.ny(), nz = mask.nz();
  std::vector<int32_t> g(static_cast<size_t>(mask.size()));
  // x: two sweeps per row.
  parallel_for(0, ny * nz, o.threads, [&](int64_t b, int64_t e) {
    for (int64_t row = b; row < e; ++row) {
      const uint8_t* m = mask.data() + row * nx;
      int32_t* d = g.data() + row * nx;
      int64_t last = -1;
      for (int64_t x = 0; x < nx; ++x) {
        if ((m[x] != 0) == seed_value) last = x;
        d[x] = last < 0 ? kInf : static_cast<int32_t>(x - last);
      }
      last = -1;
      for (int64_t x = nx - 1; x >= 0; --x) {
        if ((m[x] != 0) == seed_value) last = x;
        if (last >= 0) d[x] = std::min(d[x], static_cast<int32_t>(last - x));
        if (d[x] < kInf) d[x] *= d[x];
      }
    }
  }, 64);
  o.interrupter.check(p0 + (p1 - p0) / 3);
  // y and z: lower envelopes along columns, gathered into line buffers.
  for (int axis = 1; axis < 3; ++axis) {
    const int64_t n = axis == 1 ? ny : nz, stride = axis == 1 ? nx : nx * ny;
    const int64_t lines = axis == 1 ? nx * nz : nx * ny;
    parallel_for(0, lines, o.threads, [&](int64_t b, int64_t e) {
      std::vector<int32_t> f(static_cast<size_t>(n)), d(static_cast<size_t>(n));
      std::vector<int64_t> v;
      std::vector<double> zb;
      for (int64_t l = b; l < e; ++l) {
        const int64_t start = axis == 1 ? (l % nx) + (l / nx) * nx * ny : l;
        for (int64_t i = 0; i < n; ++i) f[static_cast<size_t>(i)] = g[static_cast<size_t>(start + i * stride)];
        envelope(f.data(), d.data(), n, v, zb);
        for (int64_t i = 0; i < n; ++i) g[static_cast<size_t>(start + i * stride)] = d[static_cast<size_t>(i)];
        if ((l & 4095) == 4095) o.interrupter.check();
      }
    }, 256);
    o.interrupter.check(p0 + (p1 - p0) * (axis + 1) / 3);
  }
  return g;
}

VolumeU8 dilate(const VolumeU8& m, double r2, const MorphologyOptions& o, double p0, double p1) {
  const auto d = squared_distance_to(m, true, o, p0, p1);
  VolumeU8 out = VolumeU8::uninitialized(m.grid());
  for (int64_t i = 0; i < m.size(); ++i) out[i] = static_cast<double>(d[static_cast<size_t>(i)]) <= r2 ? 1 : 0;
  return out;
}

VolumeU8 erode(const VolumeU8& m, double r2, const MorphologyOptions& o, double p0, double p1) {
  const auto d = squared_distance_to(m, false, o, p0, p1);
  const int64_t nx = m.nx(), ny = m.ny(), nz = m.nz();
  VolumeU8 out = VolumeU8::uninitialized(m.grid());
  auto face = [&](int64_t c, int64_t n) { return std::min(c + 1, n - c); };  // distance to the outside ring
  for (int64_t z = 0; z < nz; ++z)
    for (int64_t y = 0; y < ny; ++y)
      for (int64_t x = 0; x < nx; ++x) {
        const int64_t i = m.index(x, y, z);
        const int64_t f = std::min({face(x, nx), face(y, ny), face(z, nz)});
        const double dd = std::min(static_cast<double>(d[static_cast<size_t>(i)]), static_cast<double>(f * f));
        out[i] = m[i] && dd > r2 ? 1 : 0;
      }
  return out;
}

}  // namespace

VolumeU8 morphology(const VolumeU8& mask, const MorphologyOptions& o) {
  if (!(o.radius >= 0) || !std::isfinite(o.radius))
    throw InputError("param 'radius': expected a finite value >= 0, got " + std::to_string(o.radius));
  const double r2 = o.radius * o.radius;
  if (mask.size() == 0) return VolumeU8(mask.grid(), 0);
  if (mask.nx() > 26000 || mask.ny() > 26000 || mask.nz() > 26000)
    throw InputError("morphology: volumes up to 26000 voxels per axis (32-bit squared distances)");
  VolumeU8 out;
  switch (o.op) {
    case MorphologyOp::dilate: out = dilate(mask, r2, o, 0, 1); break;
    case MorphologyOp::erode: out = erode(mask, r2, o, 0, 1); break;
    case MorphologyOp::open: out = dilate(erode(mask, r2, o, 0, 0.5), r2, o, 0.5, 1); break;
    case MorphologyOp::close: out = erode(dilate(mask, r2, o, 0, 0.5), r2, o, 0.5, 1); break;
  }
  o.interrupter.check(1.0);
  return out;
}

}  // namespace skel::segmentation
