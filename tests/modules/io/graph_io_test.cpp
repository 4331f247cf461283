#include "io/graph_io.hpp"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdlib>
#include <fstream>
#include <filesystem>
#include <functional>

#include "geometry/skeleton_to_graph.hpp"
#include "../graph/graph_test_util.hpp"
#include "skel/error.hpp"

using namespace skel::geometry;
using namespace skel::io;

using namespace skel;

namespace {

// A graph with every kind of content: junctions, ends, a loop edge, an isolated node, radii,
// node/edge attributes and labels, non-integer coordinates.
SpatialGraph sample_graph(bool with_loop) {
  VolumeU8 v({24, 20, 6}, 0, {0.7, 1.3, 2.1}, {-3.25, 10.0, 0.125});
  skel::test::draw_line(v, {1, 1, 2}, {20, 12, 2});
  skel::test::draw_line(v, {10, 1, 3}, {10, 18, 3});
  skel::test::draw_line(v, {10, 10, 3}, {3, 17, 4});
  if (with_loop) skel::test::draw_square_ring(v, {15, 14, 1}, 0, 1, 5);
  VolumeF32 d(v.grid(), 0.0f);
  for (int64_t i = 0; i < d.size(); ++i) d[i] = 0.1f * static_cast<float>(i % 17) + 0.33f;
  auto g = skeleton_to_graph(v, &d, {}).graph;
  if (with_loop) g.add_node({1.0 / 3.0, 2.0 / 7.0, -5.5});
  auto& w = g.ensure_edge_attribute("weight");
  for (size_t e = 0; e < w.size(); ++e) w[e] = 0.25f * static_cast<float>(e) + 1.0f / 3.0f;
  auto& t = g.ensure_edge_label("tree");
  for (size_t e = 0; e < t.size(); ++e) t[e] = static_cast<int32_t>(e % 3) - 1;
  auto& nw = g.ensure_node_attribute("score");
  for (size_t n = 0; n < nw.size(); ++n) nw[n] = static_cast<float>(n) / 7.0f;
  EXPECT_TRUE(g.check_invariants().empty());
  return g;
}

void expect_near(const Vec3& a, const Vec3& b, double tol) {
  for (int k = 0; k < 3; ++k) EXPECT_NEAR(a[k], b[k], tol * (1.0 + std::abs(a[k])));
}

// Same ids, order, polylines, attributes (coordinates within `tol`).
void expect_same(const SpatialGraph& a, const SpatialGraph& b, double tol, bool node_radius_too = true) {
  ASSERT_EQ(a.node_count(), b.node_count());
  ASSERT_EQ(a.edge_count(), b.edge_count());
  EXPECT_EQ(a.unit, b.unit);
  for (int64_t n = 0; n < a.node_count(); ++n) expect_near(a.positions[n], b.positions[n], tol);
  for (int64_t e = 0; e < a.edge_count(); ++e) {
    EXPECT_EQ(a.edges[e].node0, b.edges[e].node0);
    EXPECT_EQ(a.edges[e].node1, b.edges[e].node1);
    ASSERT_EQ(a.edges[e].points.size(), b.edges[e].points.size());
    for (size_t i = 0; i < a.edges[e].points.size(); ++i) expect_near(a.edges[e].points[i], b.edges[e].points[i], tol);
  }
  EXPECT_EQ(a.edge_labels, b.edge_labels);
  EXPECT_EQ(a.edge_attributes, b.edge_attributes);  // floats are written with 9 digits: exact
  EXPECT_EQ(a.point_attributes, b.point_attributes);
  if (node_radius_too) {
    EXPECT_EQ(a.node_attributes, b.node_attributes);
    EXPECT_EQ(a.node_labels, b.node_labels);
  }
}

std::filesystem::path tmp_dir() {
  auto d = std::filesystem::path(SKEL_BINARY_DIR) / "graph_io_test";
  std::filesystem::create_directories(d);
  return d;
}

}  // namespace

TEST(GraphIo, FormatFromExtension) {
  EXPECT_EQ(graph_format_from_path("a/b.AM"), GraphFormat::amira);
  EXPECT_EQ(graph_format_from_path("x.vtp"), GraphFormat::vtp);
  EXPECT_EQ(graph_format_from_path("x.swc"), GraphFormat::swc);
  EXPECT_EQ(graph_format_from_path("x.graphml"), GraphFormat::graphml);
  EXPECT_EQ(graph_format_from_path("x.csv"), GraphFormat::csv);
  EXPECT_THROW(graph_format_from_path("x.obj"), InputError);
}

TEST(GraphIo, AmiraRoundTripAndLayout) {
  const auto g = sample_graph(true);
  const std::string text = graph_to_text(g, GraphFormat::amira);
  EXPECT_EQ(text.rfind("# AmiraMesh 3D ASCII 2.0\n", 0), 0u);
  EXPECT_NE(text.find("define VERTEX " + std::to_string(g.node_count()) + "\n"), std::string::npos);
  EXPECT_NE(text.find("define EDGE " + std::to_string(g.edge_count()) + "\n"), std::string::npos);
  EXPECT_NE(text.find("define POINT " + std::to_string(g.point_count()) + "\n"), std::string::npos);
  EXPECT_NE(text.find("ContentType \"HxSpatialGraph\""), std::string::npos);
  EXPECT_NE(text.find("VERTEX { float[3] VertexCoordinates } @1\n"), std::string::npos);
  EXPECT_NE(text.find("EDGE { int[2] EdgeConnectivity } @2\n"), std::string::npos);
  EXPECT_NE(text.find("EDGE { int NumEdgePoints } @3\n"), std::string::npos);
  EXPECT_NE(text.find("POINT { float[3] EdgePointCoordinates } @4\n"), std::string::npos);
  EXPECT_NE(text.find("POINT { float thickness } @5\n"), std::string::npos);
  EXPECT_NE(text.find("EDGE { int tree } @"), std::string::npos);
  const auto r = graph_from_text(text, GraphFormat::amira);
  expect_same(g, r, 1e-7);
  // Amira stores float coordinates: the second round trip is exact.
  EXPECT_EQ(graph_to_text(r, GraphFormat::amira), text);
}

