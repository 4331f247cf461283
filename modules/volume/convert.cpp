#include "volume/convert.hpp"

#include <algorithm>
#include <cmath>
#include <limits>

#include "skel/parallel.hpp"

namespace skel::volume {

namespace {

template <class U, class T>
U clamp_cast(T v) {
  if constexpr (std::is_floating_point_v<U>) {
    return static_cast<U>(v);
  } else {
    if constexpr (std::is_floating_point_v<T>) {
      if (std::isnan(v)) return U{0};
      const double d = std::round(static_cast<double>(v));
      if (d <= static_cast<double>(std::numeric_limits<U>::lowest())) return std::numeric_limits<U>::lowest();
      if (d >= static_cast<double>(std::numeric_limits<U>::max())) return std::numeric_limits<U>::max();
      return static_cast<U>(d);
    } else {
      using W = int64_t;
      const W w = static_cast<W>(v);
      const W lo = static_cast<W>(std::numeric_limits<U>::lowest());
      const W hi = static_cast<W>(std::numeric_limits<U>::max());
      return static_cast<U>(std::clamp(w, lo, hi));
    }
  }
}

template <class U, class T>
DataPtr convert_to(const Volume<T>& in, const ConvertOptions& o) {
  auto out = std::make_shared<Volume<U>>(Volume<U>::uninitialized(in.grid()));
  const T* s = in.data();
  U* d = out->data();
  const int64_t n = in.size();
  double scale = 1.0, lo = 0.0, target_lo = 0.0;
  if (o.mode == ConvertMode::Rescale && n > 0) {
    auto [mn, mx] = std::minmax_element(s, s + n);
    lo = static_cast<double>(*mn);
    const double range = static_cast<double>(*mx) - lo;
    double t_lo = 0.0, t_hi = 1.0;
    if constexpr (!std::is_floating_point_v<U>) {
      t_lo = static_cast<double>(std::numeric_limits<U>::lowest());
      t_hi = static_cast<double>(std::numeric_limits<U>::max());
    }
    target_lo = t_lo;
    scale = range > 0 ? (t_hi - t_lo) / range : 0.0;
  }
  const int64_t slab = std::max<int64_t>(1, in.nx() * in.ny());
  parallel_for(0, in.nz(), o.threads, [&](int64_t z0, int64_t z1) {
    for (int64_t i = z0 * slab; i < z1 * slab; ++i) {
      if (o.mode == ConvertMode::Rescale) {
        d[i] = clamp_cast<U>(target_lo + (static_cast<double>(s[i]) - lo) * scale);
      } else {
        d[i] = clamp_cast<U>(s[i]);
      }
    }
    o.interrupter.check(static_cast<double>(z1) / static_cast<double>(std::max<int64_t>(1, in.nz())));
  });
  return out;
}

}  // namespace

DataPtr convert_volume_type(const DataObject& input, const ConvertOptions& o) {
  return visit_volume(input, "input", [&](const auto& v) -> DataPtr {
    if (o.dtype == "uint8") return convert_to<uint8_t>(v, o);
    if (o.dtype == "uint16") return convert_to<uint16_t>(v, o);
    if (o.dtype == "uint32") return convert_to<uint32_t>(v, o);
    if (o.dtype == "int32") return convert_to<int32_t>(v, o);
    if (o.dtype == "float32") return convert_to<float>(v, o);
    if (o.dtype == "float64") return convert_to<double>(v, o);
    throw InputError("unknown dtype '" + o.dtype +
                     "'; expected uint8, uint16, uint32, int32, float32 or float64");
  });
}

DataPtr crop_volume(const DataObject& input, const Dims& begin, const Dims& size) {
  return visit_volume(input, "input", [&](const auto& v) -> DataPtr {
    using T = typename std::decay_t<decltype(v)>::value_type;
    Dims b{}, e{};
    for (int a = 0; a < 3; ++a) {
      b[a] = std::clamp<int64_t>(begin[a], 0, v.dims()[a]);
      e[a] = std::clamp<int64_t>(begin[a] + size[a], 0, v.dims()[a]);
      if (e[a] <= b[a]) {
        throw InputError("crop box is empty along " + std::string(1, "xyz"[a]) + " (volume has " +
                         std::to_string(v.dims()[a]) + " voxels)");
      }
    }
    Grid g = v.grid();
    g.dims = {e[0] - b[0], e[1] - b[1], e[2] - b[2]};
    g.origin = v.grid().position(static_cast<double>(b[0]), static_cast<double>(b[1]), static_cast<double>(b[2]));
    auto out = std::make_shared<Volume<T>>(Volume<T>::uninitialized(g));
    for (int64_t z = 0; z < g.dims[2]; ++z)
      for (int64_t y = 0; y < g.dims[1]; ++y)
        std::copy_n(&v(b[0], b[1] + y, b[2] + z), g.dims[0], &(*out)(0, y, z));
    return out;
  });
}

}  // namespace skel::volume
