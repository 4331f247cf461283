// Mesh files: round trips of every format, a .vtp written by VTK's own (Python) writer, malformed
// files, and the io.read_mesh / io.write_mesh modules.
#include "io/mesh_io.hpp"

#include <gtest/gtest.h>

#include <cstdlib>
#include <filesystem>
#include <fstream>

#include "io/mesh_vtk.hpp"
#include "skel/error.hpp"
#include "skel/run_module.hpp"

using namespace skel;
using namespace skel::io;

namespace {

std::filesystem::path tmp_dir() {
  auto d = std::filesystem::path(SKEL_BINARY_DIR) / "mesh_io_test";
  std::filesystem::create_directories(d);
  return d;
}

// Vertices in order of first use by the triangles (so that .stl, which stores only triangles, reads
// back the same ids), non-integer coordinates, a polyline over extra vertices, attributes of both
// types on every kind of element.
Mesh sample_mesh() {
  Mesh m;
  m.unit = "mm";
  const float s = 1.0f / 3.0f;
  m.points = {{0, 0, 0}, {1.5f, 0, s}, {0, 2.25f, -s}, {1.5f, 2.25f, 7.125e-3f}, {-4, 1e5f, 3.0e-7f},
              {0.1f, 0.2f, 0.3f}, {9, 9, 9}, {-1, -2, -3}};
  m.add_triangle(0, 1, 2);
  m.add_triangle(2, 1, 3);
  m.add_triangle(3, 1, 4);
  m.add_line({5, 6, 7});
  m.add_line({7, 0});
  m.vertex_attributes["manifold"] = std::vector<int32_t>{4, 5, 5, 4, 6, 2, 2, 3};
  m.vertex_attributes["height"] = std::vector<float>{0.5f, s, -2.0f, 1e-8f, 3, 4, 5, 6};
  m.triangle_attributes["manifold"] = std::vector<int32_t>{1, 0, 1};
  m.triangle_attributes["area"] = std::vector<float>{0.25f, s, 7.0f};
  m.line_attributes["manifold"] = std::vector<int32_t>{1, 0};
  m.line_attributes["length"] = std::vector<float>{2.5f, s};
  EXPECT_TRUE(m.check_invariants().empty());
  return m;
}

// The part of `m` a format carries.
Mesh carried(const Mesh& m, MeshFormat f) {
  Mesh c;
  c.points = m.points;
  c.triangles = m.triangles;
  if (f == MeshFormat::vtp || f == MeshFormat::ply) return m;
  if (f == MeshFormat::obj) {
    c.line_offsets = m.line_offsets;
    c.line_vertices = m.line_vertices;
    c.unit = m.unit;
  }
  if (f == MeshFormat::surf) c.unit = m.unit;
  if (f == MeshFormat::stl) c.points.resize(5);  // the line-only vertices are not in an STL file
  return c;
}

void write_text(const std::filesystem::path& p, const std::string& s) {
  std::ofstream(p, std::ios::binary) << s;
}

std::string read_error(const std::filesystem::path& p) {
  try {
    read_mesh(p, mesh_format_from_path(p));
  } catch (const InputError& e) {
    return e.what();
  }
  return "(no error)";
}

}  // namespace

TEST(MeshIo, FormatFromExtension) {
  EXPECT_EQ(mesh_format_from_path("a/b.VTP"), MeshFormat::vtp);
  EXPECT_EQ(mesh_format_from_path("b.ply"), MeshFormat::ply);
  EXPECT_EQ(mesh_format_from_path("b.stl"), MeshFormat::stl);
  EXPECT_EQ(mesh_format_from_path("b.obj"), MeshFormat::obj);
  EXPECT_EQ(mesh_format_from_path("b.surf"), MeshFormat::surf);
  EXPECT_THROW(mesh_format_from_path("b.am"), InputError);
}