TEST(GraphIo, VtpRoundTrip) {
  const auto g = sample_graph(true);
  const std::string text = graph_to_text(g, GraphFormat::vtp);
  EXPECT_NE(text.find("<VTKFile type=\"PolyData\""), std::string::npos);
  const auto r = graph_from_text(text, GraphFormat::vtp);
  expect_same(g, r, 0.0);
}

TEST(GraphIo, GraphmlRoundTrip) {
  const auto g = sample_graph(true);
  const auto r = graph_from_text(graph_to_text(g, GraphFormat::graphml), GraphFormat::graphml);
  expect_same(g, r, 0.0);
}

TEST(GraphIo, CsvRoundTripThroughFiles) {
  const auto g = sample_graph(true);
  const auto d = tmp_dir();
  write_graph(g, d / "net.csv", GraphFormat::csv, d / "net_nodes.csv");
  const auto r = read_graph(d / "net.csv", GraphFormat::csv);  // nodes file found by name
  expect_same(g, r, 0.0);
  EXPECT_THROW(write_graph(g, d / "x.csv", GraphFormat::csv), InputError);
}

TEST(GraphIo, AllFormatsThroughFiles) {
  const auto g = sample_graph(true);
  const auto d = tmp_dir();
  for (const char* name : {"net.am", "net.vtp", "net.graphml"}) {
    const auto p = d / name;
    const auto f = graph_format_from_path(p);
    write_graph(g, p, f);
    expect_same(g, read_graph(p, f), 1e-7);
  }
}

TEST(GraphIo, SwcRoundTripOfATree) {
  const auto g = sample_graph(false);
  ASSERT_EQ(g.cyclomatic_number(), 0);
  const std::string text = graph_to_text(g, GraphFormat::swc);
  const auto r = graph_from_text(text, GraphFormat::swc);
  // Node ids and edge directions change (breadth-first order); compare canonical edges.
  ASSERT_EQ(r.node_count(), g.node_count());
  ASSERT_EQ(r.edge_count(), g.edge_count());
  auto canon = [](const SpatialGraph& x) {
    std::vector<std::pair<std::vector<Vec3>, std::vector<float>>> out;
    for (int64_t e = 0; e < x.edge_count(); ++e) {
      auto p = x.edges[e].points;
      auto rad = x.point_attributes.at("radius")[e];
      if (p.back() < p.front()) {
        std::reverse(p.begin(), p.end());
        std::reverse(rad.begin(), rad.end());
      }
      out.emplace_back(p, rad);
    }
    std::sort(out.begin(), out.end());
    return out;
  };
  EXPECT_EQ(canon(g), canon(r));
  auto sg = g.degrees(), sr = r.degrees();
  std::sort(sg.begin(), sg.end());
  std::sort(sr.begin(), sr.end());
  EXPECT_EQ(sg, sr);
  EXPECT_THROW(graph_to_text(sample_graph(true), GraphFormat::swc), InputError);
}

TEST(GraphIo, MalformedFilesAreInputErrors) {
  EXPECT_THROW(graph_from_text("hello", GraphFormat::amira), InputError);
  EXPECT_THROW(graph_from_text("# AmiraMesh BINARY-LITTLE-ENDIAN 2.0\n", GraphFormat::amira), InputError);
  const std::string bad_am =
      "# AmiraMesh 3D ASCII 2.0\ndefine VERTEX 1\ndefine EDGE 1\ndefine POINT 2\n"
      "VERTEX { float[3] VertexCoordinates } @1\nEDGE { int[2] EdgeConnectivity } @2\n"
      "EDGE { int NumEdgePoints } @3\nPOINT { float[3] EdgePointCoordinates } @4\n"
      "@1\n0 0 0\n@2\n0 3\n@3\n2\n@4\n0 0 0 1 1 1\n";
  EXPECT_THROW(graph_from_text(bad_am, GraphFormat::amira), InputError);
  EXPECT_THROW(graph_from_text("1 0 0 0 0 1 7\n", GraphFormat::swc), InputError);
  EXPECT_THROW(graph_from_text("<graphml><graph><edge source=\"a\" target=\"b\"/></graph></graphml>",
                               GraphFormat::graphml),
               InputError);
  EXPECT_THROW(graph_from_text("<VTKFile type=\"PolyData\"><PolyData>", GraphFormat::vtp), InputError);
  EXPECT_THROW(read_graph("/nonexistent/x.am", GraphFormat::amira), InputError);
}

