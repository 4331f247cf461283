#pragma once
// GridCells: a grid cell complex (thesis §2.3.1 "The Grid Cell Model"), type id "cells".
//
// A voxel object is a cell complex of closed unit cubes: every voxel is a 3-cell with its six faces
// (2-cells), twelve edges (1-cells) and eight vertices (0-cells), shared with its neighbours. Cells are
// addressed by Khalimsky coordinates k = (kx, ky, kz), 0 <= k <= 2·dims: voxel (x, y, z) is the 3-cell
// (2x+1, 2y+1, 2z+1); a cell's dimension is the number of odd coordinates; it has two cofaces along
// each axis where its coordinate is even and two faces along each axis where it is odd.
//
// Storage: one byte per point of the (X+1)(Y+1)(Z+1) lattice of voxel corners (x fastest, 64-bit
// indices). Lattice point p = (i, j, k) owns the eight cells 2p + (a, b, c), a, b, c in {0, 1}: bit
// a + 2b + 4c says whether that cell is in the complex:
//   bit 0: the 0-cell (vertex) at p          bit 4: the 1-cell along +z
//   bit 1: the 1-cell (edge) along +x        bit 5: the 2-cell (face) in the x-z plane
//   bit 2: the 1-cell along +y               bit 6: the 2-cell in the y-z plane
//   bit 3: the 2-cell in the x-y plane       bit 7: the 3-cell (voxel) (i, j, k)
// So a complex costs (X+1)(Y+1)(Z+1) bytes: 1 byte per voxel plus the lattice's extra faces (1.012
// bytes per voxel at 256³), eight cells per byte. Bits of cells outside [0, 2·dims] are always 0.
// Geometry: the 0-cell at lattice point p lies at the physical position of voxel corner
// origin + (p - 0.5)·spacing (voxel centres at origin + x·spacing, as in Volume).
#include <array>
#include <cstdint>
#include <string>
#include <vector>

#include "skel/data.hpp"
#include "skel/volume.hpp"

namespace skel {

namespace type_ids {
inline constexpr const char* grid_cells = "cells";  // skel::GridCells (declared here, not in data.hpp)
}  // namespace type_ids

class GridCells final : public DataObject {
public:
  GridCells() : GridCells(Grid{}) {}
  // An empty complex over the voxels of `voxel_grid`.
  explicit GridCells(const Grid& voxel_grid);

  // The complex X(P) of a voxel object (mask > 0): every object voxel as a closed cube.
  static GridCells from_mask(const VolumeU8& mask, int threads = 0);

  [[nodiscard]] const Grid& grid() const { return grid_; }
  // Lattice dims (X+1, Y+1, Z+1) and Khalimsky dims (2X+1, 2Y+1, 2Z+1).
  [[nodiscard]] Dims lattice_dims() const { return {grid_.dims[0] + 1, grid_.dims[1] + 1, grid_.dims[2] + 1}; }
  [[nodiscard]] Dims cell_dims() const { return {2 * grid_.dims[0] + 1, 2 * grid_.dims[1] + 1, 2 * grid_.dims[2] + 1}; }
  [[nodiscard]] int64_t lattice_size() const { return static_cast<int64_t>(bits_.size()); }

  [[nodiscard]] bool inside(int64_t kx, int64_t ky, int64_t kz) const {
    return kx >= 0 && ky >= 0 && kz >= 0 && kx <= 2 * grid_.dims[0] && ky <= 2 * grid_.dims[1] && kz <= 2 * grid_.dims[2];
  }
  [[nodiscard]] int64_t lattice_index(int64_t kx, int64_t ky, int64_t kz) const {
    return (kx >> 1) + lx_ * ((ky >> 1) + ly_ * (kz >> 1));
  }
  static constexpr int bit(int64_t kx, int64_t ky, int64_t kz) {
    return static_cast<int>((kx & 1) | ((ky & 1) << 1) | ((kz & 1) << 2));
  }
  // Whether cell k is in the complex (false outside the Khalimsky box).
  [[nodiscard]] bool has(int64_t kx, int64_t ky, int64_t kz) const {
    return inside(kx, ky, kz) && ((bits_[static_cast<size_t>(lattice_index(kx, ky, kz))] >> bit(kx, ky, kz)) & 1);
  }
  // Adds (on = true) or removes cell k; k must be inside.
  void set(int64_t kx, int64_t ky, int64_t kz, bool on) {
    uint8_t& b = bits_[static_cast<size_t>(lattice_index(kx, ky, kz))];
    const auto m = static_cast<uint8_t>(1u << bit(kx, ky, kz));
    b = on ? static_cast<uint8_t>(b | m) : static_cast<uint8_t>(b & ~m);
  }
  // The raw presence bytes (lattice order) for writers and fast scans.
  [[nodiscard]] const std::vector<uint8_t>& bytes_data() const { return bits_; }
  [[nodiscard]] std::vector<uint8_t>& bytes_data() { return bits_; }

  // Number of cells per dimension (c0, c1, c2, c3) and the Euler characteristic c0 - c1 + c2 - c3.
  [[nodiscard]] std::array<int64_t, 4> counts() const;
  [[nodiscard]] int64_t euler() const;

  // Bit masks of a lattice byte by cell dimension.
  static constexpr uint8_t kDimMask[4] = {0x01, 0x16, 0x68, 0x80};
  static constexpr int bit_dimension(int b) { return __builtin_popcount(static_cast<unsigned>(b)); }

  [[nodiscard]] std::string type_id() const override { return type_ids::grid_cells; }
  [[nodiscard]] uint64_t bytes() const override { return bits_.size(); }
  [[nodiscard]] std::string describe() const override;
  [[nodiscard]] std::string physical_unit() const override { return grid_.unit; }

  // The encoding name written with the lattice bytes to files (HDF5 attribute `encoding`).
  static constexpr const char* kEncoding = "skelflow.grid_cells.v1: one byte per voxel corner (x+1)(y+1)(z+1), bit a+2b+4c = cell 2p+(a,b,c)";

  bool operator==(const GridCells& o) const { return grid_ == o.grid_ && bits_ == o.bits_; }

private:
  Grid grid_;
  int64_t lx_ = 1, ly_ = 1;
  std::vector<uint8_t> bits_;
};

}  // namespace skel
