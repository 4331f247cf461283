// Labels onto skeleton meshes (thesis fig. 6.14: rods and plates coloured per element).
#include <gtest/gtest.h>

#include <set>

#include "analysis/rods_plates.hpp"
#include "geometry/mesh_labels.hpp"
#include "geometry/names.hpp"
#include "geometry/skeleton_to_mesh.hpp"
#include "skel/error.hpp"
#include "skel/run_module.hpp"

using namespace skel;

namespace {
// A one-voxel-thin plate (z = 4) with a rod standing on it.
VolumeU8 plate_and_rod() {
  VolumeU8 s(Dims{24, 24, 20}, 0);
  for (int64_t y = 3; y < 21; ++y)
    for (int64_t x = 3; x < 21; ++x) s(x, y, 4) = 1;
  for (int64_t z = 5; z < 16; ++z) s(10, 12, z) = 1;
  return s;
}
}  // namespace

TEST(MeshLabels, TrianglesTakeThePlateElementAndLinesTheRodElement) {
  const VolumeU8 s = plate_and_rod();
  VolumeF32 d(s.grid(), 1.0f);
  const auto r = analysis::rods_plates_elements(s, s, d);
  ASSERT_EQ(r.table.rows(), 2);
  const int32_t plate = r.table.strings("class")[0] == "plate" ? 1 : 2, rod = 3 - plate;
  Mesh m = geometry::skeleton_to_mesh(s);
  ASSERT_GT(m.triangle_count(), 0);
  ASSERT_GT(m.line_count(), 0);
  geometry::label_mesh(m, r.skeleton_elements, "element");
  EXPECT_TRUE(m.check_invariants().empty());
  for (int32_t t : Mesh::attribute<int32_t>(m.triangle_attributes, "element")) EXPECT_EQ(t, plate);
  for (int32_t l : Mesh::attribute<int32_t>(m.line_attributes, "element")) EXPECT_EQ(l, rod);
  // Every vertex is labelled (voxel vertices directly, centres from their triangle).
  for (int32_t v : Mesh::attribute<int32_t>(m.vertex_attributes, "element")) EXPECT_TRUE(v == plate || v == rod);
  // The same name twice is an error naming the parameter.
  try {
    geometry::label_mesh(m, r.skeleton_elements, "element");
    FAIL() << "expected InputError";
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("'attribute'"), std::string::npos) << e.what();
  }
}

TEST(MeshLabels, ModuleWritesClassesThatSurviveSmoothingAndDecimation) {
  const VolumeU8 s = plate_and_rod();
  auto sk = std::make_shared<VolumeU8>(s);
  auto d = std::make_shared<VolumeF32>(s.grid(), 1.0f);
  const auto rp = run_module("analysis.rods_plates_elements", {{"mask", sk}, {"skeleton", sk}, {"distance", d}});
  const auto mesh = run_module(geometry::names::skeleton_to_mesh, {{"skeleton", sk}}).data("mesh");
  const auto labelled = run_module(geometry::names::mesh_labels, {{"mesh", mesh}, {"labels", rp.data("classes")}},
                                   {{"attribute", ParamValue(std::string("class"))}}).get<Mesh>("mesh");
  for (int32_t t : Mesh::attribute<int32_t>(labelled->triangle_attributes, "class")) EXPECT_EQ(t, 2);
  for (int32_t l : Mesh::attribute<int32_t>(labelled->line_attributes, "class")) EXPECT_EQ(l, 1);
  const auto smooth = run_module(geometry::names::mesh_smooth, {{"mesh", labelled}}).data("mesh");
  const auto small = run_module(geometry::names::mesh_decimate, {{"mesh", smooth}}, {{"keep", 0.1}}).get<Mesh>("mesh");
  ASSERT_GT(small->triangle_count(), 0);
  std::set<int32_t> seen;
  for (int32_t t : Mesh::attribute<int32_t>(small->triangle_attributes, "class")) seen.insert(t);
  EXPECT_EQ(seen, std::set<int32_t>{2});
  // Labels in another unit are refused, naming both inputs.
  Grid g = s.grid();
  g.unit = "mm";
  auto other = std::make_shared<VolumeU8>(g, 1);
  try {
    run_module(geometry::names::mesh_labels, {{"mesh", mesh}, {"labels", other}});
    FAIL() << "expected InputError";
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("labels"), std::string::npos) << e.what();
  }
}