TEST(GraphIo, ReadsAmiraWrittenByAmira) {
  // Layout as Amira writes it (extra parameters, CRLF-free, thickness), edge points not exactly at
  // the vertices are snapped to them.
  const std::string am =
      "# AmiraMesh 3D ASCII 2.0\n\n\ndefine VERTEX 3\ndefine EDGE 2\ndefine POINT 5\n\n"
      "Parameters {\n    SpatialGraphUnitsVertex {\n    }\n    ContentType \"HxSpatialGraph\"\n}\n\n"
      "VERTEX { float[3] VertexCoordinates } @1\nEDGE { int[2] EdgeConnectivity } @2\n"
      "EDGE { int NumEdgePoints } @3\nPOINT { float[3] EdgePointCoordinates } @4\n"
      "POINT { float thickness } @5\n\n# Data section follows\n"
      "@1\n0 0 0\n10 0 0\n10 5 0\n\n@2\n0 1\n1 2\n\n@3\n3\n2\n\n@4\n0 0 0\n5 0.5 0\n10 0 0\n10 0 0\n10 5 0\n\n"
      "@5\n1\n2\n3\n3\n4\n";
  const auto g = graph_from_text(am, GraphFormat::amira);
  EXPECT_EQ(g.node_count(), 3);
  EXPECT_EQ(g.edge_count(), 2);
  EXPECT_EQ(g.point_attributes.at("radius")[0], (std::vector<float>{1, 2, 3}));
  EXPECT_NEAR(g.total_length(), 2 * std::sqrt(25.25) + 5, 1e-6);
}

// The messages of the malformed files above: the file, the line where known, and what is wrong.
TEST(GraphIo, MalformedFileMessages) {
  auto message = [](const std::function<void()>& f) -> std::string {
    try {
      f();
    } catch (const InputError& e) {
      return e.what();
    }
    return "(no error)";
  };
  EXPECT_EQ(message([] { graph_from_text("hello", GraphFormat::amira, {}, "h.am"); }),
            "h.am: not an AmiraMesh file (first line must start with '# AmiraMesh')");
  EXPECT_EQ(message([] { graph_from_text("# AmiraMesh BINARY-LITTLE-ENDIAN 2.0\n", GraphFormat::amira, {}, "b.am"); }),
            "b.am: only ASCII AmiraMesh is supported, header says '# AmiraMesh BINARY-LITTLE-ENDIAN 2.0'");
  const std::string bad_am =
      "# AmiraMesh 3D ASCII 2.0\ndefine VERTEX 1\ndefine EDGE 1\ndefine POINT 2\n"
      "VERTEX { float[3] VertexCoordinates } @1\nEDGE { int[2] EdgeConnectivity } @2\n"
      "EDGE { int NumEdgePoints } @3\nPOINT { float[3] EdgePointCoordinates } @4\n"
      "@1\n0 0 0\n@2\n0 3\n@3\n2\n@4\n0 0 0 1 1 1\n";
  EXPECT_EQ(message([&] { graph_from_text(bad_am, GraphFormat::amira, {}, "bad.am"); }),
            "bad.am:12: block @2 (EdgeConnectivity): node id 3 out of range (1 nodes)");
  EXPECT_EQ(message([] { graph_from_text("1 0 0 0 0 1 7\n", GraphFormat::swc, {}, "p.swc"); }),
            "p.swc:1: sample 1 has unknown parent 7");
  EXPECT_EQ(message([] { graph_from_text("1 0 0 zero 0 1 -1\n", GraphFormat::swc, {}, "n.swc"); }),
            "n.swc:1: expected a number, got 'zero'");
  EXPECT_EQ(message([] {
              graph_from_text("<graphml><graph><edge source=\"a\" target=\"b\"/></graph></graphml>",
                              GraphFormat::graphml, {}, "e.graphml");
            }),
            "e.graphml: edge refers to unknown node 'a'");
  EXPECT_EQ(
      message([] { graph_from_text("<graphml>\n<graph>\n<node id=\"a\"", GraphFormat::graphml, {}, "t.graphml"); }),
      "t.graphml:3: unterminated XML tag");
  EXPECT_EQ(message([] { graph_from_text("<VTKFile type=\"PolyData\"><PolyData>", GraphFormat::vtp, {}, "u.vtp"); }),
            "u.vtp:1: unclosed XML element <PolyData> (the file ends at line 1)");
  EXPECT_EQ(message([] { read_graph("/nonexistent/x.am", GraphFormat::amira); }), "/nonexistent/x.am: file not found");
}

namespace {
std::string error_of(const std::function<void()>& f) {
  try {
    f();
  } catch (const InputError& e) {
    return e.what();
  }
  return "(no error)";
}
bool contains(const std::string& s, const std::string& part) { return s.find(part) != std::string::npos; }
}  // namespace

// Expat parses GraphML and VTK XML without recursion: 100000 nested elements parse (and the tree is
// freed) within the default stack, and an unclosed deep file is a located error.
TEST(GraphIo, DeeplyNestedXmlParsesWithoutRecursion) {
  constexpr int depth = 100000;
  std::string deep;
  for (int i = 0; i < depth; ++i) deep += "<x>";
  std::string closing;
  for (int i = 0; i < depth; ++i) closing += "</x>";
  const std::string gml = "<graphml>\n<key id=\"dx\" for=\"node\" attr.name=\"x\" attr.type=\"double\"/>\n<graph>\n"
                          "<node id=\"a\"><data key=\"dx\">1.5</data>" + deep + closing + "</node>\n<node id=\"b\"/>\n"
                          "<edge source=\"a\" target=\"b\"/>\n</graph>\n</graphml>\n";
  const auto g = graph_from_text(gml, GraphFormat::graphml, {}, "deep.graphml");
  ASSERT_EQ(g.node_count(), 2);
  EXPECT_EQ(g.edge_count(), 1);
  EXPECT_EQ(g.positions[0][0], 1.5);
  EXPECT_EQ(error_of([&] { graph_from_text("<graphml>\n<graph>\n" + deep, GraphFormat::graphml, {}, "open.graphml"); }),
            "open.graphml:3: unclosed XML element <x> (the file ends at line 3)");
  const std::string vtp = "<VTKFile type=\"PolyData\">\n" + deep + closing + "\n</VTKFile>\n";
  EXPECT_EQ(error_of([&] { graph_from_text(vtp, GraphFormat::vtp, {}, "deep.vtp"); }), "deep.vtp: no <Piece>");
  // Other syntax errors are expat's, with line and column.
  EXPECT_EQ(error_of([] { graph_from_text("<graphml>\n<graph></grph>\n</graphml>", GraphFormat::graphml, {}, "m.graphml"); }),
            "m.graphml:2:10: XML syntax error: mismatched tag");
}

