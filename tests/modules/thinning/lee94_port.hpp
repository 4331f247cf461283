#pragma once
// A literal C++ port of scikit-image 0.19's _skeletonize_3d_cy.pyx (itself a port of Fiji's
// Skeletonize3D): full raster scans, the 27-byte neighbourhood array in skimage's numbering, the
// Euler LUT test octant by octant and the recursive octree labelling. Slow and independent of
// thinning::thin_lee94 (shares no code with it); the fast implementation is tested against it.
// The octree_labeling and is_Euler_invariant bodies were generated mechanically from the .pyx.
#include <cstdint>
#include <cstring>
#include <vector>

#include "skel/volume.hpp"

namespace skel::test::lee94_port {

inline void octree_labeling(int octant, int label, uint8_t cube[26]) {
  if (octant == 1) {
    if (cube[0] == 1) {
      cube[0] = static_cast<uint8_t>(label);
    }
    if (cube[1] == 1) {
      cube[1] = static_cast<uint8_t>(label);
      octree_labeling(2, label, cube);
    }
    if (cube[3] == 1) {
      cube[3] = static_cast<uint8_t>(label);
      octree_labeling(3, label, cube);
    }
    if (cube[4] == 1) {
      cube[4] = static_cast<uint8_t>(label);
      octree_labeling(2, label, cube);
      octree_labeling(3, label, cube);
      octree_labeling(4, label, cube);
    }
    if (cube[9] == 1) {
      cube[9] = static_cast<uint8_t>(label);
      octree_labeling(5, label, cube);
    }
    if (cube[10] == 1) {
      cube[10] = static_cast<uint8_t>(label);
      octree_labeling(2, label, cube);
      octree_labeling(5, label, cube);
      octree_labeling(6, label, cube);
    }
    if (cube[12] == 1) {
      cube[12] = static_cast<uint8_t>(label);
      octree_labeling(3, label, cube);
      octree_labeling(5, label, cube);
      octree_labeling(7, label, cube);
    }
  }
  if (octant == 2) {
    if (cube[1] == 1) {
      cube[1] = static_cast<uint8_t>(label);
      octree_labeling(1, label, cube);
    }
    if (cube[4] == 1) {
      cube[4] = static_cast<uint8_t>(label);
      octree_labeling(1, label, cube);
      octree_labeling(3, label, cube);
      octree_labeling(4, label, cube);
    }
    if (cube[10] == 1) {
      cube[10] = static_cast<uint8_t>(label);
      octree_labeling(1, label, cube);
      octree_labeling(5, label, cube);
      octree_labeling(6, label, cube);
    }
    if (cube[2] == 1) {
      cube[2] = static_cast<uint8_t>(label);
    }
    if (cube[5] == 1) {
      cube[5] = static_cast<uint8_t>(label);
      octree_labeling(4, label, cube);
    }
    if (cube[11] == 1) {
      cube[11] = static_cast<uint8_t>(label);
      octree_labeling(6, label, cube);
    }
    if (cube[13] == 1) {
      cube[13] = static_cast<uint8_t>(label);
      octree_labeling(4, label, cube);
      octree_labeling(6, label, cube);
      octree_labeling(8, label, cube);
    }
  }
  if (octant == 3) {
    if (cube[3] == 1) {
      cube[3] = static_cast<uint8_t>(label);
      octree_labeling(1, label, cube);
    }
    if (cube[4] == 1) {
      cube[4] = static_cast<uint8_t>(label);
      octree_labeling(1, label, cube);
      octree_labeling(2, label, cube);
      octree_labeling(4, label, cube);
    }
    if (cube[12] == 1) {
      cube[12] = static_cast<uint8_t>(label);
      octree_labeling(1, label, cube);
      octree_labeling(5, label, cube);
      octree_labeling(7, label, cube);
    }
    if (cube[6] == 1) {
      cube[6] = static_cast<uint8_t>(label);
    }
    if (cube[7] == 1) {
      cube[7] = static_cast<uint8_t>(label);
      octree_labeling(4, label, cube);
    }
    if (cube[14] == 1) {
      cube[14] = static_cast<uint8_t>(label);
      octree_labeling(7, label, cube);
    }
    if (cube[15] == 1) {
      cube[15] = static_cast<uint8_t>(label);
      octree_labeling(4, label, cube);
      octree_labeling(7, label, cube);
      octree_labeling(8, label, cube);
    }
  }
  if (octant == 4) {
    if (cube[4] == 1) {
      cube[4] = static_cast<uint8_t>(label);
      octree_labeling(1, label, cube);
      octree_labeling(2, label, cube);
      octree_labeling(3, label, cube);
    }
    if (cube[5] == 1) {
      cube[5] = static_cast<uint8_t>(label);
      octree_labeling(2, label, cube);
    }
    if (cube[13] == 1) {
      cube[13] = static_cast<uint8_t>(label);
      octree_labeling(2, label, cube);
      octree_labeling(6, label, cube);
      octree_labeling(8, label, cube);
    }
    if (cube[7] == 1) {
      cube[7] = static_cast<uint8_t>(label);
      octree_labeling(3, label, cube);
    }
    if (cube[15] == 1) {
      cube[15] = static_cast<uint8_t>(label);
      octree_labeling(3, label, cube);
      octree_labeling(7, label, cube);
      octree_labeling(8, label, cube);
    }
    if (cube[8] == 1) {
      cube[8] = static_cast<uint8_t>(label);
    }
    if (cube[16] == 1) {
      cube[16] = static_cast<uint8_t>(label);
      octree_labeling(8, label, cube);
    }
  }
  if (octant == 5) {
    if (cube[9] == 1) {
      cube[9] = static_cast<uint8_t>(label);
      octree_labeling(1, label, cube);
    }
    if (cube[10] == 1) {
      cube[10] = static_cast<uint8_t>(label);
      octree_labeling(1, label, cube);
      octree_labeling(2, label, cube);
      octree_labeling(6, label, cube);
    }
    if (cube[12] == 1) {
      cube[12] = static_cast<uint8_t>(label);
      octree_labeling(1, label, cube);
      octree_labeling(3, label, cube);
      octree_labeling(7, label, cube);
    }
    if (cube[17] == 1) {
      cube[17] = static_cast<uint8_t>(label);
    }
    if (cube[18] == 1) {
      cube[18] = static_cast<uint8_t>(label);
      octree_labeling(6, label, cube);
    }
    if (cube[20] == 1) {
      cube[20] = static_cast<uint8_t>(label);
      octree_labeling(7, label, cube);
    }
    if (cube[21] == 1) {
      cube[21] = static_cast<uint8_t>(label);
      octree_labeling(6, label, cube);
      octree_labeling(7, label, cube);
      octree_labeling(8, label, cube);
    }
  }
  if (octant == 6) {
    if (cube[10] == 1) {
      cube[10] = static_cast<uint8_t>(label);
      octree_labeling(1, label, cube);
      octree_labeling(2, label, cube);
      octree_labeling(5, label, cube);
    }
    if (cube[11] == 1) {
      cube[11] = static_cast<uint8_t>(label);
      octree_labeling(2, label, cube);
    }
    if (cube[13] == 1) {
      cube[13] = static_cast<uint8_t>(label);
      octree_labeling(2, label, cube);
      octree_labeling(4, label, cube);
      octree_labeling(8, label, cube);
    }
    if (cube[18] == 1) {
      cube[18] = static_cast<uint8_t>(label);
      octree_labeling(5, label, cube);
    }
    if (cube[21] == 1) {
      cube[21] = static_cast<uint8_t>(label);
      octree_labeling(5, label, cube);
      octree_labeling(7, label, cube);
      octree_labeling(8, label, cube);
    }
    if (cube[19] == 1) {
      cube[19] = static_cast<uint8_t>(label);
    }
    if (cube[22] == 1) {
      cube[22] = static_cast<uint8_t>(label);
      octree_labeling(8, label, cube);
    }
  }
  if (octant == 7) {
    if (cube[12] == 1) {
      cube[12] = static_cast<uint8_t>(label);
      octree_labeling(1, label, cube);
      octree_labeling(3, label, cube);
      octree_labeling(5, label, cube);
    }
    if (cube[14] == 1) {
      cube[14] = static_cast<uint8_t>(label);
      octree_labeling(3, label, cube);
    }
    if (cube[15] == 1) {
      cube[15] = static_cast<uint8_t>(label);
      octree_labeling(3, label, cube);
      octree_labeling(4, label, cube);
      octree_labeling(8, label, cube);
    }
    if (cube[20] == 1) {
      cube[20] = static_cast<uint8_t>(label);
      octree_labeling(5, label, cube);
    }
    if (cube[21] == 1) {
      cube[21] = static_cast<uint8_t>(label);
      octree_labeling(5, label, cube);
      octree_labeling(6, label, cube);
      octree_labeling(8, label, cube);
    }
    if (cube[23] == 1) {
      cube[23] = static_cast<uint8_t>(label);
    }
    if (cube[24] == 1) {
      cube[24] = static_cast<uint8_t>(label);
      octree_labeling(8, label, cube);
    }
  }
  if (octant == 8) {
    if (cube[13] == 1) {
      cube[13] = static_cast<uint8_t>(label);
      octree_labeling(2, label, cube);
      octree_labeling(4, label, cube);
      octree_labeling(6, label, cube);
    }
    if (cube[15] == 1) {
      cube[15] = static_cast<uint8_t>(label);
      octree_labeling(3, label, cube);
      octree_labeling(4, label, cube);
      octree_labeling(7, label, cube);
    }
    if (cube[16] == 1) {
      cube[16] = static_cast<uint8_t>(label);
      octree_labeling(4, label, cube);
    }
    if (cube[21] == 1) {
      cube[21] = static_cast<uint8_t>(label);
      octree_labeling(5, label, cube);
      octree_labeling(6, label, cube);
      octree_labeling(7, label, cube);
    }
    if (cube[22] == 1) {
      cube[22] = static_cast<uint8_t>(label);
      octree_labeling(6, label, cube);
    }
    if (cube[24] == 1) {
      cube[24] = static_cast<uint8_t>(label);
      octree_labeling(7, label, cube);
    }
    if (cube[25] == 1) {
      cube[25] = static_cast<uint8_t>(label);
    }
  }
}
inline bool is_Euler_invariant(const uint8_t neighbors[27], const int lut[256]) {
  int n, euler_char = 0;
  n = 1;
  if (neighbors[2] == 1) n |= 128;
  if (neighbors[1] == 1) n |= 64;
  if (neighbors[11] == 1) n |= 32;
  if (neighbors[10] == 1) n |= 16;
  if (neighbors[5] == 1) n |= 8;
  if (neighbors[4] == 1) n |= 4;
  if (neighbors[14] == 1) n |= 2;
  euler_char += lut[n];
  n = 1;
  if (neighbors[0] == 1) n |= 128;
  if (neighbors[9] == 1) n |= 64;
  if (neighbors[3] == 1) n |= 32;
  if (neighbors[12] == 1) n |= 16;
  if (neighbors[1] == 1) n |= 8;
  if (neighbors[10] == 1) n |= 4;
  if (neighbors[4] == 1) n |= 2;
  euler_char += lut[n];
  n = 1;
  if (neighbors[8] == 1) n |= 128;
  if (neighbors[7] == 1) n |= 64;
  if (neighbors[17] == 1) n |= 32;
  if (neighbors[16] == 1) n |= 16;
  if (neighbors[5] == 1) n |= 8;
  if (neighbors[4] == 1) n |= 4;
  if (neighbors[14] == 1) n |= 2;
  euler_char += lut[n];
  n = 1;
  if (neighbors[6] == 1) n |= 128;
  if (neighbors[15] == 1) n |= 64;
  if (neighbors[7] == 1) n |= 32;
  if (neighbors[16] == 1) n |= 16;
  if (neighbors[3] == 1) n |= 8;
  if (neighbors[12] == 1) n |= 4;
  if (neighbors[4] == 1) n |= 2;
  euler_char += lut[n];
  n = 1;
  if (neighbors[20] == 1) n |= 128;
  if (neighbors[23] == 1) n |= 64;
  if (neighbors[19] == 1) n |= 32;
  if (neighbors[22] == 1) n |= 16;
  if (neighbors[11] == 1) n |= 8;
  if (neighbors[14] == 1) n |= 4;
  if (neighbors[10] == 1) n |= 2;
  euler_char += lut[n];
  n = 1;
  if (neighbors[18] == 1) n |= 128;
  if (neighbors[21] == 1) n |= 64;
  if (neighbors[9] == 1) n |= 32;
  if (neighbors[12] == 1) n |= 16;
  if (neighbors[19] == 1) n |= 8;
  if (neighbors[22] == 1) n |= 4;
  if (neighbors[10] == 1) n |= 2;
  euler_char += lut[n];
  n = 1;
  if (neighbors[26] == 1) n |= 128;
  if (neighbors[23] == 1) n |= 64;
  if (neighbors[17] == 1) n |= 32;
  if (neighbors[14] == 1) n |= 16;
  if (neighbors[25] == 1) n |= 8;
  if (neighbors[22] == 1) n |= 4;
  if (neighbors[16] == 1) n |= 2;
  euler_char += lut[n];
  n = 1;
  if (neighbors[24] == 1) n |= 128;
  if (neighbors[25] == 1) n |= 64;
  if (neighbors[15] == 1) n |= 32;
  if (neighbors[16] == 1) n |= 16;
  if (neighbors[21] == 1) n |= 8;
  if (neighbors[22] == 1) n |= 4;
  if (neighbors[12] == 1) n |= 2;
  euler_char += lut[n];
  return euler_char == 0;
}

inline std::vector<int> euler_lut() {
  const int arr[128] = {1, -1, -1, 1, -3, -1, -1, 1, -1, 1, 1, -1, 3, 1, 1, -1, -3, -1,
                        3, 1, 1, -1, 3, 1, -1, 1, 1, -1, 3, 1, 1, -1, -3, 3, -1, 1, 1,
                        3, -1, 1, -1, 1, 1, -1, 3, 1, 1, -1, 1, 3, 3, 1, 5, 3, 3, 1,
                        -1, 1, 1, -1, 3, 1, 1, -1, -7, -1, -1, 1, -3, -1, -1, 1, -1,
                        1, 1, -1, 3, 1, 1, -1, -3, -1, 3, 1, 1, -1, 3, 1, -1, 1, 1,
                        -1, 3, 1, 1, -1, -3, 3, -1, 1, 1, 3, -1, 1, -1, 1, 1, -1, 3,
                        1, 1, -1, 1, 3, 3, 1, 5, 3, 3, 1, -1, 1, 1, -1, 3, 1, 1, -1};
  std::vector<int> lut(256, 0);
  for (int i = 0; i < 128; ++i) lut[static_cast<size_t>(2 * i + 1)] = arr[i];
  return lut;
}

inline bool is_endpoint(const uint8_t neighbors[27]) {
  int s = 0;
  for (int j = 0; j < 27; ++j) s += neighbors[j];
  return s == 2;
}

inline bool is_simple_point(const uint8_t neighbors[27]) {
  uint8_t cube[26];
  std::memcpy(cube, neighbors, 13);
  std::memcpy(cube + 13, neighbors + 14, 13);
  int label = 2;
  for (int i = 0; i < 26; ++i) {
    if (cube[i] == 1) {
      switch (i) {
        case 0: case 1: case 3: case 4: case 9: case 10: case 12: octree_labeling(1, label, cube); break;
        case 2: case 5: case 11: case 13: octree_labeling(2, label, cube); break;
        case 6: case 7: case 14: case 15: octree_labeling(3, label, cube); break;
        case 8: case 16: octree_labeling(4, label, cube); break;
        case 17: case 18: case 20: case 21: octree_labeling(5, label, cube); break;
        case 19: case 22: octree_labeling(6, label, cube); break;
        case 23: case 24: octree_labeling(7, label, cube); break;
        default: octree_labeling(8, label, cube); break;  // i == 25
      }
      label += 1;
      if (label - 2 >= 2) return false;
    }
  }
  return true;
}

// img: a padded [p][r][c] array (p = z, r = y, c = x) of 0/1, dims np, nr, nc.
struct Padded {
  int64_t np = 0, nr = 0, nc = 0;
  std::vector<uint8_t> v;
  uint8_t& operator()(int64_t p, int64_t r, int64_t c) { return v[static_cast<size_t>((p * nr + r) * nc + c)]; }
};

inline void get_neighborhood(Padded& img, int64_t p, int64_t r, int64_t c, uint8_t n[27]) {
  int k = 0;
  for (int dp = -1; dp <= 1; ++dp)
    for (int dc = -1; dc <= 1; ++dc)
      for (int dr = -1; dr <= 1; ++dr) n[k++] = img(p + dp, r + dr, c + dc);
}

// skeletonize_3d on a mask (x fastest = skimage's last axis): pad by one, normalise to 0/1, thin, crop.
inline VolumeU8 skeletonize_3d(const VolumeU8& mask) {
  Padded img;
  img.np = mask.nz() + 2;
  img.nr = mask.ny() + 2;
  img.nc = mask.nx() + 2;
  img.v.assign(static_cast<size_t>(img.np * img.nr * img.nc), 0);
  for (int64_t z = 0; z < mask.nz(); ++z)
    for (int64_t y = 0; y < mask.ny(); ++y)
      for (int64_t x = 0; x < mask.nx(); ++x) img(z + 1, y + 1, x + 1) = mask(x, y, z) != 0;
  const std::vector<int> lut = euler_lut();
  struct Coordinate { int64_t p, r, c; };
  std::vector<Coordinate> simple_border_points;
  uint8_t neighb[27];
  const int borders[6] = {4, 3, 2, 1, 5, 6};
  const int num_borders = img.np == 3 ? 4 : 6;
  int unchanged_borders = 0;
  while (unchanged_borders < num_borders) {
    unchanged_borders = 0;
    for (int j = 0; j < num_borders; ++j) {
      const int curr_border = borders[j];
      simple_border_points.clear();
      for (int64_t p = 1; p < img.np - 1; ++p)
        for (int64_t r = 1; r < img.nr - 1; ++r)
          for (int64_t c = 1; c < img.nc - 1; ++c) {
            if (img(p, r, c) != 1) continue;
            const bool is_border_pt = (curr_border == 1 && img(p, r, c - 1) == 0) ||
                                      (curr_border == 2 && img(p, r, c + 1) == 0) ||
                                      (curr_border == 3 && img(p, r + 1, c) == 0) ||
                                      (curr_border == 4 && img(p, r - 1, c) == 0) ||
                                      (curr_border == 5 && img(p + 1, r, c) == 0) ||
                                      (curr_border == 6 && img(p - 1, r, c) == 0);
            if (!is_border_pt) continue;
            get_neighborhood(img, p, r, c, neighb);
            if (is_endpoint(neighb) || !is_Euler_invariant(neighb, lut.data()) || !is_simple_point(neighb)) continue;
            simple_border_points.push_back({p, r, c});
          }
      bool no_change = true;
      for (const Coordinate& pt : simple_border_points) {
        get_neighborhood(img, pt.p, pt.r, pt.c, neighb);
        if (is_simple_point(neighb)) {
          img(pt.p, pt.r, pt.c) = 0;
          no_change = false;
        }
      }
      if (no_change) unchanged_borders += 1;
    }
  }
  VolumeU8 out(mask.grid(), 0);
  for (int64_t z = 0; z < mask.nz(); ++z)
    for (int64_t y = 0; y < mask.ny(); ++y)
      for (int64_t x = 0; x < mask.nx(); ++x) out(x, y, z) = img(z + 1, y + 1, x + 1);
  return out;
}

}  // namespace skel::test::lee94_port
