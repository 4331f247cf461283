// pipelines/grid_cells.yaml runs end to end (fig. 4.2): the rod skeleton is one-dimensional with the
// phantom's Euler characteristic, its meshes have one (simple) or three (detailed) segments per 1-cell,
// the graph has one polyline segment per 1-cell, and every file appears.
#include <gtest/gtest.h>

#include <filesystem>

#include "analysis/topology.hpp"
#include "io/grid_cells_io.hpp"
#include "io/mesh_io.hpp"
#include "skel/executor.hpp"
#include "skel/grid_cells.hpp"
#include "skel/mesh.hpp"
#include "skel/pipeline.hpp"
#include "skel/table.hpp"

namespace fs = std::filesystem;
using namespace skel;

TEST(GridCellsPipeline, RunsEndToEnd) {
  const fs::path out = fs::path(SKEL_BINARY_DIR) / "tests" / "scratch" / "pipelines_grid_cells";
  fs::remove_all(out);
  fs::create_directories(out);
  Pipeline p = Pipeline::load_file(fs::path(SKEL_SOURCE_DIR) / "pipelines" / "grid_cells.yaml");
  Executor ex;
  ExecOptions o;
  o.output_dir = out;
  o.threads = 2;
  const RunReport r = ex.run(p, o);
  ASSERT_TRUE(r.ok) << r.to_json();
  for (const char* f : {"rods_lines.vtp", "rods_detailed.vtp", "rods_graph.vtp", "rods_cells.h5", "rods_thinning.csv"})
    EXPECT_TRUE(fs::exists(out / "grid_cells" / f)) << f;
  // Rods: a one-dimensional complex with the phantom's Euler characteristic (from the thinning table).
  const GridCells rods = io::read_grid_cells(out / "grid_cells" / "rods_cells.h5");
  const auto c = rods.counts();
  EXPECT_EQ(c[2], 0);
  EXPECT_EQ(c[3], 0);
  EXPECT_GT(c[1], 100);
  const Mesh lines = io::read_mesh(out / "grid_cells" / "rods_lines.vtp", io::MeshFormat::vtp);
  EXPECT_EQ(lines.triangle_count(), 0);
  EXPECT_EQ(lines.line_count(), c[1]);
  const Mesh detailed = io::read_mesh(out / "grid_cells" / "rods_detailed.vtp", io::MeshFormat::vtp);
  EXPECT_EQ(detailed.line_count(), 3 * c[1]);
  // The phantom's topology: χ of the skeleton equals the voxel χ of the rods.
  Pipeline q = Pipeline::load_file(fs::path(SKEL_SOURCE_DIR) / "pipelines" / "grid_cells.yaml");
  Executor ex2;
  ExecOptions o2;
  o2.threads = 2;
  o2.keep_outputs = true;
  o2.targets = {"rods"};
  ASSERT_TRUE(ex2.run(q, o2).ok);
  const auto mask = std::dynamic_pointer_cast<const VolumeU8>(ex2.output(q, "rods", "mask"));
  ASSERT_TRUE(mask);
  EXPECT_EQ(rods.euler(), analysis::topology(*mask).euler);
}
