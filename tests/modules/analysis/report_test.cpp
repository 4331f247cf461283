// analysis.report: the numbers in the page, one self-contained file, SVG that parses as XML, and a
// PNG that decodes (signature, IHDR, CRCs, IDAT inflating to the expected size and pixels).
#include <expat.h>
#include <gtest/gtest.h>
#include <zlib.h>

#include <cmath>
#include <filesystem>
#include <fstream>
#include <sstream>

#include "analysis/report.hpp"
#include "skel/text.hpp"
#include "skel/run_module.hpp"
#include "skel/spatial_graph.hpp"
#include "skel/volume.hpp"

using namespace skel;
using namespace skel::analysis;

namespace {

// Three edges: (0,0,0)-(3,4,0) length 5 (radius 1), (3,4,0)-(3,4,10) length 10 (radius 2), and
// (0,0,0)-(0,0,10)-(3,4,10) length 15 (radius 3): total 30, one loop-free triangle.
SpatialGraph triangle() {
  SpatialGraph g;
  g.unit = "mm";
  const int64_t a = g.add_node({0, 0, 0}), b = g.add_node({3, 4, 0}), c = g.add_node({3, 4, 10});
  g.add_edge(a, b);
  g.add_edge(b, c);
  g.add_edge(a, c, {{0, 0, 0}, {0, 0, 10}, {3, 4, 10}});
  auto& r = g.point_attributes["radius"];
  r.resize(3);
  for (size_t e = 0; e < 3; ++e) r[e].assign(g.edges[e].points.size(), static_cast<float>(e + 1));
  return g;
}

// The <svg>...</svg> blocks of a page.
std::vector<std::string> svg_blocks(const std::string& html) {
  std::vector<std::string> out;
  for (size_t p = html.find("<svg"); p != std::string::npos; p = html.find("<svg", p + 1)) {
    const size_t e = html.find("</svg>", p);
    EXPECT_NE(e, std::string::npos);
    out.push_back(html.substr(p, e + 6 - p));
  }
  return out;
}

struct SvgInfo {
  std::string id;
  int64_t bars = 0, count_sum = 0, polylines = 0, images = 0;
};
void XMLCALL on_start(void* ud, const XML_Char* name, const XML_Char** attrs) {
  auto* s = static_cast<SvgInfo*>(ud);
  const std::string n = name;
  std::map<std::string, std::string> a;
  for (int i = 0; attrs[i]; i += 2) a[attrs[i]] = attrs[i + 1];
  if (n == "svg") s->id = a["id"];
  if (n == "rect" && a["class"] == "bar") ++s->bars, s->count_sum += std::stoll(a.at("data-count"));
  if (n == "polyline") ++s->polylines;
  if (n == "image") ++s->images;
}
SvgInfo parse_svg(const std::string& svg) {
  SvgInfo info;
  XML_Parser p = XML_ParserCreate("UTF-8");
  XML_SetUserData(p, &info);
  XML_SetStartElementHandler(p, on_start);
  const auto st = XML_Parse(p, svg.data(), static_cast<int>(svg.size()), 1);
  EXPECT_EQ(st, XML_STATUS_OK) << XML_ErrorString(XML_GetErrorCode(p)) << " at line " << XML_GetCurrentLineNumber(p);
  XML_ParserFree(p);
  return info;
}


uint32_t be32(const std::string& s, size_t at) {
  return (uint32_t(uint8_t(s[at])) << 24) | (uint32_t(uint8_t(s[at + 1])) << 16) | (uint32_t(uint8_t(s[at + 2])) << 8) |
         uint8_t(s[at + 3]);
}

struct Png {
  uint32_t w = 0, h = 0;
  std::vector<uint8_t> pixels;
};
// Decodes an 8-bit greyscale PNG checking every CRC; filter bytes must be 0 (what the writer emits).
Png decode_png(const std::string& png) {
  Png out;
  EXPECT_EQ(png.substr(0, 8), std::string("\x89PNG\r\n\x1a\n", 8));
  std::string idat;
  std::vector<std::string> types;
  for (size_t p = 8; p + 12 <= png.size();) {
    const uint32_t len = be32(png, p);
    const std::string td = png.substr(p + 4, 4 + len);
    const uint32_t crc = be32(png, p + 8 + len);
    EXPECT_EQ(crc, static_cast<uint32_t>(crc32(0L, reinterpret_cast<const Bytef*>(td.data()), static_cast<uInt>(td.size()))))
        << td.substr(0, 4);
    types.push_back(td.substr(0, 4));
    if (types.back() == "IHDR") {
      out.w = be32(td, 4), out.h = be32(td, 8);
      EXPECT_EQ(td[12], 8);  // bit depth
      EXPECT_EQ(td[13], 0);  // greyscale
    }
    if (types.back() == "IDAT") idat += td.substr(4);
    p += 12 + len;
  }
  EXPECT_EQ(types, (std::vector<std::string>{"IHDR", "IDAT", "IEND"}));
  uLongf n = (out.w + 1) * out.h;
  std::string raw(n, '\0');
  EXPECT_EQ(uncompress(reinterpret_cast<Bytef*>(raw.data()), &n, reinterpret_cast<const Bytef*>(idat.data()),
                       static_cast<uLong>(idat.size())),
            Z_OK);
  EXPECT_EQ(n, (out.w + 1) * out.h);
  for (uint32_t y = 0; y < out.h; ++y) {
    EXPECT_EQ(raw[y * (out.w + 1)], 0) << "filter byte of row " << y;
    for (uint32_t x = 0; x < out.w; ++x) out.pixels.push_back(static_cast<uint8_t>(raw[y * (out.w + 1) + 1 + x]));
  }
  return out;
}

std::string td_value(const std::string& html, const std::string& id) {
  const std::string key = "id=\"" + id + "\">";
  const size_t p = html.find(key);
  EXPECT_NE(p, std::string::npos) << id;
  if (p == std::string::npos) return {};
  const size_t b = p + key.size();
  return html.substr(b, html.find('<', b) - b);
}

}  // namespace