TEST(GraphIo, SwcParentCycleIsAnError) {
  // A 3-sample cycle below a valid tree: named by the file, the line and a sample on the cycle.
  const std::string small = "1 1 0 0 0 1 -1\n2 1 1 0 0 1 1\n3 1 2 0 0 1 5\n4 1 3 0 0 1 3\n5 1 4 0 0 1 4\n";
  EXPECT_EQ(error_of([&] { graph_from_text(small, GraphFormat::swc, {}, "c.swc"); }),
            "c.swc:3: sample 3: parent links form a cycle of 3 sample(s) (parent 5); SWC samples must form trees");
  // A pure 5000-sample cycle (no root at all) used to give an empty graph.
  std::string ring;
  for (int i = 1; i <= 5000; ++i)
    ring += std::to_string(i) + " 3 " + std::to_string(i) + " 0 0 1 " + std::to_string(i == 1 ? 5000 : i - 1) + "\n";
  const std::string m = error_of([&] { graph_from_text(ring, GraphFormat::swc, {}, "ring.swc"); });
  EXPECT_TRUE(contains(m, "ring.swc:1: sample 1: parent links form a cycle of 5000 sample(s)")) << m;
}

TEST(GraphIo, GraphmlOnePointEdgeIsNamed) {
  const std::string gml =
      "<graphml>\n<key id=\"p\" for=\"edge\" attr.name=\"points\" attr.type=\"string\"/>\n<graph>\n"
      "<node id=\"a\"/><node id=\"b\"/>\n<edge id=\"e7\" source=\"a\" target=\"b\"><data key=\"p\">1 2 3</data></edge>\n"
      "</graph>\n</graphml>\n";
  EXPECT_EQ(error_of([&] { graph_from_text(gml, GraphFormat::graphml, {}, "one.graphml"); }),
            "one.graphml:5: edge 'e7' has 1 point in 'points', expected >= 2 (its end nodes at least)");
}

TEST(GraphIo, DeclaredCountsAreCheckedAgainstTheFileSize) {
  const std::string huge = "# AmiraMesh 3D ASCII 2.0\ndefine VERTEX 4000000000\ndefine EDGE 0\ndefine POINT 0\n"
                           "VERTEX { float[3] VertexCoordinates } @1\n@1\n0 0 0\n";
  EXPECT_EQ(error_of([&] { graph_from_text(huge, GraphFormat::amira, {}, "h.am"); }),
            "h.am:2: 'define VERTEX 4000000000' declares more elements than a file of " + std::to_string(huge.size()) +
                " bytes can hold");
  // Counts that fit one by one but not together (3 coordinates per vertex and point).
  const std::string both = "# AmiraMesh 3D ASCII 2.0\ndefine VERTEX 12\ndefine EDGE 0\ndefine POINT 12\n@1\n";
  EXPECT_TRUE(contains(error_of([&] { graph_from_text(both, GraphFormat::amira, {}, "b.am"); }),
                       "b.am: 'define VERTEX 12', 'define EDGE 0' and 'define POINT 12' need more values than a file of"));
  // Numbers beyond int64 are input errors, not std::out_of_range.
  EXPECT_EQ(error_of([] {
              graph_from_text("# AmiraMesh 3D ASCII 2.0\ndefine VERTEX 99999999999999999999999\n@1\n", GraphFormat::amira,
                              {}, "o.am");
            }),
            "o.am:2: number 99999999999999999999999 is too large");
  // A per-edge point count larger than the declared points.
  const std::string npts =
      "# AmiraMesh 3D ASCII 2.0\ndefine VERTEX 2\ndefine EDGE 1\ndefine POINT 2\n"
      "VERTEX { float[3] VertexCoordinates } @1\nEDGE { int[2] EdgeConnectivity } @2\n"
      "EDGE { int NumEdgePoints } @3\nPOINT { float[3] EdgePointCoordinates } @4\n"
      "@1\n0 0 0\n1 0 0\n@2\n0 1\n@3\n3000000000\n@4\n0 0 0 1 0 0\n";
  EXPECT_EQ(error_of([&] { graph_from_text(npts, GraphFormat::amira, {}, "n.am"); }),
            "n.am:15: block @3 (NumEdgePoints): an edge has 3000000000 points, more than 'define POINT 2'");
  // .vtp: the declared sizes must match the arrays; offsets and ids must be indices.
  const std::string vtp = "<VTKFile type=\"PolyData\"><PolyData>\n<Piece NumberOfPoints=\"4000000000\">\n"
                          "<Points><DataArray Name=\"Points\" NumberOfComponents=\"3\">0 0 0 1 1 1</DataArray></Points>\n"
                          "</Piece></PolyData></VTKFile>\n";
  EXPECT_EQ(error_of([&] { graph_from_text(vtp, GraphFormat::vtp, {}, "p.vtp"); }),
            "p.vtp:2: <Piece> declares NumberOfPoints=\"4000000000\" but the file holds 2");
  const std::string offs = "<VTKFile type=\"PolyData\"><PolyData>\n<Piece>\n"
                           "<Points><DataArray Name=\"Points\" NumberOfComponents=\"3\">0 0 0 1 1 1</DataArray></Points>\n"
                           "<Lines><DataArray Name=\"connectivity\">0 1</DataArray>"
                           "<DataArray Name=\"offsets\">-4 2</DataArray></Lines>\n</Piece></PolyData></VTKFile>\n";
  EXPECT_EQ(error_of([&] { graph_from_text(offs, GraphFormat::vtp, {}, "o.vtp"); }),
            "o.vtp: line cell 0: offset -4 is not a valid index");
  const std::string conn = "<VTKFile type=\"PolyData\"><PolyData>\n<Piece>\n"
                           "<Points><DataArray Name=\"Points\" NumberOfComponents=\"3\">0 0 0 1 1 1</DataArray></Points>\n"
                           "<Verts><DataArray Name=\"connectivity\">0</DataArray>"
                           "<DataArray Name=\"offsets\">1 9</DataArray></Verts>\n</Piece></PolyData></VTKFile>\n";
  EXPECT_EQ(error_of([&] { graph_from_text(conn, GraphFormat::vtp, {}, "v.vtp"); }),
            "v.vtp: vertex cell 1: offset 1 is past the end of the connectivity (1 values)");
}

