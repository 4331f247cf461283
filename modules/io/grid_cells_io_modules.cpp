// io.write_cells / io.read_cells: grid cell complexes in HDF5 files (grid_cells_io.hpp).
#include "io/grid_cells_io.hpp"
#include "io/names.hpp"
#include "skel/module.hpp"

namespace skel::io {
namespace {

struct CellsWriteOptions {
  std::string dataset = kGridCellsDataset;
  int compression = 1;
  int threads = 0;
};

class WriteCells final : public Module {
public:
  static ModuleSpec spec() {
    return ModuleSpec(names::write_cells, "Write a grid cell complex to an HDF5 file")
        .input<GridCells>("cells", "the grid cell complex (e.g. a grid cell skeleton)")
        .path("path", "", PathRole::Output, "HDF5 file to create; written to a temporary file and renamed when the run succeeds")
        .extensions({".h5", ".hdf5"})
        .param("dataset", &CellsWriteOptions::dataset, "dataset name (groups are created)")
        .param("compression", &CellsWriteOptions::compression, "deflate level (0 = none)").range(0, 9)
        .details(R"(The complex's lattice bytes as a uint8 dataset of shape [z+1][y+1][x+1]: one byte per
voxel corner p, bit a+2b+4c set when cell 2p+(a,b,c) (Khalimsky coordinates) is in the complex - bit 0
the 0-cell, bits 1, 2, 4 the 1-cells along +x, +y, +z, bits 3, 5, 6 the 2-cells, bit 7 the 3-cell (voxel
p). Attributes: `spacing`, `origin` (lattice point 0 = the lower corner of voxel 0), `unit`, and
`encoding` naming this layout, which marks the dataset as a complex (io.read_cells refuses datasets
without it; `skelflow info` prints it). Memory: one copy of the lattice (1 byte per voxel corner).)");
  }
  void run(RunContext& ctx) override {
    const auto o = ctx.options<CellsWriteOptions>();
    write_grid_cells(ctx.output_path("path"), *ctx.input<GridCells>("cells"), o.dataset, o.compression, o.threads);
  }
};
SKEL_REGISTER_MODULE(WriteCells);

struct CellsReadOptions {
  std::string dataset = kGridCellsDataset;
};

class ReadCells final : public Module {
public:
  static ModuleSpec spec() {
    return ModuleSpec(names::read_cells, "Read a grid cell complex from an HDF5 file (written by io.write_cells)")
        .output<GridCells>("cells", "the grid cell complex")
        .path("path", "", PathRole::Input, "HDF5 file; relative to the pipeline's folder")
        .extensions({".h5", ".hdf5"})
        .param("dataset", &CellsReadOptions::dataset, "dataset name")
        .details(R"(Reads the layout io.write_cells writes (a uint8 dataset with the attribute `encoding`).
Refused with the file's name: a missing dataset, another voxel type, a missing or different `encoding`,
bits of cells outside the box, and bytes that are not a cell complex (a cell without one of its faces).
Memory: the complex (1 byte per voxel corner) and the dataset while reading (1 byte per voxel corner).)");
  }
  void run(RunContext& ctx) override {
    ctx.output("cells", read_grid_cells(ctx.input_path("path"), ctx.options<CellsReadOptions>().dataset));
  }
};
SKEL_REGISTER_MODULE(ReadCells);

}  // namespace
}  // namespace skel::io
