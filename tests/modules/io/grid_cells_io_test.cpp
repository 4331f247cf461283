// Grid cell complexes in HDF5 files: round trip (bytes, grid), the encoding attribute in `skelflow info`'s
// description, the modules io.write_cells / io.read_cells, and clear errors for files that are not a
// complex.
#include <gtest/gtest.h>

#include <filesystem>
#include <memory>
#include <random>

#include "io/grid_cells_io.hpp"
#include "io/hdf5_volume.hpp"
#include "io/volume_format.hpp"
#include "skel/run_module.hpp"

namespace fs = std::filesystem;
using namespace skel;

namespace {

fs::path scratch() {
  static fs::path d = [] {
    const auto* info = ::testing::UnitTest::GetInstance()->current_test_info();
    const std::string name = info ? std::string(info->test_suite_name()) + "." + info->name() : "cells";
    fs::path p = fs::path(SKEL_BINARY_DIR) / "tests" / "scratch" / "grid_cells_io" / name;
    fs::remove_all(p);
    fs::create_directories(p);
    return p;
  }();
  return d;
}

GridCells random_complex(uint32_t seed) {
  std::mt19937 rng(seed);
  VolumeU8 m(Grid(Dims{7, 5, 6}, {0.5, 0.25, 2.0}, {1.0, -2.0, 3.5}, "mm"), 0);
  for (int64_t i = 0; i < m.size(); ++i) m[i] = rng() % 3 == 0 ? 1 : 0;
  return GridCells::from_mask(m);
}

TEST(GridCellsIO, RoundTripKeepsCellsAndGrid) {
  for (uint32_t seed = 0; seed < 4; ++seed) {
    const GridCells c = random_complex(seed);
    const fs::path f = scratch() / ("c" + std::to_string(seed) + ".h5");
    io::write_grid_cells(f, c, io::kGridCellsDataset, static_cast<int>(seed % 2));
    const GridCells r = io::read_grid_cells(f);
    EXPECT_TRUE(r == c) << seed;
    EXPECT_EQ(r.grid().unit, "mm");
    EXPECT_EQ(r.euler(), c.euler());
    // Any HDF5 reader sees a uint8 volume on the lattice of voxel corners.
    const io::VolumeInfo i = io::read_volume_info(f, "/cells");
    EXPECT_EQ(i.dtype, "uint8");
    EXPECT_EQ(i.dims, (Dims{8, 6, 7}));
    EXPECT_DOUBLE_EQ(i.origin[0], 1.0 - 0.25);
    EXPECT_EQ(io::read_string_attribute(f, "/cells", "encoding"), GridCells::kEncoding);
    EXPECT_NE(io::describe_file(f).find("encoding: skelflow.grid_cells.v1"), std::string::npos) << io::describe_file(f);
    EXPECT_NE(io::describe_volume_file(f).find("skelflow.grid_cells.v1"), std::string::npos);
  }
}

TEST(GridCellsIO, RefusesFilesThatAreNotAComplex) {
  const fs::path plain = scratch() / "plain.h5";
  io::write_volume(plain, VolumeU8(Dims{3, 3, 3}, 1), "/cells");
  try {
    (void)io::read_grid_cells(plain);
    FAIL() << "no encoding accepted";
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("plain.h5: dataset '/cells' is not a grid cell complex (attribute 'encoding' is absent"),
              std::string::npos)
        << e.what();
  }
  // Bits of a 1-cell without its 0-cells: not a complex.
  const fs::path open = scratch() / "open.h5";
  io::write_volume(open, VolumeU8(Dims{3, 3, 3}, 0x02), "/cells");
  io::write_string_attribute(open, "/cells", "encoding", GridCells::kEncoding);
  try {
    (void)io::read_grid_cells(open);
    FAIL() << "an open complex accepted";
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("not a cell complex: cell (1, 0, 0) lacks its face (0, 0, 0)"), std::string::npos) << e.what();
  }
  // Cells beyond the box: the last lattice plane may hold only cells with even coordinates there.
  const fs::path outside = scratch() / "outside.h5";
  VolumeU8 o(Dims{2, 2, 2}, 0);
  o(1, 0, 0) = 0x01 | 0x02;
  io::write_volume(outside, o, "/cells");
  io::write_string_attribute(outside, "/cells", "encoding", GridCells::kEncoding);
  EXPECT_THROW((void)io::read_grid_cells(outside), InputError);
  EXPECT_THROW((void)io::read_grid_cells(scratch() / "missing.h5"), InputError);
  EXPECT_THROW((void)io::read_grid_cells(plain, "/nothing"), InputError);
}

TEST(GridCellsIO, ModulesWriteAndRead) {
  auto c = std::make_shared<GridCells>(random_complex(9));
  const fs::path f = scratch() / "m.h5";
  run_module("io.write_cells", {{"cells", c}}, {{"path", ParamValue(f.string())}});
  ASSERT_TRUE(fs::exists(f));
  const ModuleRunResult r = run_module("io.read_cells", {}, {{"path", ParamValue(f.string())}});
  EXPECT_TRUE(*r.get<GridCells>("cells") == *c);
  EXPECT_THROW(run_module("io.read_cells", {}, {{"path", ParamValue((scratch() / "none.h5").string())}}), InputError);
}

}  // namespace