// inf, 1e400 and NaN coordinates or radii are refused by every reader, at their line.
TEST(GraphIo, NonFiniteCoordinatesAndRadiiAreRefused) {
  for (const char* bad : {"inf", "1e400", "nan", "-Infinity"}) {
    const std::string b = bad;
    SCOPED_TRACE(b);
    EXPECT_EQ(error_of([&] { graph_from_text("1 1 0 0 0 1 -1\n2 1 " + b + " 0 0 1 1\n", GraphFormat::swc, {}, "f.swc"); }),
              "f.swc:2: a coordinate is not a finite number");
    EXPECT_EQ(error_of([&] { graph_from_text("1 1 0 0 0 1 -1\n2 1 1 0 0 " + b + " 1\n", GraphFormat::swc, {}, "r.swc"); }),
              "r.swc:2: the radius is not a finite number");
    const std::string am =
        "# AmiraMesh 3D ASCII 2.0\ndefine VERTEX 2\ndefine EDGE 1\ndefine POINT 2\n"
        "VERTEX { float[3] VertexCoordinates } @1\nEDGE { int[2] EdgeConnectivity } @2\n"
        "EDGE { int NumEdgePoints } @3\nPOINT { float[3] EdgePointCoordinates } @4\nPOINT { float thickness } @5\n"
        "@1\n0 0 0\n1 0 0\n@2\n0 1\n@3\n2\n@4\n0 0 0\n1 0 0\n@5\n1\n" + b + "\n";
    EXPECT_EQ(error_of([&] { graph_from_text(am, GraphFormat::amira, {}, "f.am"); }),
              "f.am:22: block @5 (thickness): a radius is not a finite number");
    std::string am_xyz = am;
    am_xyz.replace(am_xyz.find("@1\n0 0 0\n1 0 0"), 14, "@1\n0 0 0\n1 " + b + " 0");
    EXPECT_EQ(error_of([&] { graph_from_text(am_xyz, GraphFormat::amira, {}, "x.am"); }),
              "x.am:12: block @1 (VertexCoordinates): a coordinate is not a finite number");
    const std::string gml =
        "<graphml>\n<key id=\"dx\" for=\"node\" attr.name=\"x\" attr.type=\"double\"/>\n"
        "<key id=\"p\" for=\"edge\" attr.name=\"points\" attr.type=\"string\"/>\n<graph>\n"
        "<node id=\"a\"><data key=\"dx\">" + b + "</data></node>\n</graph>\n</graphml>\n";
    EXPECT_TRUE(contains(error_of([&] { graph_from_text(gml, GraphFormat::graphml, {}, "f.graphml"); }),
                         "f.graphml:5: node 'a' 'x': a coordinate is not a finite number"));
    const std::string gml_pts =
        "<graphml>\n<key id=\"p\" for=\"edge\" attr.name=\"points\" attr.type=\"string\"/>\n<graph>\n"
        "<node id=\"a\"/><node id=\"b\"/>\n<edge id=\"e\" source=\"a\" target=\"b\"><data key=\"p\">0 0 0;\n1 " + b +
        " 0</data></edge>\n</graph>\n</graphml>\n";
    EXPECT_EQ(error_of([&] { graph_from_text(gml_pts, GraphFormat::graphml, {}, "p.graphml"); }),
              "p.graphml:6: edge 'e' 'points': a coordinate is not a finite number");
    const std::string vtp = "<VTKFile type=\"PolyData\"><PolyData>\n<Piece>\n<Points>\n"
                            "<DataArray Name=\"Points\" NumberOfComponents=\"3\">0 0 0\n1 " + b +
                            " 1</DataArray></Points>\n</Piece></PolyData></VTKFile>\n";
    EXPECT_EQ(error_of([&] { graph_from_text(vtp, GraphFormat::vtp, {}, "f.vtp"); }),
              "f.vtp:5: DataArray 'Points': a coordinate is not a finite number");
    EXPECT_EQ(error_of([&] {
                graph_from_text("edge,node0,node1,point,x,y,z\n0,0,1,0,0,0,0\n0,0,1,1,1," + b + ",0\n", GraphFormat::csv,
                                "node,x,y,z\n0,0,0,0\n1,1,0,0\n", "f.csv");
              }),
              "f.csv:3: column 'y': a coordinate is not a finite number");
    EXPECT_EQ(error_of([&] {
                graph_from_text("edge,node0,node1,point,x,y,z\n", GraphFormat::csv, "node,x,y,z\n0,0,0," + b + "\n", "n.csv");
              }),
              "n.csv (nodes):2: column 'z': a coordinate is not a finite number");
  }
  // CSV node ids beyond the nodes table (also huge ones) are located errors.
  EXPECT_EQ(error_of([] {
              graph_from_text("edge,node0,node1,point,x,y,z\n0,0,1e300,0,0,0,0\n0,0,1e300,1,1,0,0\n", GraphFormat::csv,
                              "node,x,y,z\n0,0,0,0\n1,1,0,0\n", "i.csv");
            }),
            "i.csv:2: node1: node id 1.0000000000000001e+300 out of range (2 nodes)");
}

