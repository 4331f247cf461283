#include "skel/grid_cells.hpp"

#include <sstream>

#include "skel/parallel.hpp"

namespace skel {

GridCells::GridCells(const Grid& voxel_grid) : grid_(voxel_grid) {
  grid_.validate();
  const Dims l = lattice_dims();
  lx_ = l[0];
  ly_ = l[1];
  bits_.assign(static_cast<size_t>(l[0] * l[1] * l[2]), 0);
}

GridCells GridCells::from_mask(const VolumeU8& mask, int threads) {
  GridCells g(mask.grid());
  // Bits a lattice point gets from the voxel at offset -d (d = dx + 2dy + 4dz, per axis 0 or 1): along an
  // axis where the voxel lies below (d = 1) the point is the voxel's upper corner, so only the cells with
  // an even (0) coordinate offset on that axis belong to the voxel's closed cube.
  uint8_t from[8]{};
  for (int d = 0; d < 8; ++d)
    for (int b = 0; b < 8; ++b)
      if ((b & d) == 0) from[d] = static_cast<uint8_t>(from[d] | (1u << b));
  const Dims ld = g.lattice_dims();
  const int64_t nx = mask.nx(), ny = mask.ny(), nz = mask.nz();
  const uint8_t* m = mask.data();
  parallel_for(0, ld[2], threads, [&](int64_t k0, int64_t k1) {
    for (int64_t k = k0; k < k1; ++k)
      for (int64_t j = 0; j < ld[1]; ++j)
        for (int64_t i = 0; i < ld[0]; ++i) {
          uint8_t v = 0;
          for (int d = 0; d < 8; ++d) {
            const int64_t x = i - (d & 1), y = j - ((d >> 1) & 1), z = k - ((d >> 2) & 1);
            if (x < 0 || y < 0 || z < 0 || x >= nx || y >= ny || z >= nz) continue;
            if (m[x + nx * (y + ny * z)]) v = static_cast<uint8_t>(v | from[d]);
          }
          g.bits_[static_cast<size_t>(i + ld[0] * (j + ld[1] * k))] = v;
        }
  });
  return g;
}

std::array<int64_t, 4> GridCells::counts() const {
  std::array<int64_t, 4> c{};
  for (uint8_t b : bits_)
    for (int d = 0; d < 4; ++d) c[static_cast<size_t>(d)] += __builtin_popcount(static_cast<unsigned>(b & kDimMask[d]));
  return c;
}

int64_t GridCells::euler() const {
  const auto c = counts();
  return c[0] - c[1] + c[2] - c[3];
}

std::string GridCells::describe() const {
  const auto c = counts();
  std::ostringstream s;
  s << "cells " << grid_.dims[0] << "x" << grid_.dims[1] << "x" << grid_.dims[2] << " voxels, " << c[0] << " 0-cells, "
    << c[1] << " 1-cells, " << c[2] << " 2-cells, " << c[3] << " 3-cells, euler " << (c[0] - c[1] + c[2] - c[3])
    << ", spacing " << grid_.spacing[0] << " " << grid_.spacing[1] << " " << grid_.spacing[2] << " " << grid_.unit;
  return s.str();
}

}  // namespace skel