TEST(ReportHistogram, NiceEdgesCoverValuesAndCountsSum) {
  const std::vector<double> v{0.13, 0.5, 1.7, 2.2, 3.99, std::nan(""), 2.0};
  const Histogram h = nice_histogram(v, 10);
  ASSERT_EQ(h.counts.size() + 1, h.edges.size());
  EXPECT_LE(h.edges.front(), 0.13);
  EXPECT_GE(h.edges.back(), 3.99);
  const double step = h.edges[1] - h.edges[0];
  EXPECT_NEAR(step, 0.5, 1e-12);  // (3.99 - 0.13) / 10 = 0.386 -> 0.5
  int64_t sum = 0;
  for (auto c : h.counts) sum += c;
  EXPECT_EQ(sum, 6);  // NaN left out
  EXPECT_EQ(h.counts[0], 1);  // [0, 0.5): 0.13
  const Histogram one = nice_histogram({7.0, 7.0}, 5);
  ASSERT_EQ(one.counts.size(), 1u);
  EXPECT_EQ(one.counts[0], 2);
  EXPECT_TRUE(nice_histogram({std::nan("")}, 5).counts.empty());
}

TEST(ReportPng, EncodesAndDecodesGreyscale) {
  std::vector<uint8_t> px(7 * 5);
  for (size_t i = 0; i < px.size(); ++i) px[i] = static_cast<uint8_t>(i * 7);
  const Png p = decode_png(encode_png_gray8(7, 5, px));
  EXPECT_EQ(p.w, 7u);
  EXPECT_EQ(p.h, 5u);
  EXPECT_EQ(p.pixels, px);
  EXPECT_THROW(encode_png_gray8(3, 3, px), Error);
}