TEST(GraphIo, UnitAndPlacementTravelThroughEveryFormat) {
  auto g = sample_graph(false);
  g.unit = "mm";
  g.source_grid.unit = "mm";
  g.source_grid.direction = {0, -1, 0, 1, 0, 0, 0, 0, 1};
  const auto d = tmp_dir();
  for (const char* name : {"unit.am", "unit.vtp", "unit.graphml", "unit.swc", "unit.csv"}) {
    SCOPED_TRACE(name);
    const auto p = d / name;
    const auto f = graph_format_from_path(p);
    write_graph(g, p, f, d / "unit_nodes.csv");
    const auto r = read_graph(p, f, d / "unit_nodes.csv");
    EXPECT_EQ(r.unit, "mm");
    EXPECT_EQ(r.source_grid.unit, "mm");
    EXPECT_NEAR(r.total_length(), g.total_length(), 1e-5 * g.total_length());
    if (f == GraphFormat::amira || f == GraphFormat::vtp) {
      EXPECT_EQ(r.source_grid.origin, g.source_grid.origin);
      EXPECT_EQ(r.source_grid.direction, g.source_grid.direction);
    }
  }
  // Amira's own layout of the unit, which Amira reads.
  EXPECT_NE(graph_to_text(g, GraphFormat::amira).find("    Units {\n        Coordinates \"mm\"\n    }\n"), std::string::npos);
  // A file that names no unit gives the default one.
  SpatialGraph plain;
  plain.add_node({0, 0, 0});
  plain.add_node({1, 0, 0});
  plain.add_edge(0, 1);
  std::string swc = graph_to_text(plain, GraphFormat::swc);
  swc.erase(swc.find("# unit:"), swc.find('\n', swc.find("# unit:")) + 1 - swc.find("# unit:"));
  EXPECT_EQ(graph_from_text(swc, GraphFormat::swc).unit, kDefaultUnit);
}

TEST(GraphIo, ReadOptionsScaleCoordinatesAndRadiiAndOverrideTheUnit) {
  auto g = sample_graph(false);
  g.unit = "voxel";
  SpatialGraph r = g;
  apply_read_options(r, {.scale = 0.5, .unit = "um"});
  EXPECT_EQ(r.unit, "um");
  EXPECT_NEAR(r.total_length(), 0.5 * g.total_length(), 1e-9 * g.total_length());
  EXPECT_EQ(r.positions[1][0], 0.5 * g.positions[1][0]);
  const auto& ra = r.point_attributes.at("radius");
  const auto& ga = g.point_attributes.at("radius");
  EXPECT_FLOAT_EQ(ra[0][0], 0.5f * ga[0][0]);
  EXPECT_EQ(r.edge_attributes.at("weight"), g.edge_attributes.at("weight"));  // not a length
  EXPECT_EQ(r.node_attributes.at("score"), g.node_attributes.at("score"));
  EXPECT_TRUE(r.check_invariants().empty());
  SpatialGraph keep = g;
  apply_read_options(keep, {});
  EXPECT_EQ(keep.unit, "voxel");  // no override: the file's unit stays
  EXPECT_THROW(apply_read_options(keep, {.scale = 0.0, .unit = {}}), InputError);
}

