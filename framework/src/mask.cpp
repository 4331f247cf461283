#include "skel/mask.hpp"

#include <type_traits>

#include "skel/error.hpp"

namespace skel {

VolumeU8 to_mask(const DataObject& data, const std::string& what) {
  return visit_volume(data, what, [&](const auto& v) -> VolumeU8 {
    using T = typename std::decay_t<decltype(v)>::value_type;
    if constexpr (std::is_floating_point_v<T>) {
      throw InputError(what + ": expected a binary mask (integer volume, voxel > 0 is object), got " + v.type_id() +
                       "; threshold it first");
    } else {
      VolumeU8 out = VolumeU8::uninitialized(v.grid());
      const T* src = v.data();
      uint8_t* dst = out.data();
      for (int64_t i = 0, n = v.size(); i < n; ++i) dst[i] = src[i] > 0 ? 1 : 0;
      return out;
    }
  });
}

std::shared_ptr<const VolumeU8> shared_mask(const DataPtr& data, const std::string& what) {
  if (!data) throw InputError(what + ": no data");
  if (auto u8 = std::dynamic_pointer_cast<const VolumeU8>(data)) return u8;
  return std::make_shared<const VolumeU8>(to_mask(*data, what));
}

}  // namespace skel
