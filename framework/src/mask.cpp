#include "skel/mask.hpp"
#include "skel/out_of_core.hpp"

#include <algorithm>
#include <limits>
#include <type_traits>

#include "skel/error.hpp"

namespace skel {

namespace {

template <class T>
std::string not_binary_message(const std::string& what, T lo, T hi) {
  std::string m = what + ": a mask holds 0 and 1, but this volume holds values from " + std::to_string(lo) + " to " +
                  std::to_string(hi) + " (a grey or label image?); every voxel > 0 is taken as object";
  if (lo > 0) m += ", here all of them";
  return m + " (segmentation.threshold makes a mask)";
}

// Smallest and largest value of v[0..n): one pass of plain min/max reductions (vectorised).
template <class T>
void min_max(const T* v, int64_t n, T& lo, T& hi) {
  T a = std::numeric_limits<T>::max(), b = std::numeric_limits<T>::lowest();
  for (int64_t i = 0; i < n; ++i) {
    a = v[i] < a ? v[i] : a;
    b = v[i] > b ? v[i] : b;
  }
  lo = a;
  hi = b;
}

}  // namespace

VolumeU8 to_mask(const DataObject& data, const std::string& what, std::string* warning) {
  return visit_volume(data, what, [&](const auto& v) -> VolumeU8 {
    using T = typename std::decay_t<decltype(v)>::value_type;
    if constexpr (std::is_floating_point_v<T>) {
      throw InputError(what + ": expected a binary mask (integer volume, voxel > 0 is object), got " + v.type_id() +
                       "; threshold it first");
    } else {
      VolumeU8 out = VolumeU8::uninitialized(v.grid());
      const T* src = v.data();
      uint8_t* dst = out.data();
      const int64_t n = v.size();
      T lo = 0, hi = 0;
      // Blocks that stay in cache: the check reads what the conversion just read.
      constexpr int64_t block = int64_t{1} << 16;
      if (n > 0) lo = hi = src[0];
      for (int64_t b = 0; b < n; b += block) {
        const int64_t e = std::min(n, b + block);
        for (int64_t i = b; i < e; ++i) dst[i] = src[i] > 0 ? 1 : 0;
        if (warning) {
          T a, z;
          min_max(src + b, e - b, a, z);
          lo = std::min(lo, a);
          hi = std::max(hi, z);
        }
      }
      if (warning) {
        warning->clear();
        if (n > 0 && (lo < 0 || hi > 1)) *warning = not_binary_message(what, lo, hi);
      }
      return out;
    }
  });
}

std::shared_ptr<const VolumeU8> shared_mask(const DataPtr& data, const std::string& what, std::string* warning) {
  if (!data) throw InputError(what + ": no data");
  if (auto u8 = std::dynamic_pointer_cast<const VolumeU8>(data)) {
    if (warning) {
      warning->clear();
      uint8_t lo = 0, hi = 0;
      if (u8->size() > 0) min_max(u8->data(), u8->size(), lo, hi);
      if (hi > 1) *warning = not_binary_message(what, lo, hi);
    }
    return u8;
  }
  return std::make_shared<const VolumeU8>(to_mask(*data, what, warning));
}

VolumeU8 read_mask_block(const DataObject& data, const Dims& begin, const Dims& size, const std::string& what) {
  return visit_voxel_type(data.type_id(), what, [&](auto tag) {
    using T = decltype(tag);
    return to_mask(read_block<T>(data, begin, size, what), what);
  });
}

}  // namespace skel