// A Y of three polylines written by VTK's own vtkXMLPolyDataWriter (Debian's python3-vtk9) in every
// encoding it offers — appended raw and base64, inline binary, ASCII; zlib or none; UInt32 and UInt64
// headers — reads with the right points, lines and attributes. Lines share the junction's point id,
// so the three edges meet at one node.
TEST(GraphIo, ReadsVtpWrittenByVtk) {
  if (std::system("/usr/bin/python3 -c 'import vtk' >/dev/null 2>&1") != 0) GTEST_SKIP() << "python3-vtk9 is not installed";
  const auto d = tmp_dir() / "vtk_made";
  std::filesystem::remove_all(d);
  std::filesystem::create_directories(d);
  const auto script = d / "write.py";
  {
    std::ofstream py(script);
    py << R"PY(import sys, vtk
out = sys.argv[1]
pts = vtk.vtkPoints()
pts.SetDataTypeToDouble()
xyz = [(0, 0, 0), (5, 0, 0), (10, 0, 0),              # trunk: 0 -> 2
       (12, 1.5, 0), (14, 4, 0.5),                     # branch a: 2 -> 4
       (12, -1.5, 0), (14, -4, -0.5)]                  # branch b: 2 -> 6
for p in xyz: pts.InsertNextPoint(*p)
lines = vtk.vtkCellArray()
for ids in ([0, 1, 2], [2, 3, 4], [2, 5, 6]):
    lines.InsertNextCell(len(ids))
    for i in ids: lines.InsertCellPoint(i)
pd = vtk.vtkPolyData()
pd.SetPoints(pts)
pd.SetLines(lines)
r = vtk.vtkDoubleArray(); r.SetName("MaximumInscribedSphereRadius")
for i in range(len(xyz)): r.InsertNextValue(1.0 + 0.25 * i)
pd.GetPointData().AddArray(r)
t = vtk.vtkIntArray(); t.SetName("tree")
for v in (7, 8, 9): t.InsertNextValue(v)
pd.GetCellData().AddArray(t)
w = vtk.vtkFloatArray(); w.SetName("weight")
for v in (0.5, 1.5, 2.5): w.InsertNextValue(v)
pd.GetCellData().AddArray(w)
for name, mode, encode, zlib, h64 in [
        ("appended_raw_zlib", "appended", False, True, True),
        ("appended_raw_zlib_h32", "appended", False, True, False),
        ("appended_raw_plain", "appended", False, False, True),
        ("appended_base64_zlib", "appended", True, True, False),
        ("inline_binary_zlib", "binary", False, True, True),
        ("inline_binary_plain_h32", "binary", False, False, False),
        ("ascii", "ascii", False, False, True)]:
    wr = vtk.vtkXMLPolyDataWriter()
    wr.SetInputData(pd)
    wr.SetFileName(out + "/" + name + ".vtp")
    {"appended": wr.SetDataModeToAppended, "binary": wr.SetDataModeToBinary, "ascii": wr.SetDataModeToAscii}[mode]()
    wr.SetEncodeAppendedData(encode)
    if zlib: wr.SetCompressorTypeToZLib()
    else: wr.SetCompressorTypeToNone()
    if h64: wr.SetHeaderTypeToUInt64()
    else: wr.SetHeaderTypeToUInt32()
    if not wr.Write(): sys.exit(1)
)PY";
  }
  ASSERT_EQ(std::system(("/usr/bin/python3 " + script.string() + " " + d.string()).c_str()), 0);
  const std::string files[] = {"appended_raw_zlib", "appended_raw_zlib_h32", "appended_raw_plain", "appended_base64_zlib",
                               "inline_binary_zlib", "inline_binary_plain_h32", "ascii"};
  for (const auto& f : files) {
    SCOPED_TRACE(f);
    const auto p = d / (f + ".vtp");
    ASSERT_TRUE(std::filesystem::exists(p));
    const SpatialGraph g = read_graph(p, GraphFormat::vtp);
    ASSERT_EQ(g.node_count(), 4);  // the trunk's start, the junction, two ends
    ASSERT_EQ(g.edge_count(), 3);
    const auto deg = g.degrees();
    EXPECT_EQ(std::count(deg.begin(), deg.end(), 3), 1);
    EXPECT_EQ(std::count(deg.begin(), deg.end(), 1), 3);
    for (const auto& e : g.edges) EXPECT_EQ(e.points.size(), 3u);
    EXPECT_EQ(g.edges[1].points[1], (Vec3{12, 1.5, 0}));
    EXPECT_EQ(g.edges[2].points[2], (Vec3{14, -4, -0.5}));
    EXPECT_NEAR(g.total_length(), 10.0 + 2.0 * (2.5 + std::sqrt(4.0 + 6.25 + 0.25)), 1e-12);
    const auto& r = g.point_attributes.at("MaximumInscribedSphereRadius");
    EXPECT_FLOAT_EQ(r[0][1], 1.25f);
    EXPECT_FLOAT_EQ(r[2][2], 2.5f);
    EXPECT_EQ(g.edge_labels.at("tree"), (std::vector<int32_t>{7, 8, 9}));
    EXPECT_EQ(g.edge_attributes.at("weight"), (std::vector<float>{0.5f, 1.5f, 2.5f}));
    EXPECT_EQ(g.unit, kDefaultUnit);  // VTK stores no unit
  }
}

TEST(GraphIo, VtpIsWrittenBinaryCompressedByDefaultAndAsciiOnRequest) {
  auto g = sample_graph(true);
  g.unit = "nm";
  const std::string bin = graph_to_text(g, GraphFormat::vtp);
  EXPECT_NE(bin.find("compressor=\"vtkZLibDataCompressor\""), std::string::npos);
  EXPECT_NE(bin.find("<AppendedData encoding=\"raw\">"), std::string::npos);
  EXPECT_EQ(bin.find("format=\"ascii\""), std::string::npos);
  expect_same(g, graph_from_text(bin, GraphFormat::vtp), 0.0);
  const std::string ascii = graph_to_text(g, GraphFormat::vtp, nullptr, {.encoding = VtpEncoding::ascii});
  EXPECT_EQ(ascii.find("AppendedData"), std::string::npos);
  EXPECT_NE(ascii.find("format=\"ascii\""), std::string::npos);
  expect_same(g, graph_from_text(ascii, GraphFormat::vtp), 0.0);
  // Corrupt compressed data and an unsupported compressor are input errors naming the array.
  std::string bad = bin;
  bad[bad.find('_', bad.find("<AppendedData")) + 40] ^= 0x5A;
  try {
    graph_from_text(bad, GraphFormat::vtp, {}, "bad.vtp");
    ADD_FAILURE() << "corrupt data was accepted";
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("bad.vtp: DataArray"), std::string::npos) << e.what();
  }
  std::string lz4 = bin;
  lz4.replace(lz4.find("vtkZLibDataCompressor"), 21, "vtkLZ4DataCompressor");
  try {
    graph_from_text(lz4, GraphFormat::vtp, {}, "lz4.vtp");
    ADD_FAILURE() << "LZ4 was accepted";
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("lz4.vtp: unsupported compression 'vtkLZ4DataCompressor'"), std::string::npos) << e.what();
  }
}