TEST(MeshIo, RoundTripEveryFormat) {
  const Mesh m = sample_mesh();
  for (const char* ext : {".vtp", ".ply", ".stl", ".obj", ".surf"}) {
    SCOPED_TRACE(ext);
    const auto p = tmp_dir() / (std::string("sample") + ext);
    const auto f = mesh_format_from_path(p);
    write_mesh(m, p, f);
    const Mesh back = read_mesh(p, f);
    const Mesh want = carried(m, f);
    EXPECT_EQ(back.points, want.points);
    EXPECT_EQ(back.triangles, want.triangles);
    EXPECT_EQ(back.line_offsets, want.line_offsets);
    EXPECT_EQ(back.line_vertices, want.line_vertices);
    EXPECT_EQ(back.vertex_attributes, want.vertex_attributes);
    EXPECT_EQ(back.triangle_attributes, want.triangle_attributes);
    EXPECT_EQ(back.line_attributes, want.line_attributes);
    EXPECT_EQ(back.unit, want.unit);
    EXPECT_TRUE(back == want);
  }
}

TEST(MeshIo, VtpIsBinaryCompressedAppended) {
  const auto p = tmp_dir() / "compressed.vtp";
  write_mesh(sample_mesh(), p, MeshFormat::vtp);
  std::ifstream in(p, std::ios::binary);
  const std::string s((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  EXPECT_NE(s.find("compressor=\"vtkZLibDataCompressor\""), std::string::npos);
  EXPECT_NE(s.find("format=\"appended\""), std::string::npos);
  EXPECT_NE(s.find("encoding=\"raw\""), std::string::npos);
}

TEST(MeshIo, EmptyMeshRoundTrips) {
  for (const char* ext : {".vtp", ".ply", ".stl", ".obj", ".surf"}) {
    SCOPED_TRACE(ext);
    const auto p = tmp_dir() / (std::string("empty") + ext);
    write_mesh(Mesh{}, p, mesh_format_from_path(p));
    const Mesh back = read_mesh(p, mesh_format_from_path(p));
    EXPECT_EQ(back.vertex_count(), 0);
    EXPECT_EQ(back.triangle_count(), 0);
    EXPECT_EQ(back.line_count(), 0);
  }
}

// A .vtp written by VTK's own writer (Python, as users' scripts do): a quad (read as two triangles),
// a polyline, a double point array and an int cell array.
TEST(MeshIo, ReadsVtpWrittenByVtkPython) {
  if (std::system("/usr/bin/python3 -c 'import vtk' > /dev/null 2>&1") != 0) GTEST_SKIP() << "python3-vtk9 missing";
  const auto p = tmp_dir() / "from_python.vtp";
  std::filesystem::remove(p);
  const auto script = tmp_dir() / "write_vtp.py";
  write_text(script,
             "import sys, vtk\n"
             "pts = vtk.vtkPoints()\n"
             "for x, y, z in [(0,0,0),(1,0,0),(1,1,0),(0,1,0),(2,2,2)]: pts.InsertNextPoint(x, y, z)\n"
             "poly = vtk.vtkPolyData(); poly.SetPoints(pts)\n"
             "quads = vtk.vtkCellArray(); quads.InsertNextCell(4, [0,1,2,3]); poly.SetPolys(quads)\n"
             "lines = vtk.vtkCellArray(); lines.InsertNextCell(2, [2,4]); poly.SetLines(lines)\n"
             "h = vtk.vtkDoubleArray(); h.SetName('h')\n"
             "for v in [0.5, 1.5, 2.5, 3.5, 4.5]: h.InsertNextValue(v)\n"
             "poly.GetPointData().AddArray(h)\n"
             "c = vtk.vtkIntArray(); c.SetName('cls'); c.InsertNextValue(7); c.InsertNextValue(9)\n"
             "poly.GetCellData().AddArray(c)\n"
             "w = vtk.vtkXMLPolyDataWriter(); w.SetFileName(sys.argv[1]); w.SetInputData(poly); w.Write()\n");
  ASSERT_EQ(std::system(("/usr/bin/python3 " + script.string() + " " + p.string()).c_str()), 0);
  const Mesh m = read_mesh(p, MeshFormat::vtp);
  ASSERT_EQ(m.vertex_count(), 5);
  EXPECT_EQ(m.points[4], (Mesh::Point{2, 2, 2}));
  ASSERT_EQ(m.triangle_count(), 2);
  EXPECT_EQ(m.triangles[0], (Mesh::Triangle{0, 1, 2}));
  EXPECT_EQ(m.triangles[1], (Mesh::Triangle{0, 2, 3}));
  ASSERT_EQ(m.line_count(), 1);
  EXPECT_EQ(m.line_vertices, (std::vector<int64_t>{2, 4}));
  EXPECT_EQ(Mesh::attribute<float>(m.vertex_attributes, "h")[3], 3.5f);
  // Cell data rows: the line first (7), then the quad (9) for both of its triangles.
  EXPECT_EQ(Mesh::attribute<int32_t>(m.triangle_attributes, "cls"), (std::vector<int32_t>{9, 9}));
  EXPECT_EQ(Mesh::attribute<int32_t>(m.line_attributes, "cls"), (std::vector<int32_t>{7}));
  EXPECT_EQ(m.unit, "µm");
}

TEST(MeshIo, ForeignAsciiFormatsRead) {
  const auto d = tmp_dir();
  write_text(d / "ascii.ply",
             "ply\nformat ascii 1.0\nelement vertex 4\nproperty float x\nproperty float y\nproperty float z\n"
             "property uchar red\nelement face 1\nproperty list uchar int vertex_index\nelement edge 1\n"
             "property int vertex1\nproperty int vertex2\nend_header\n0 0 0 1\n1 0 0 2\n1 1 0 3\n0 1 0 4\n4 0 1 2 3\n0 2\n");
  const Mesh ply = read_mesh(d / "ascii.ply", MeshFormat::ply);
  EXPECT_EQ(ply.triangle_count(), 2);
  EXPECT_EQ(Mesh::attribute<int32_t>(ply.vertex_attributes, "red"), (std::vector<int32_t>{1, 2, 3, 4}));
  write_text(d / "ascii.stl",
             "solid t\nfacet normal 0 0 1\nouter loop\nvertex 0 0 0\nvertex 1 0 0\nvertex 0 1 0\nendloop\nendfacet\n"
             "facet normal 0 0 1\nouter loop\nvertex 1 0 0\nvertex 1 1 0\nvertex 0 1 0\nendloop\nendfacet\nendsolid t\n");
  const Mesh stl = read_mesh(d / "ascii.stl", MeshFormat::stl);
  EXPECT_EQ(stl.vertex_count(), 4);
  EXPECT_EQ(stl.triangles[1], (Mesh::Triangle{1, 3, 2}));
  write_text(d / "neg.obj", "o x\nv 0 0 0\nv 1 0 0\nv 1 1 0\nvn 0 0 1\nf -3//1 -2//1 -1//1\n");
  const Mesh obj = read_mesh(d / "neg.obj", MeshFormat::obj);
  EXPECT_EQ(obj.triangles, (std::vector<Mesh::Triangle>{{0, 1, 2}}));
}

TEST(MeshIo, MalformedFilesNameFileAndLine) {
  const auto d = tmp_dir();
  write_text(d / "bad_index.obj", "v 0 0 0\nv 1 0 0\nf 1 2 3\n");
  EXPECT_EQ(read_error(d / "bad_index.obj"), (d / "bad_index.obj").string() + ":3: vertex index 3 out of range (2 vertices so far)");
  write_text(d / "bad_number.surf", "# HyperSurface 0.1 ASCII\nVertices 1\n 0 x 0\n");
  EXPECT_EQ(read_error(d / "bad_number.surf"), (d / "bad_number.surf").string() + ":3: expected y, found 'x'");
  write_text(d / "huge.surf", "# HyperSurface 0.1 ASCII\nVertices 99999999999\n");
  EXPECT_NE(read_error(d / "huge.surf").find("is more than the file holds"), std::string::npos);
  write_text(d / "short.stl", std::string(80, ' ') + std::string("\x05\0\0\0", 4) + std::string(10, '\0'));
  EXPECT_EQ(read_error(d / "short.stl"), (d / "short.stl").string() + ": binary STL of 5 triangles needs 334 bytes, the file has 94");
  write_text(d / "huge.ply", "ply\nformat binary_little_endian 1.0\nelement vertex 4000000000\nproperty float x\n"
                             "property float y\nproperty float z\nend_header\n");
  EXPECT_NE(read_error(d / "huge.ply").find("element 'vertex' count 4000000000 is more than the file holds"), std::string::npos);
  write_text(d / "face.ply", "ply\nformat ascii 1.0\nelement vertex 1\nproperty float x\nproperty float y\nproperty float z\n"
                             "element face 1\nproperty list uchar int vertex_indices\nend_header\n0 0 0\n3 0 0 5\n");
  EXPECT_EQ(read_error(d / "face.ply"), (d / "face.ply").string() + ": a face names vertex 5 of 1");
  write_text(d / "not.vtp", "<VTKFile type=\"PolyData\"><broken");
  EXPECT_EQ(read_error(d / "not.vtp"), (d / "not.vtp").string() + ": not a readable VTK XML PolyData file (Error parsing XML in stream at line 1, column 25, byte index 25: unclosed token)");
  EXPECT_EQ(read_error(d / "missing.ply"), (d / "missing.ply").string() + ": file not found");
}

TEST(MeshIo, VtkConversionRoundTrips) {
  const Mesh m = sample_mesh();
  auto poly = mesh_to_vtk(m);
  EXPECT_EQ(poly->GetNumberOfPolys(), 3);
  EXPECT_EQ(poly->GetNumberOfLines(), 2);
  EXPECT_TRUE(mesh_from_vtk(*poly, "test") == m);
}

TEST(MeshIo, ModulesWriteAndRead) {
  const auto d = tmp_dir() / "modules";
  std::filesystem::create_directories(d);
  auto m = std::make_shared<Mesh>(sample_mesh());
  run_module("io.write_mesh", {{"mesh", m}}, {{"path", std::string("out/m.ply")}}, {.threads = 1, .base_dir = d});
  auto r = run_module("io.read_mesh", {}, {{"path", std::string("out/m.ply")}}, {.threads = 1, .base_dir = d});
  EXPECT_TRUE(*r.get<Mesh>("mesh") == *m);
  EXPECT_THROW(run_module("io.write_mesh", {{"mesh", m}}, {{"path", std::string("m.txt")}}, {.threads = 1, .base_dir = d}),
               InputError);
}

TEST(MeshIo, RefusesInconsistentMesh) {
  Mesh m;
  m.points = {{0, 0, 0}};
  m.add_triangle(0, 0, 1);
  EXPECT_THROW(write_mesh(m, tmp_dir() / "bad.ply", MeshFormat::ply), InputError);
  EXPECT_FALSE(std::filesystem::exists(tmp_dir() / "bad.ply"));
}

// A write that fails (here: /proc takes no files, not even root's) is an Error naming the file; the
// .vtp goes through VTK's writer, whose error is caught and reported the same way.
TEST(MeshIo, FailedWriteNamesTheFile) {
  for (const char* ext : {".vtp", ".ply"}) {
    SCOPED_TRACE(ext);
    const std::filesystem::path p = std::string("/proc/skelflow_mesh_io_test") + ext;
    try {
      write_mesh(sample_mesh(), p, mesh_format_from_path(p));
      ADD_FAILURE() << "no error";
    } catch (const Error& e) {
      EXPECT_EQ(std::string(e.what()).rfind("cannot write " + p.string() + ": ", 0), 0u) << e.what();
      EXPECT_EQ(std::string(e.what()).find("skelflow-tmp"), std::string::npos) << e.what();
    }
    EXPECT_FALSE(std::filesystem::exists(p));
  }
}
