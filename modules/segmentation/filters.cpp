// Image filters of the pre-processing chain (thesis §6.1): separable Gaussian, median, illumination
// correction along z.
#include <algorithm>
#include <cmath>
#include <vector>

#include "segmentation/segmentation.hpp"
#include "skel/block_journal.hpp"
#include "skel/distributed.hpp"
#include "skel/error.hpp"
#include "skel/parallel.hpp"

namespace skel::segmentation {
namespace {

// Half kernel k[0..r] (k[j] weighs the taps at -j and +j) of a normalised sampled Gaussian with
// sigma s voxels, r = max(1, ceil(truncate·s)), in the arithmetic of `sum`.
std::vector<float> half_kernel(double s, double truncate, GaussianSum sum) {
  const int r = std::max(1, static_cast<int>(std::ceil(truncate * s)));
  std::vector<float> out(static_cast<size_t>(r + 1));
  if (sum == GaussianSum::paired) {
    std::vector<double> k(static_cast<size_t>(r + 1));
    double total = 0;
    for (int i = 0; i <= r; ++i) {
      k[static_cast<size_t>(i)] = std::exp(-0.5 * i * i / (s * s));
      total += (i == 0 ? 1.0 : 2.0) * k[static_cast<size_t>(i)];
    }
    for (size_t i = 0; i < k.size(); ++i) out[i] = static_cast<float>(k[i] / total);
  } else {
    // Weights rounded to float first, their sum taken from -r to r.
    for (int i = 0; i <= r; ++i)
      out[static_cast<size_t>(i)] = static_cast<float>(std::exp(-0.5 * static_cast<double>(i * i) / (s * s)));
    double total = 0;
    for (int i = -r; i <= r; ++i) total += out[static_cast<size_t>(i < 0 ? -i : i)];
    for (auto& w : out) w = static_cast<float>(w / total);
  }
  return out;
}

inline int64_t clamp_index(int64_t i, int64_t n) { return i < 0 ? 0 : (i >= n ? n - 1 : i); }

// dst[x] = the kernel applied to rows(-r..r)[x], rows(j) = pointer to the row at offset j; whole rows
// at a time, so the inner loops run over x and vectorise.
//   paired:     k0·rows(0)[x] + Σ_j k_j·(rows(-j)[x] + rows(+j)[x])
//   sequential: 0 + k_r·rows(-r)[x] + ... + k_r·rows(+r)[x], left to right
template <GaussianSum Sum, class RowAt>
void combine_rows(float* dst, int64_t nx, const std::vector<float>& k, RowAt&& row_at) {
  if constexpr (Sum == GaussianSum::paired) {
    const float* c = row_at(0);
    const float k0 = k[0];
    for (int64_t x = 0; x < nx; ++x) dst[x] = k0 * c[x];
    for (size_t j = 1; j < k.size(); ++j) {
      const float* a = row_at(-static_cast<int64_t>(j));
      const float* b = row_at(static_cast<int64_t>(j));
      const float kj = k[j];
      for (int64_t x = 0; x < nx; ++x) dst[x] += kj * (a[x] + b[x]);
    }
  } else {
    const auto r = static_cast<int64_t>(k.size()) - 1;
    std::fill_n(dst, nx, 0.0f);
    for (int64_t j = -r; j <= r; ++j) {
      const float* a = row_at(j);
      const float kj = k[static_cast<size_t>(j < 0 ? -j : j)];
      for (int64_t x = 0; x < nx; ++x) dst[x] += kj * a[x];
    }
  }
}

// The three axis passes; an empty kernel skips its axis. Progress: one third per axis.
template <GaussianSum Sum>
void smooth_axes(VolumeF32& out, const std::vector<float> (&k)[3], int threads, const Interrupter& interrupter) {
  const int64_t nx = out.nx(), ny = out.ny(), nz = out.nz();
  float* d = out.data();
  // x: each row padded with its border values.
  if (!k[0].empty()) {
    const auto r = static_cast<int64_t>(k[0].size()) - 1;
    parallel_for(0, ny * nz, threads, [&](int64_t b, int64_t e) {
      std::vector<float> buf(static_cast<size_t>(nx + 2 * r));
      for (int64_t row = b; row < e; ++row) {
        float* p = d + row * nx;
        std::fill_n(buf.begin(), r, p[0]);
        std::copy(p, p + nx, buf.begin() + r);
        std::fill_n(buf.begin() + r + nx, r, p[nx - 1]);
        const float* c = buf.data() + r;
        combine_rows<Sum>(p, nx, k[0], [&](int64_t j) { return c + j; });
        if ((row & 1023) == 1023) interrupter.check();
      }
    }, 64);
  }
  interrupter.check(1.0 / 3.0);
  // y: per slice, rows combined from a copy of the slice (whole rows: vectorised over x).
  if (!k[1].empty()) {
    parallel_for(0, nz, threads, [&](int64_t b, int64_t e) {
      std::vector<float> slice(static_cast<size_t>(nx * ny));
      for (int64_t z = b; z < e; ++z) {
        float* p = d + z * nx * ny;
        std::copy(p, p + nx * ny, slice.begin());
        for (int64_t y = 0; y < ny; ++y)
          combine_rows<Sum>(p + y * nx, nx, k[1], [&](int64_t j) { return slice.data() + clamp_index(y + j, ny) * nx; });
        interrupter.check();
      }
    }, 1);
  }
  interrupter.check(2.0 / 3.0);
  // z: per y, the nz rows of that y copied into a buffer and combined.
  if (!k[2].empty()) {
    parallel_for(0, ny, threads, [&](int64_t b, int64_t e) {
      std::vector<float> col(static_cast<size_t>(nx * nz));
      for (int64_t y = b; y < e; ++y) {
        for (int64_t z = 0; z < nz; ++z) std::copy_n(d + (y + ny * z) * nx, nx, col.begin() + z * nx);
        for (int64_t z = 0; z < nz; ++z)
          combine_rows<Sum>(d + (y + ny * z) * nx, nx, k[2], [&](int64_t j) { return col.data() + clamp_index(z + j, nz) * nx; });
        interrupter.check();
      }
    }, 1);
  }
  interrupter.check(1.0);
}

template <class T>
inline void sort2(T& a, T& b) {
  const T lo = b < a ? b : a;
  const T hi = b < a ? a : b;
  a = lo;
  b = hi;
}

// Median of 27 values per lane by forgetful selection: keep 15 candidates, drop the minimum and the
// maximum (neither can be the median), add the next value, repeat; the middle of the last 3 is it.
template <class T, int L>
void median27(const T* const src[27], T* dst, int lanes) {
  T buf[15][L] = {};
  for (int i = 0; i < 15; ++i)
    for (int l = 0; l < lanes; ++l) buf[i][l] = src[i][l];
  int s = 15, next = 15;
  while (true) {
    for (int i = 1; i < s; ++i)
      for (int l = 0; l < L; ++l) sort2(buf[0][l], buf[i][l]);
    for (int i = 1; i < s - 1; ++i)
      for (int l = 0; l < L; ++l) sort2(buf[i][l], buf[s - 1][l]);
    if (s == 3) break;
    for (int l = 0; l < lanes; ++l) buf[0][l] = src[next][l];
    ++next;
    --s;
  }
  for (int l = 0; l < lanes; ++l) dst[l] = buf[1][l];
}

}  // namespace

void gaussian_in_place(VolumeF32& image, const Vec3& sigma, double truncate, GaussianSum sum, int threads,
                       const Interrupter& interrupter) {
  for (int a = 0; a < 3; ++a)
    if (!(sigma[a] >= 0) || !std::isfinite(sigma[a])) throw InputError("gaussian: sigma must be finite and >= 0");
  if (!(truncate > 0) || !std::isfinite(truncate)) throw InputError("gaussian: truncate must be finite and > 0");
  if (image.size() == 0) return;
  std::vector<float> k[3];
  for (int a = 0; a < 3; ++a)
    if (sigma[a] > 0) k[a] = half_kernel(sigma[a], truncate, sum);
  if (sum == GaussianSum::paired) smooth_axes<GaussianSum::paired>(image, k, threads, interrupter);
  else smooth_axes<GaussianSum::sequential>(image, k, threads, interrupter);
}

static void check_gaussian_options(const GaussianOptions& o) {
  for (int a = 0; a < 3; ++a)
    if (!(o.sigma[a] >= 0) || !std::isfinite(o.sigma[a]))
      throw InputError("param 'sigma': expected finite values >= 0, got " + std::to_string(o.sigma[a]) + " on axis " + "xyz"[a]);
  if (!(o.truncate > 0)) throw InputError("param 'truncate': expected > 0");
}

void gaussian_in_place(VolumeF32& out, const GaussianOptions& o) {
  check_gaussian_options(o);
  if (out.size() == 0) return;
  // Sigma in voxels; an axis of one voxel is left as it is.
  Vec3 s{0, 0, 0};
  for (int a = 0; a < 3; ++a)
    if (out.dims()[a] > 1) s[a] = o.sigma[a] / out.spacing()[a];
  gaussian_in_place(out, s, o.truncate, GaussianSum::paired, o.threads, o.interrupter);
}

VolumeF32 gaussian(const DataObject& image, const GaussianOptions& o) {
  check_gaussian_options(o);
  VolumeF32 out = visit_volume(image, "image", [&](const auto& v) {
    VolumeF32 f = VolumeF32::uninitialized(v.grid());
    parallel_for(0, v.size(), o.threads, [&](int64_t b, int64_t e) {
      for (int64_t i = b; i < e; ++i) f[i] = static_cast<float>(v[i]);
    }, 1 << 16);
    return f;
  });
  gaussian_in_place(out, o);
  return out;
}

template <class T>
Volume<T> median_as(const Volume<T>& v, const MedianOptions& o) {
  if (o.radius < 0) throw InputError("param 'radius': expected >= 0, got " + std::to_string(o.radius));
  if (o.radius == 0 || v.size() == 0) return v;
  const int64_t nx = v.nx(), ny = v.ny(), nz = v.nz();
  Volume<T> out = Volume<T>::uninitialized(v.grid());
  if (o.radius == 1) {
    constexpr int L = 64;
    parallel_for(0, ny * nz, o.threads, [&](int64_t b, int64_t e) {
      std::vector<T> rows(static_cast<size_t>(9 * (nx + 2)));
      for (int64_t row = b; row < e; ++row) {
        const int64_t y = row % ny, z = row / ny;
        for (int dz = -1, q = 0; dz <= 1; ++dz)
          for (int dy = -1; dy <= 1; ++dy, ++q) {
            const T* s = v.data() + (clamp_index(y + dy, ny) + ny * clamp_index(z + dz, nz)) * nx;
            T* t = rows.data() + q * (nx + 2);
            t[0] = s[0];
            std::copy(s, s + nx, t + 1);
            t[nx + 1] = s[nx - 1];
          }
        T* dst = out.data() + row * nx;
        for (int64_t x0 = 0; x0 < nx; x0 += L) {
          const T* src[27];
          for (int q = 0; q < 9; ++q)
            for (int dx = 0; dx < 3; ++dx) src[3 * q + dx] = rows.data() + q * (nx + 2) + x0 + dx;
          median27<T, L>(src, dst + x0, static_cast<int>(std::min<int64_t>(L, nx - x0)));
        }
        if ((row & 255) == 255) o.interrupter.check();
      }
    }, 16);
  } else {
    const int r = o.radius;
    const int64_t w = 2 * r + 1;
    parallel_for(0, ny * nz, o.threads, [&](int64_t b, int64_t e) {
      std::vector<T> vals(static_cast<size_t>(w * w * w));
      for (int64_t row = b; row < e; ++row) {
        const int64_t y = row % ny, z = row / ny;
        for (int64_t x = 0; x < nx; ++x) {
          size_t n = 0;
          for (int64_t dz = -r; dz <= r; ++dz)
            for (int64_t dy = -r; dy <= r; ++dy) {
              const T* s = v.data() + (clamp_index(y + dy, ny) + ny * clamp_index(z + dz, nz)) * nx;
              for (int64_t dx = -r; dx <= r; ++dx) vals[n++] = s[clamp_index(x + dx, nx)];
            }
          std::nth_element(vals.begin(), vals.begin() + static_cast<int64_t>(n / 2), vals.end());
          out.data()[row * nx + x] = vals[n / 2];
        }
        if ((row & 15) == 15) o.interrupter.check();
      }
    }, 1);
  }
  o.interrupter.check(1.0);
  return out;
}

template Volume<uint8_t> median_as(const Volume<uint8_t>&, const MedianOptions&);
template Volume<uint16_t> median_as(const Volume<uint16_t>&, const MedianOptions&);
template Volume<uint32_t> median_as(const Volume<uint32_t>&, const MedianOptions&);
template Volume<uint64_t> median_as(const Volume<uint64_t>&, const MedianOptions&);
template Volume<int32_t> median_as(const Volume<int32_t>&, const MedianOptions&);
template Volume<float> median_as(const Volume<float>&, const MedianOptions&);
template Volume<double> median_as(const Volume<double>&, const MedianOptions&);

DataPtr median(const DataObject& image, const MedianOptions& o) {
  return visit_volume(image, "image", [&](const auto& v) -> DataPtr {
    using V = std::decay_t<decltype(v)>;
    return std::make_shared<V>(median_as(v, o));
  });
}

namespace {

// m(z) of one slice: the mean of its brightest `percentile` fraction (at least one voxel); `vals` is
// work space. The same arithmetic in memory and block-wise (nth_element, then the sum in order).
template <class T>
double slice_brightness(const T* slice, int64_t plane, double percentile, std::vector<double>& vals) {
  const int64_t top = std::max<int64_t>(1, static_cast<int64_t>(std::ceil(percentile * static_cast<double>(plane))));
  vals.resize(static_cast<size_t>(plane));
  for (int64_t i = 0; i < plane; ++i) vals[static_cast<size_t>(i)] = static_cast<double>(slice[i]);
  std::nth_element(vals.begin(), vals.begin() + (plane - top), vals.end());
  double sum = 0;
  for (int64_t i = plane - top; i < plane; ++i) sum += vals[static_cast<size_t>(i)];
  return sum / static_cast<double>(top);
}

void check_percentile(const IlluminationOptions& o) {
  if (o.mode == IlluminationMode::fit && !(o.percentile > 0 && o.percentile <= 1))
    throw InputError("param 'percentile': expected a fraction in (0, 1], got " + std::to_string(o.percentile));
}

// The factors f(z) from res.slice_statistic (fit) or the given line.
void illumination_factors(IlluminationResult& res, int64_t nz, const IlluminationOptions& o) {
  res.factor.resize(static_cast<size_t>(nz));
  if (o.mode != IlluminationMode::fit) {
    for (int64_t z = 0; z < nz; ++z) res.factor[static_cast<size_t>(z)] = o.intercept + o.slope * static_cast<double>(z);
    return;
  }
  // Least-squares line through (z, m(z)).
  double sz = 0, sm = 0, szz = 0, szm = 0;
  for (int64_t z = 0; z < nz; ++z) {
    const double m = res.slice_statistic[static_cast<size_t>(z)], zz = static_cast<double>(z);
    sz += zz; sm += m; szz += zz * zz; szm += zz * m;
  }
  const double n = static_cast<double>(nz);
  const double den = n * szz - sz * sz;
  res.fit_slope = nz > 1 && den != 0 ? (n * szm - sz * sm) / den : 0.0;
  res.fit_intercept = nz > 0 ? (sm - res.fit_slope * sz) / n : 0.0;
  for (int64_t z = 0; z < nz; ++z) {
    const double lz = res.fit_intercept + res.fit_slope * static_cast<double>(z);
    if (!(lz > 0))
      throw InputError("image: the fitted brightness line " + std::to_string(res.fit_intercept) + " + " +
                       std::to_string(res.fit_slope) + "·z is not positive at slice " + std::to_string(z) +
                       "; give slope/intercept instead (fit: false)");
    res.factor[static_cast<size_t>(z)] = res.fit_intercept / lz;
  }
}

}  // namespace

IlluminationResult illumination_z(const DataObject& image, const IlluminationOptions& o) {
  IlluminationResult res;
  res.image = visit_volume(image, "image", [&](const auto& v) {
    const int64_t nz = v.nz(), plane = v.nx() * v.ny();
    check_percentile(o);
    if (o.mode == IlluminationMode::fit) {
      res.slice_statistic.assign(static_cast<size_t>(nz), 0.0);
      if (plane > 0)
        parallel_for(0, nz, o.threads, [&](int64_t b, int64_t e) {
          std::vector<double> vals;
          for (int64_t z = b; z < e; ++z)
            res.slice_statistic[static_cast<size_t>(z)] = slice_brightness(&v[z * plane], plane, o.percentile, vals);
        }, 1);
    }
    illumination_factors(res, nz, o);
    o.interrupter.check(0.5);
    VolumeF32 out = VolumeF32::uninitialized(v.grid());
    parallel_for(0, nz, o.threads, [&](int64_t b, int64_t e) {
      for (int64_t z = b; z < e; ++z) {
        const double f = res.factor[static_cast<size_t>(z)];
        for (int64_t i = z * plane; i < (z + 1) * plane; ++i) out[i] = static_cast<float>(static_cast<double>(v[i]) * f);
      }
    }, 1);
    return out;
  });
  o.interrupter.check(1.0);
  return res;
}

IlluminationResult illumination_z_blocks(const DataObject& image, const ChunkedVolume& out, const IlluminationOptions& o,
                                         const Dims& block, int64_t slab) {
  IlluminationResult res;
  check_percentile(o);
  const Dims d = any_volume_grid(image, "input 'image'").dims;
  const int64_t nz = d[2], plane = d[0] * d[1];
  visit_voxel_type(image.type_id(), "input 'image'", [&](auto t) {
    using T = decltype(t);
    if (o.mode == IlluminationMode::fit) {
      // Pass 1: slabs of whole slices (the statistic needs a whole slice), the slices in parallel.
      res.slice_statistic.assign(static_cast<size_t>(nz), 0.0);
      slab = std::max<int64_t>(1, slab);
      const int64_t slabs = (nz + slab - 1) / slab;
      for (int64_t k = 0; k < slabs && plane > 0; ++k) {
        const int64_t z0 = k * slab, n = std::min(slab, nz - z0);
        const Volume<T> s = read_block<T>(image, {0, 0, z0}, {d[0], d[1], n}, "input 'image'");
        parallel_for(0, n, o.threads, [&](int64_t b, int64_t e) {
          std::vector<double> vals;
          for (int64_t z = b; z < e; ++z)
            res.slice_statistic[static_cast<size_t>(z0 + z)] = slice_brightness(&s[z * plane], plane, o.percentile, vals);
        }, 1);
        report_blocks(o.interrupter, "illumination statistics", k + 1, slabs);
      }
    }
    illumination_factors(res, nz, o);
    // Pass 2: every block scaled by the factor of its slices; resumable per block (--resume: pass 1
    // reads only the image and runs again).
    for_each_block_resumable(BlockLayout(d, block), o.interrupter, "illumination", [&](const Block& b) {
      const Volume<T> in = read_block<T>(image, b.begin, b.size, "input 'image'");
      VolumeF32 v = VolumeF32::uninitialized(out.box_grid(b.begin, b.size));
      const int64_t bplane = b.size[0] * b.size[1];
      for (int64_t z = 0; z < b.size[2]; ++z) {
        const double f = res.factor[static_cast<size_t>(b.begin[2] + z)];
        for (int64_t i = z * bplane; i < (z + 1) * bplane; ++i) v[i] = static_cast<float>(static_cast<double>(in[i]) * f);
      }
      out.write(v, b.begin);
    });
  });
  return res;
}

// ---------------------------------------------------------------- block-wise Gaussian (out-of-core)
namespace {
// Sigma in voxels of gaussian(): an axis of one voxel is left as it is.
Vec3 sigma_in_voxels(const Grid& g, const GaussianOptions& o) {
  for (int a = 0; a < 3; ++a)
    if (!(o.sigma[a] >= 0) || !std::isfinite(o.sigma[a]))
      throw InputError("param 'sigma': expected finite values >= 0, got " + std::to_string(o.sigma[a]) + " on axis " + "xyz"[a]);
  if (!(o.truncate > 0)) throw InputError("param 'truncate': expected > 0");
  Vec3 s{0, 0, 0};
  for (int a = 0; a < 3; ++a)
    if (g.dims[a] > 1) s[a] = o.sigma[a] / g.spacing[a];
  return s;
}
}  // namespace

Dims gaussian_halo(const Grid& grid, const GaussianOptions& o) {
  const Vec3 s = sigma_in_voxels(grid, o);
  Dims h{0, 0, 0};
  for (int a = 0; a < 3; ++a)
    if (s[a] > 0) h[a] = static_cast<int64_t>(half_kernel(s[a], o.truncate, GaussianSum::paired).size()) - 1;
  return h;
}

void gaussian_blocks(const DataObject& image, const ChunkedVolume& out, const GaussianOptions& o, const Dims& block) {
  const Grid& g = any_volume_grid(image, "input 'image'");
  if (out.dims() != g.dims || out.type_id() != type_ids::volume_f32)
    throw Error("gaussian_blocks: the output must be float32 on the image's grid");
  const Vec3 s = sigma_in_voxels(g, o);
  const Dims halo = gaussian_halo(g, o);
  const BlockLayout layout(g.dims, block);
  const Interrupter inner;
  visit_voxel_type(image.type_id(), "input 'image'", [&](auto tag) {
    using T = decltype(tag);
    // Split over MPI ranks when there are several; else resumable per block (--resume).
    const auto body = [&](const Block& b) {
      // The block with the kernel's radius around it (clipped to the grid, where the border value
      // is replicated as in memory): every interior voxel sees the same taps as in memory.
      Dims ob{}, os{};
      for (int a = 0; a < 3; ++a) {
        ob[a] = std::max<int64_t>(0, b.begin[a] - halo[a]);
        os[a] = std::min(g.dims[a], b.begin[a] + b.size[a] + halo[a]) - ob[a];
      }
      const Volume<T> v = read_block<T>(image, ob, os, "input 'image'");
      VolumeF32 f = VolumeF32::uninitialized(v.grid());
      for (int64_t i = 0; i < v.size(); ++i) f[i] = static_cast<float>(v[i]);
      if (f.size() > 0) gaussian_in_place(f, s, o.truncate, GaussianSum::paired, o.threads, inner);
      VolumeF32 interior = read_block<float>(f, {b.begin[0] - ob[0], b.begin[1] - ob[1], b.begin[2] - ob[2]}, b.size, "block");
      out.write(interior, b.begin);
    };
    if (distributing()) for_each_owned_block(layout, o.interrupter, "gaussian", body);
    else for_each_block_resumable(layout, o.interrupter, "gaussian", body);
  });
}

// ---------------------------------------------------------------- block-wise median (out-of-core)
void median_blocks(const DataObject& image, const ChunkedVolume& out, const MedianOptions& o, const Dims& block) {
  const Grid& g = any_volume_grid(image, "input 'image'");
  if (out.dims() != g.dims || out.type_id() != image.type_id())
    throw Error("median_blocks: the output must have the image's type and grid");
  const int64_t r = o.radius;
  if (r < 0) throw InputError("param 'radius': expected >= 0");
  const BlockLayout layout(g.dims, block, r);
  MedianOptions inner = o;
  inner.interrupter = Interrupter();
  visit_voxel_type(image.type_id(), "input 'image'", [&](auto tag) {
    using T = decltype(tag);
    // Split over MPI ranks when there are several; else resumable per block (--resume).
    const auto body = [&](const Block& b) {
      // The block with `radius` voxels around it (clipped to the grid, where the border value is
      // replicated as in memory): every interior voxel sees the same cube as in memory.
      const Volume<T> v = read_block<T>(image, b.outer_begin, b.outer_size, "input 'image'");
      const Volume<T> m = median_as(v, inner);
      out.write(read_block<T>(m, {b.begin[0] - b.outer_begin[0], b.begin[1] - b.outer_begin[1], b.begin[2] - b.outer_begin[2]},
                              b.size, "block"),
                b.begin);
    };
    if (distributing()) for_each_owned_block(layout, o.interrupter, "median", body);
    else for_each_block_resumable(layout, o.interrupter, "median", body);
  });
}

}  // namespace skel::segmentation