// The other way round: VTK's own reader takes our binary .vtp (points, lines, attributes, the unit).
TEST(GraphIo, VtkReadsOurBinaryVtp) {
  if (std::system("/usr/bin/python3 -c 'import vtk' >/dev/null 2>&1") != 0) GTEST_SKIP() << "python3-vtk9 is not installed";
  auto g = sample_graph(true);
  g.unit = "mm";
  const auto d = tmp_dir() / "vtk_reads";
  std::filesystem::create_directories(d);
  write_graph(g, d / "ours.vtp", GraphFormat::vtp);
  {
    std::ofstream py(d / "read.py");
    py << R"PY(import sys, vtk
r = vtk.vtkXMLPolyDataReader()
r.SetFileName(sys.argv[1])
r.Update()
if r.GetErrorCode(): sys.exit(1)
pd = r.GetOutput()
w = pd.GetCellData().GetArray("weight")
print(pd.GetNumberOfPoints(), pd.GetNumberOfVerts(), pd.GetNumberOfLines(),
      pd.GetFieldData().GetAbstractArray("unit").GetValue(0),
      "%.9g" % sum(w.GetValue(i) for i in range(w.GetNumberOfTuples())))
)PY";
  }
  ASSERT_EQ(std::system(("/usr/bin/python3 " + (d / "read.py").string() + " " + (d / "ours.vtp").string() + " > " +
                         (d / "out.txt").string()).c_str()),
            0);
  std::ifstream in(d / "out.txt");
  int64_t points = 0, verts = 0, lines = 0;
  std::string unit;
  double weight = 0;
  in >> points >> verts >> lines >> unit >> weight;
  EXPECT_EQ(points, g.node_count() + g.point_count());
  EXPECT_EQ(verts, g.node_count());
  EXPECT_EQ(lines, g.edge_count());
  EXPECT_EQ(unit, "mm");
  double expect = 0;
  for (float x : g.edge_attributes.at("weight")) expect += x;
  EXPECT_NEAR(weight, expect, 1e-5 * expect);
}

// Integer data become int32 labels; a value outside int32 (or NaN) made the cast undefined behaviour
// (UBSan in libFuzzer: 1e11 in a GraphML <data>, -7.2e18 in VTP cell data; reproducers are seeds of
// graph_graphml and graph_vtp now). It is refused, naming the file, line and data.
TEST(GraphIo, LabelsOutsideInt32AreRefused) {
  for (const char* bad : {"1e11", "-3000000000", "nan"}) {
    const std::string b = bad;
    SCOPED_TRACE(b);
    const std::string gml_node =
        "<graphml>\n<key id=\"k\" for=\"node\" attr.name=\"kind\" attr.type=\"int\"/>\n<graph>\n"
        "<node id=\"a\"><data key=\"k\">" + b + "</data></node>\n</graph>\n</graphml>\n";
    const std::string ne = error_of([&] { graph_from_text(gml_node, GraphFormat::graphml, {}, "n.graphml"); });
    EXPECT_TRUE(contains(ne, "n.graphml:4: node 'a' 'kind': label value ")) << ne;
    EXPECT_TRUE(contains(ne, "is not a 32-bit integer")) << ne;
    const std::string gml_edge =
        "<graphml>\n<key id=\"k\" for=\"edge\" attr.name=\"tree\" attr.type=\"long\"/>\n<graph>\n"
        "<node id=\"a\"/><node id=\"b\"/>\n<edge id=\"e\" source=\"a\" target=\"b\"><data key=\"k\">" + b +
        "</data></edge>\n</graph>\n</graphml>\n";
    const std::string ee = error_of([&] { graph_from_text(gml_edge, GraphFormat::graphml, {}, "e.graphml"); });
    EXPECT_TRUE(contains(ee, "e.graphml:5: edge 'e' 'tree': label value ")) << ee;
    EXPECT_TRUE(contains(ee, "is not a 32-bit integer")) << ee;
    const std::string ce = error_of([&] {
      graph_from_text("edge,node0,node1,point,x,y,z,edge_label:tree\n0,0,1,0,0,0,0," + b + "\n0,0,1,1,1,0,0," + b + "\n",
                      GraphFormat::csv, "node,x,y,z\n0,0,0,0\n1,1,0,0\n", "e.csv");
    });
    EXPECT_TRUE(contains(ce, "e.csv:2: column 'edge_label:tree': label value ")) << ce;
    const std::string cn = error_of([&] {
      graph_from_text("edge,node0,node1,point,x,y,z\n", GraphFormat::csv, "node,x,y,z,node_label:kind\n0,0,0,0," + b + "\n", "n.csv");
    });
    EXPECT_TRUE(contains(cn, "n.csv (nodes):2: column 'node_label:kind': label value ")) << cn;
  }
  // The largest and smallest int32 still read.
  const std::string ok =
      "<graphml>\n<key id=\"k\" for=\"node\" attr.name=\"kind\" attr.type=\"int\"/>\n<graph>\n"
      "<node id=\"a\"><data key=\"k\">2147483647</data></node><node id=\"b\"><data key=\"k\">-2147483648</data></node>\n"
      "</graph>\n</graphml>\n";
  const SpatialGraph g = graph_from_text(ok, GraphFormat::graphml, {}, "ok.graphml");
  ASSERT_EQ(g.node_labels.at("kind").size(), 2u);
  EXPECT_EQ(g.node_labels.at("kind")[0], 2147483647);
  EXPECT_EQ(g.node_labels.at("kind")[1], -2147483648);
  // libFuzzer's reproducers.
  const std::filesystem::path corpus = std::filesystem::path(SKEL_SOURCE_DIR) / "fuzz" / "corpus";
  for (const auto& [file, format] : {std::pair{"graph_vtp/ubsan_huge_cell_label.vtp", GraphFormat::vtp},
                                     std::pair{"graph_graphml/ubsan_huge_int_data.graphml", GraphFormat::graphml}}) {
    std::ifstream in(corpus / file, std::ios::binary);
    ASSERT_TRUE(in) << file;
    const std::string text((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
    const std::string e = error_of([&] { graph_from_text(text, format, {}, file); });
    EXPECT_TRUE(contains(e, std::string(file) + ":")) << e;
    EXPECT_TRUE(contains(e, "is not a 32-bit integer")) << e;
  }
}
