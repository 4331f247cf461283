// pipelines/grid_cells.yaml runs end to end (fig. 4.2): the rod skeleton is one-dimensional with the
// phantom's Euler characteristic, its meshes have one (simple) or three (detailed) segments per 1-cell,
// the graph has one polyline segment per 1-cell, and every file appears.
#include <gtest/gtest.h>

#include <algorithm>
#include <filesystem>
#include <iostream>
#include <map>
#include <unordered_map>

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

namespace {

// Number of edges of the triangles of `m` by how many triangles share them (1: boundary, 2: manifold,
// more: where plates meet), keyed by the sorted vertex pair.
std::map<int, int64_t> edge_valences(const Mesh& m) {
  std::unordered_map<uint64_t, int> n;
  for (const auto& t : m.triangles)
    for (int i = 0; i < 3; ++i) {
      auto a = static_cast<uint64_t>(t[static_cast<size_t>(i)]), b = static_cast<uint64_t>(t[static_cast<size_t>((i + 1) % 3)]);
      if (a > b) std::swap(a, b);
      ++n[a * (uint64_t{1} << 32) + b];
    }
  std::map<int, int64_t> v;
  for (const auto& [e, c] : n) ++v[std::min(c, 3)];
  return v;
}

}  // namespace

// pipelines/grid_cells_plates.yaml runs end to end (fig. 4.5): the geodesic plate skeletons are sheets
// of 2-cells (t = 67 a part of t = 33), their mesh is mostly a 2-manifold with boundary (edges shared by
// more than two triangles only where plates meet), decimation keeps 2 % of the triangles, and the
// homotopic skeleton (Y_t locked in grid cell thinning) contains Y_t and has the phantom's Euler
// characteristic. The counts are printed for bench/RESULTS.md and docs/meshes.md.
TEST(GridCellsPipeline, PlatesRunEndToEnd) {
  const fs::path out = fs::path(SKEL_BINARY_DIR) / "tests" / "scratch" / "pipelines_grid_cells_plates";
  fs::remove_all(out);
  fs::create_directories(out);
  Pipeline p = Pipeline::load_file(fs::path(SKEL_SOURCE_DIR) / "pipelines" / "grid_cells_plates.yaml");
  Executor ex;
  ExecOptions o;
  o.output_dir = out;
  o.threads = 2;
  o.keep_outputs = true;
  const RunReport r = ex.run(p, o);
  ASSERT_TRUE(r.ok) << r.to_json();
  const fs::path dir = out / "grid_cells";
  for (const char* f : {"plates_100.vtp", "plates_200.vtp", "plates_smooth.vtp", "plates_2pct.vtp", "plates_homotopic.vtp",
                        "plates_100_cells.h5", "plates_homotopic_cells.h5", "plates_100.csv", "plates_200.csv",
                        "plates_thinning.csv"})
    EXPECT_TRUE(fs::exists(dir / f)) << f;
  const GridCells y100 = io::read_grid_cells(dir / "plates_100_cells.h5");
  const auto y200 = std::dynamic_pointer_cast<const GridCells>(ex.output(p, "plates_200", "cells"));
  ASSERT_TRUE(y200);
  const auto c100 = y100.counts(), c200 = y200->counts();
  EXPECT_EQ(c100[3], 0);
  EXPECT_GT(c100[2], 10000);
  EXPECT_GT(c200[2], 1000);
  EXPECT_LT(c200[2], c100[2]);
  for (size_t i = 0; i < y100.bytes_data().size(); ++i)
    ASSERT_EQ(y200->bytes_data()[i] & ~y100.bytes_data()[i], 0) << "Y_67 is not a part of Y_33 at lattice point " << i;

  // Simple geometry: two triangles per 2-cell; mostly a 2-manifold with boundary.
  const Mesh raw = io::read_mesh(dir / "plates_100.vtp", io::MeshFormat::vtp);
  EXPECT_EQ(raw.triangle_count(), 2 * c100[2]);
  const auto val = edge_valences(raw);
  int64_t edges = 0;
  for (const auto& [k, n] : val) edges += n;
  const int64_t over = val.count(3) ? val.at(3) : 0;
  EXPECT_LT(over, edges / 20) << "edges shared by more than two triangles";
  const auto& manifold = Mesh::attribute<int32_t>(raw.triangle_attributes, "manifold");
  const auto all_manifold = std::count(manifold.begin(), manifold.end(), 1);
  EXPECT_GT(all_manifold, raw.triangle_count() * 8 / 10);
  const Mesh smooth = io::read_mesh(dir / "plates_smooth.vtp", io::MeshFormat::vtp);
  EXPECT_EQ(smooth.triangle_count(), raw.triangle_count());
  const Mesh small = io::read_mesh(dir / "plates_2pct.vtp", io::MeshFormat::vtp);
  EXPECT_GT(small.triangle_count(), raw.triangle_count() / 100);
  EXPECT_LT(small.triangle_count(), raw.triangle_count() * 3 / 100);
  std::cout << "plates: Y_33 " << c100[2] << " 2-cells, Y_67 " << c200[2] << " 2-cells; mesh " << raw.triangle_count()
            << " triangles (" << all_manifold << " all-manifold), edges " << edges << " (" << over
            << " with > 2 triangles), decimated " << small.triangle_count() << " triangles\n";

  // The homotopic plate skeleton: Y_33 plus what the topology needs; χ of the phantom.
  const GridCells hom = io::read_grid_cells(dir / "plates_homotopic_cells.h5");
  for (size_t i = 0; i < hom.bytes_data().size(); ++i)
    ASSERT_EQ(y100.bytes_data()[i] & ~hom.bytes_data()[i], 0) << "Y_33 cell removed at lattice point " << i;
  EXPECT_EQ(hom.counts()[3], 0);
  const auto mask = std::dynamic_pointer_cast<const VolumeU8>(ex.output(p, "plates", "mask"));
  ASSERT_TRUE(mask);
  EXPECT_EQ(hom.euler(), analysis::topology(*mask).euler);
}
