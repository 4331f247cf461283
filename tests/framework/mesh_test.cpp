// Mesh: construction, the invariants check names what is off, bytes() counts every array, equality.
#include "skel/mesh.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <limits>

#include "skel/error.hpp"

using namespace skel;

namespace {
Mesh square() {
  Mesh m;
  for (float y : {0.0f, 1.0f})
    for (float x : {0.0f, 1.0f}) m.add_vertex({x, y, 0.0f});
  m.add_triangle(0, 1, 3);
  m.add_triangle(0, 3, 2);
  m.add_line({0, 1, 3});
  m.vertex_attributes["manifold"] = std::vector<int32_t>{4, 5, 5, 4};
  m.triangle_attributes["area"] = std::vector<float>{0.5f, 0.5f};
  m.line_attributes["manifold"] = std::vector<int32_t>{0};
  return m;
}
}  // namespace

TEST(Mesh, ConstructionAndDescription) {
  const Mesh m = square();
  EXPECT_EQ(m.vertex_count(), 4);
  EXPECT_EQ(m.triangle_count(), 2);
  EXPECT_EQ(m.line_count(), 1);
  EXPECT_TRUE(m.check_invariants().empty());
  EXPECT_EQ(m.type_id(), "mesh");
  EXPECT_EQ(m.unit, "µm");
  // 4 x 12 (points) + 2 x 24 (triangles) + (2 offsets + 3 line vertices) x 8 + (4 + 2 + 1) x 4.
  EXPECT_EQ(m.bytes(), 48u + 48u + 40u + 28u);
  EXPECT_EQ(m.describe(), "mesh 4 vertices, 2 triangles, 1 lines (µm), vertex attributes: manifold, "
                          "triangle attributes: area, line attributes: manifold");
  EXPECT_EQ(Mesh::attribute<int32_t>(m.vertex_attributes, "manifold")[1], 5);
  EXPECT_THROW((void)Mesh::attribute<float>(m.vertex_attributes, "manifold"), Error);
  EXPECT_THROW((void)Mesh::attribute<float>(m.vertex_attributes, "nope"), Error);
  Mesh m2 = m;
  EXPECT_TRUE(m2 == m);
  m2.points[3][2] = 1.0f;
  EXPECT_FALSE(m2 == m);
  EXPECT_THROW(m2.add_line({1}), Error);
}

TEST(Mesh, InvariantsNameWhatIsOff) {
  Mesh a = square();
  a.triangles[1][2] = 9;
  ASSERT_EQ(a.check_invariants().size(), 1u);
  EXPECT_EQ(a.check_invariants()[0], "triangle 1 names vertex 9 of 4");
  Mesh b = square();
  b.points[2][0] = std::numeric_limits<float>::quiet_NaN();
  EXPECT_EQ(b.check_invariants().at(0), "vertex 2 is not finite");
  Mesh c = square();
  c.triangle_attributes["area"] = std::vector<float>{1.0f};
  EXPECT_EQ(c.check_invariants().at(0), "triangle attribute 'area' has 1 values for 2 elements");
  Mesh d = square();
  d.line_vertices.push_back(2);
  EXPECT_EQ(d.check_invariants().at(0), "line offsets end at 3, not at 4 line vertices");
  Mesh e = square();
  e.line_vertices[0] = -1;
  EXPECT_EQ(e.check_invariants().at(0), "a line names vertex -1 of 4");
}
