#pragma once
// Bit-parallel 3x3x3 morphology on a 27-bit cube word: bit (dx+1) + 3 (dy+1) + 9 (dz+1) is the voxel
// at offset (dx, dy, dz), the centre is bit 13. A dilation is a few shifts, masked where a shift
// would wrap from one row or plane into the next. Shared by the simple-voxel test and Lee94.
#include <cstdint>

namespace skel::thinning::cube {

constexpr uint32_t kCube = (1u << 27) - 1;
constexpr uint32_t kCentre = 1u << 13;

// The bits whose coordinate along `axis` (0 = x, 1 = y, 2 = z) equals `value` (0, 1, 2).
constexpr uint32_t plane_mask(int axis, int value) {
  uint32_t m = 0;
  for (int c = 0; c < 27; ++c) {
    const int v = axis == 0 ? c % 3 : axis == 1 ? (c / 3) % 3 : c / 9;
    if (v == value) m |= 1u << c;
  }
  return m;
}
constexpr uint32_t kNotX0 = kCube & ~plane_mask(0, 0), kNotX2 = kCube & ~plane_mask(0, 2);
constexpr uint32_t kNotY0 = kCube & ~plane_mask(1, 0), kNotY2 = kCube & ~plane_mask(1, 2);

inline uint32_t dilate26(uint32_t s) {
  s |= ((s << 1) & kNotX0) | ((s >> 1) & kNotX2);
  s |= ((s << 3) & kNotY0) | ((s >> 3) & kNotY2);
  return (s | (s << 9) | (s >> 9)) & kCube;
}
inline uint32_t dilate6(uint32_t s) {
  return (s | ((s << 1) & kNotX0) | ((s >> 1) & kNotX2) | ((s << 3) & kNotY0) | ((s >> 3) & kNotY2) | (s << 9) |
          (s >> 9)) & kCube;
}

}  // namespace skel::thinning::cube
