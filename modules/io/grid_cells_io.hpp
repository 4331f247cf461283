#pragma once
// Grid cell complexes (skel::GridCells) in HDF5 files: the lattice bytes as a uint8 dataset of shape
// [z+1][y+1][x+1] (one byte per voxel corner, bit a+2b+4c = cell 2p+(a,b,c); see skel/grid_cells.hpp),
// with the volume attributes `spacing`, `origin` (the position of lattice point 0, the lower corner of
// voxel 0: voxel origin - spacing/2) and `unit`, and a string attribute `encoding` =
// GridCells::kEncoding that marks the dataset as a complex. Any HDF5 reader sees an ordinary uint8
// volume; `skelflow info` prints the encoding.
#include <filesystem>
#include <string>

#include "skel/grid_cells.hpp"

namespace skel::io {

inline constexpr const char* kGridCellsDataset = "/cells";

// Writes `cells` to `file` (replacing it) as `dataset`; compression = deflate level 0..9.
void write_grid_cells(const std::filesystem::path& file, const GridCells& cells, const std::string& dataset = kGridCellsDataset,
                      int compression = 1, int threads = 0);
// Reads a complex written by write_grid_cells. InputError naming the file when the dataset is missing, is
// not uint8, has no or another `encoding`, has bits of cells outside the complex's box, or is not a cell
// complex (a cell whose face is absent).
GridCells read_grid_cells(const std::filesystem::path& file, const std::string& dataset = kGridCellsDataset);

}  // namespace skel::io