TEST(Report, NumbersSelfContainedSvgAndPng) {
  auto g = std::make_shared<SpatialGraph>(triangle());
  auto img = std::make_shared<VolumeU16>(Grid{Dims{8, 6, 4}, {1, 1, 1}, {0, 0, 0}, "mm"}, uint16_t{10});
  (*img)(2, 3, 1) = 500;
  const auto dir = std::filesystem::path(SKEL_BINARY_DIR) / "tests" / "report_test_out";
  std::filesystem::remove_all(dir);
  std::filesystem::create_directories(dir);
  auto st = run_module("analysis.network_statistics", {{"graph", g}});
  run_module("analysis.report",
             {{"graph", st.data("graph")}, {"summary", st.data("summary")}, {"segments", st.data("segments")}, {"image", img}},
             {{"path", ParamValue((dir / "report.html").string())}, {"title", ParamValue(std::string("Triangle <test>"))}});
  // one file, nothing else left behind
  std::vector<std::string> files;
  for (const auto& e : std::filesystem::directory_iterator(dir)) files.push_back(e.path().filename().string());
  EXPECT_EQ(files, std::vector<std::string>{"report.html"});
  std::ifstream f(dir / "report.html", std::ios::binary);
  std::stringstream ss;
  ss << f.rdbuf();
  const std::string html = ss.str();

  EXPECT_NE(html.find("<title>Triangle &lt;test&gt;</title>"), std::string::npos);
  EXPECT_EQ(td_value(html, "edges"), "3");
  EXPECT_EQ(td_value(html, "nodes"), "3");
  EXPECT_DOUBLE_EQ(std::stod(td_value(html, "total_length")), 30.0);
  EXPECT_EQ(td_value(html, "branch_points"), "0");
  EXPECT_NE(html.find("<td>total_length</td><td>30</td><td>mm</td>"), std::string::npos);  // summary with unit
  EXPECT_NE(html.find("segment length [mm]"), std::string::npos);
  EXPECT_NE(html.find("mean radius [mm]"), std::string::npos);

  // self-contained: no scripts, no links, no src; the only URL is the SVG namespace, hrefs are data URIs
  EXPECT_EQ(html.find("<script"), std::string::npos);
  EXPECT_EQ(html.find("<link"), std::string::npos);
  EXPECT_EQ(html.find("src="), std::string::npos);
  for (size_t p = html.find("http"); p != std::string::npos; p = html.find("http", p + 1))
    EXPECT_EQ(html.compare(p, 26, "http://www.w3.org/2000/svg"), 0) << html.substr(p, 40);
  for (size_t p = html.find("href=\""); p != std::string::npos; p = html.find("href=\"", p + 1))
    EXPECT_EQ(html.compare(p + 6, 5, "data:"), 0);

  const auto blocks = svg_blocks(html);
  ASSERT_EQ(blocks.size(), 5u);  // 4 histograms + the network
  std::map<std::string, SvgInfo> by_id;
  for (const auto& b : blocks) {
    const SvgInfo i = parse_svg(b);
    by_id[i.id] = i;
  }
  for (const char* id : {"hist_radius", "hist_length", "hist_tortuosity", "hist_inclination"}) {
    ASSERT_TRUE(by_id.count(id)) << id;
    EXPECT_EQ(by_id[id].count_sum, 3) << id;
    EXPECT_GE(by_id[id].bars, 1) << id;
  }
  EXPECT_EQ(by_id["hist_inclination"].bars, 9);
  EXPECT_EQ(by_id["network"].polylines, 3);
  EXPECT_EQ(by_id["network"].images, 1);

  const std::string key = "data:image/png;base64,";
  const size_t p = html.find(key);
  ASSERT_NE(p, std::string::npos);
  const size_t e = html.find('"', p);
  const Png png = decode_png(text::base64_decode(html.substr(p + key.size(), e - p - key.size()), "report image"));
  ASSERT_EQ(png.w, 8u);
  ASSERT_EQ(png.h, 6u);
  for (uint32_t y = 0; y < 6; ++y)
    for (uint32_t x = 0; x < 8; ++x) EXPECT_EQ(png.pixels[y * 8 + x], (x == 2 && y == 3) ? 255 : 0) << x << "," << y;
}

TEST(Report, TreesFromLabelsAndNoImage) {
  SpatialGraph g = triangle();
  g.edge_labels["tree"] = {1, 1, 0};
  const std::string html = make_report_html({.graph = &g});
  EXPECT_NE(html.find("<h2>Trees</h2>"), std::string::npos);
  EXPECT_NE(html.find("<tr><td>1</td><td>2</td><td>15</td></tr>"), std::string::npos);  // tree 1: 2 edges, 15 mm
  EXPECT_EQ(html.find("data:image/png"), std::string::npos);
  for (const auto& b : svg_blocks(html)) (void)parse_svg(b);
}

TEST(Report, ErrorsNameThePort) {
  auto g = std::make_shared<SpatialGraph>(triangle());
  auto seg = std::make_shared<Table>();
  seg->add("length", std::vector<double>{1.0});
  try {
    run_module("analysis.report", {{"graph", g}, {"segments", seg}}, {{"path", ParamValue(std::string("x.html"))}});
    FAIL() << "expected InputError";
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("input 'segments'"), std::string::npos) << e.what();
  }
  auto img = std::make_shared<VolumeU8>(Grid{Dims{2, 2, 2}, {1, 1, 1}, {0, 0, 0}, "µm"});
  try {
    run_module("analysis.report", {{"graph", g}, {"image", img}}, {{"path", ParamValue(std::string("x.html"))}});
    FAIL() << "expected an error for the unit mismatch";
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find("image"), std::string::npos) << e.what();
  }
  EXPECT_FALSE(std::filesystem::exists("x.html"));
}
