#include "analysis/report.hpp"

#include "skel/text.hpp"

#include <zlib.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <limits>
#include <map>
#include <numbers>
#include <sstream>

#include "skel/error.hpp"
#include "skel/units.hpp"
#include "skel/volume.hpp"

namespace skel::analysis {
namespace {

constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();

std::string num(double v, int digits = 4) {
  if (std::isnan(v)) return "NaN";
  if (std::isinf(v)) return v > 0 ? "inf" : "-inf";
  if (v == 0.0) return "0";
  char buf[64];
  std::snprintf(buf, sizeof buf, "%.*g", digits, v);
  return buf;
}

std::string esc(const std::string& s) {
  std::string o;
  o.reserve(s.size());
  for (char c : s) {
    switch (c) {
      case '&': o += "&amp;"; break;
      case '<': o += "&lt;"; break;
      case '>': o += "&gt;"; break;
      case '"': o += "&quot;"; break;
      default: o += c;
    }
  }
  return o;
}

// Smallest step of the form {1, 2, 2.5, 5} × 10^k that is >= raw (raw > 0).
double nice_step(double raw) {
  const double p = std::pow(10.0, std::floor(std::log10(raw)));
  for (double m : {1.0, 2.0, 2.5, 5.0, 10.0})
    if (m * p >= raw * (1 - 1e-12)) return m * p;
  return 10.0 * p;
}

double length_of(const std::vector<Vec3>& pts) {
  double l = 0;
  for (size_t i = 1; i < pts.size(); ++i) {
    const double dx = pts[i][0] - pts[i - 1][0], dy = pts[i][1] - pts[i - 1][1], dz = pts[i][2] - pts[i - 1][2];
    l += std::sqrt(dx * dx + dy * dy + dz * dz);
  }
  return l;
}

// ---------------------------------------------------------------------------------------------
// SVG histogram: bars with data-count, x ticks at (a subset of) the bin edges, y ticks at nice
// integer counts, axis titles with units.
std::string svg_histogram(const Histogram& h, const std::string& id, const std::string& xlabel) {
  const double W = 520, H = 280, L = 56, R = 12, T = 16, B = 48;
  std::ostringstream s;
  s << "<svg xmlns=\"http://www.w3.org/2000/svg\" id=\"" << id << "\" class=\"histogram\" width=\"" << W
    << "\" height=\"" << H << "\" viewBox=\"0 0 " << W << ' ' << H << "\">\n";
  s << "<rect x=\"0\" y=\"0\" width=\"" << W << "\" height=\"" << H << "\" fill=\"#fff\"/>\n";
  if (h.counts.empty()) {
    s << "<text x=\"" << W / 2 << "\" y=\"" << H / 2 << "\" text-anchor=\"middle\">no values</text>\n</svg>\n";
    return s.str();
  }
  const int64_t maxc = std::max<int64_t>(1, *std::max_element(h.counts.begin(), h.counts.end()));
  double ystep = std::max(1.0, nice_step(static_cast<double>(maxc) / 5.0));
  if (ystep == 2.5) ystep = 2.0;  // counts are whole numbers
  const double ytop = std::ceil(static_cast<double>(maxc) / ystep) * ystep;
  const double x0 = h.edges.front(), x1 = h.edges.back();
  const double pw = W - L - R, ph = H - T - B;
  auto X = [&](double v) { return L + (v - x0) / (x1 - x0) * pw; };
  auto Y = [&](double c) { return T + ph - c / ytop * ph; };
  // grid and y ticks
  for (double c = 0; c <= ytop + 0.5 * ystep; c += ystep) {
    s << "<line x1=\"" << L << "\" y1=\"" << num(Y(c), 6) << "\" x2=\"" << L + pw << "\" y2=\"" << num(Y(c), 6)
      << "\" stroke=\"#ddd\"/>\n";
    s << "<text x=\"" << L - 5 << "\" y=\"" << num(Y(c) + 4, 6) << "\" font-size=\"11\" text-anchor=\"end\">"
      << num(c, 6) << "</text>\n";
  }
  // bars
  for (size_t i = 0; i < h.counts.size(); ++i) {
    const double xa = X(h.edges[i]), xb = X(h.edges[i + 1]);
    const double y = Y(static_cast<double>(h.counts[i]));
    s << "<rect class=\"bar\" data-count=\"" << h.counts[i] << "\" data-from=\"" << num(h.edges[i], 10)
      << "\" data-to=\"" << num(h.edges[i + 1], 10) << "\" x=\"" << num(xa + 0.5, 6) << "\" y=\"" << num(y, 6)
      << "\" width=\"" << num(std::max(0.5, xb - xa - 1), 6) << "\" height=\"" << num(T + ph - y, 6)
      << "\" fill=\"#4a7ab5\"><title>" << num(h.edges[i]) << " – " << num(h.edges[i + 1]) << ": " << h.counts[i]
      << "</title></rect>\n";
    if (h.counts[i] > 0 && h.counts.size() <= 30)
      s << "<text x=\"" << num((xa + xb) / 2, 6) << "\" y=\"" << num(y - 3, 6)
        << "\" font-size=\"9\" text-anchor=\"middle\" fill=\"#333\">" << h.counts[i] << "</text>\n";
  }
  // axes
  s << "<line x1=\"" << L << "\" y1=\"" << T + ph << "\" x2=\"" << L + pw << "\" y2=\"" << T + ph
    << "\" stroke=\"#000\"/>\n<line x1=\"" << L << "\" y1=\"" << T << "\" x2=\"" << L << "\" y2=\"" << T + ph
    << "\" stroke=\"#000\"/>\n";
  const size_t nb = h.counts.size();
  const size_t every = std::max<size_t>(1, (nb + 5) / 6);
  for (size_t i = 0; i <= nb; i += every) {
    const double x = X(h.edges[i]);
    s << "<line x1=\"" << num(x, 6) << "\" y1=\"" << T + ph << "\" x2=\"" << num(x, 6) << "\" y2=\"" << T + ph + 5
      << "\" stroke=\"#000\"/>\n<text x=\"" << num(x, 6) << "\" y=\"" << T + ph + 17
      << "\" font-size=\"11\" text-anchor=\"middle\">" << num(h.edges[i]) << "</text>\n";
  }
  s << "<text x=\"" << L + pw / 2 << "\" y=\"" << H - 8 << "\" font-size=\"12\" text-anchor=\"middle\">"
    << esc(xlabel) << "</text>\n";
  s << "<text x=\"14\" y=\"" << T + ph / 2 << "\" font-size=\"12\" text-anchor=\"middle\" transform=\"rotate(-90 14 "
    << T + ph / 2 << ")\">edges</text>\n</svg>\n";
  return s.str();
}

std::string html_table(const Table& t, const std::string& cls) {
  std::ostringstream s;
  s << "<table class=\"" << cls << "\">\n<tr>";
  for (const auto& c : t.columns()) s << "<th>" << esc(c.name) << (c.unit.empty() ? "" : " [" + esc(c.unit) + "]") << "</th>";
  s << "</tr>\n";
  for (int64_t r = 0; r < t.rows(); ++r) {
    s << "<tr>";
    for (size_t c = 0; c < t.columns().size(); ++c) s << "<td>" << esc(t.cell(c, r)) << "</td>";
    s << "</tr>\n";
  }
  s << "</table>\n";
  return s.str();
}

// One-row table shown transposed: name | value | unit.
std::string html_summary(const Table& t) {
  std::ostringstream s;
  s << "<table class=\"summary\">\n<tr><th>quantity</th><th>value</th><th>unit</th></tr>\n";
  for (size_t c = 0; c < t.columns().size(); ++c) {
    const auto& col = t.columns()[c];
    std::string v;
    if (t.rows() > 0) {
      if (auto* d = std::get_if<std::vector<double>>(&col.values)) v = num((*d)[0], 6);
      else v = t.cell(c, 0);
    }
    s << "<tr><td>" << esc(col.name) << "</td><td>" << esc(v) << "</td><td>" << esc(col.unit) << "</td></tr>\n";
  }
  s << "</table>\n";
  return s.str();
}

struct Mip {
  int64_t w = 0, h = 0, stride = 1;
  std::vector<uint8_t> pixels;
  Grid grid;
};

Mip make_mip(const DataObject& image, int64_t max_size) {
  return visit_volume(image, "input 'image'", [&](const auto& v) {
    Mip m;
    m.grid = v.grid();
    const int64_t nx = v.nx(), ny = v.ny(), nz = v.nz();
    if (nx <= 0 || ny <= 0 || nz <= 0) throw InputError("input 'image': empty volume");
    m.stride = std::max<int64_t>(1, (std::max(nx, ny) + max_size - 1) / max_size);
    m.w = (nx + m.stride - 1) / m.stride;
    m.h = (ny + m.stride - 1) / m.stride;
    std::vector<double> mx(static_cast<size_t>(m.w * m.h), -std::numeric_limits<double>::infinity());
    const auto* d = v.data();
    for (int64_t z = 0; z < nz; ++z)
      for (int64_t y = 0; y < ny; ++y) {
        const auto* row = d + (y + ny * z) * nx;
        double* out = mx.data() + (y / m.stride) * m.w;
        for (int64_t x = 0; x < nx; ++x) {
          const double val = static_cast<double>(row[x]);
          if (val > out[x / m.stride]) out[x / m.stride] = val;
        }
      }
    double lo = std::numeric_limits<double>::infinity(), hi = -lo;
    for (double q : mx)
      if (std::isfinite(q)) lo = std::min(lo, q), hi = std::max(hi, q);
    m.pixels.resize(mx.size(), 0);
    if (hi > lo)
      for (size_t i = 0; i < mx.size(); ++i)
        m.pixels[i] = std::isfinite(mx[i]) ? static_cast<uint8_t>(std::lround((mx[i] - lo) / (hi - lo) * 255.0)) : 0;
    return m;
  });
}

std::string svg_network(const SpatialGraph& g, const DataObject* image, const ReportOptions& o) {
  double xa, ya, xb, yb;
  std::string img;
  if (image) {
    const Mip m = make_mip(*image, o.max_image_size);
    const Grid& gr = m.grid;
    xa = gr.origin[0] - 0.5 * gr.spacing[0];
    ya = gr.origin[1] - 0.5 * gr.spacing[1];
    xb = xa + static_cast<double>(gr.dims[0]) * gr.spacing[0];
    yb = ya + static_cast<double>(gr.dims[1]) * gr.spacing[1];
    const double iw = static_cast<double>(m.w * m.stride) * gr.spacing[0];
    const double ih = static_cast<double>(m.h * m.stride) * gr.spacing[1];
    img = "<image class=\"mip\" x=\"" + num(xa, 10) + "\" y=\"" + num(ya, 10) + "\" width=\"" + num(iw, 10) +
          "\" height=\"" + num(ih, 10) + "\" preserveAspectRatio=\"none\" style=\"image-rendering:pixelated\" href=\"data:image/png;base64," +
          text::base64_encode(encode_png_gray8(m.w, m.h, m.pixels)) + "\"/>\n";
  } else {
    xa = ya = std::numeric_limits<double>::infinity();
    xb = yb = -xa;
    for (const auto& e : g.edges)
      for (const auto& p : e.points) xa = std::min(xa, p[0]), xb = std::max(xb, p[0]), ya = std::min(ya, p[1]), yb = std::max(yb, p[1]);
    for (const auto& p : g.positions) xa = std::min(xa, p[0]), xb = std::max(xb, p[0]), ya = std::min(ya, p[1]), yb = std::max(yb, p[1]);
    if (!std::isfinite(xa)) xa = ya = 0, xb = yb = 1;
    const double pad = 0.05 * std::max({xb - xa, yb - ya, 1e-9});
    xa -= pad, ya -= pad, xb += pad, yb += pad;
  }
  const double bw = std::max(xb - xa, 1e-12), bh = std::max(yb - ya, 1e-12);
  const double scale = 640.0 / std::max(bw, bh);
  std::ostringstream s;
  s << "<svg xmlns=\"http://www.w3.org/2000/svg\" id=\"network\" width=\"" << num(bw * scale, 6) << "\" height=\""
    << num(bh * scale, 6) << "\" viewBox=\"" << num(xa, 10) << ' ' << num(ya, 10) << ' ' << num(bw, 10) << ' '
    << num(bh, 10) << "\">\n<rect x=\"" << num(xa, 10) << "\" y=\"" << num(ya, 10) << "\" width=\"" << num(bw, 10)
    << "\" height=\"" << num(bh, 10) << "\" fill=\"#000\"/>\n"
    << img << "<g fill=\"none\" stroke=\"#ff5a36\" stroke-width=\"1.5\" stroke-linejoin=\"round\" vector-effect=\"non-scaling-stroke\">\n";
  for (const auto& e : g.edges) {
    s << "<polyline class=\"edge\" vector-effect=\"non-scaling-stroke\" points=\"";
    for (size_t i = 0; i < e.points.size(); ++i) s << (i ? " " : "") << num(e.points[i][0], 7) << ',' << num(e.points[i][1], 7);
    s << "\"/>\n";
  }
  s << "</g>\n</svg>\n";
  return s.str();
}

}  // namespace

Histogram nice_histogram(const std::vector<double>& values, int bins) {
  Histogram h;
  double lo = std::numeric_limits<double>::infinity(), hi = -lo;
  for (double v : values)
    if (std::isfinite(v)) lo = std::min(lo, v), hi = std::max(hi, v);
  if (!std::isfinite(lo)) return h;
  bins = std::max(1, bins);
  double raw = (hi - lo) / bins;
  if (!(raw > 0)) raw = std::max(std::abs(lo), 1.0) * 0.1;
  const double step = nice_step(raw);
  const double start = std::floor(lo / step) * step;
  int64_t n = std::max<int64_t>(1, static_cast<int64_t>(std::ceil((hi - start) / step - 1e-9)));
  if (start + static_cast<double>(n) * step < hi) ++n;
  for (int64_t i = 0; i <= n; ++i) h.edges.push_back(start + static_cast<double>(i) * step);
  h.counts.assign(static_cast<size_t>(n), 0);
  for (double v : values)
    if (std::isfinite(v)) {
      auto k = static_cast<int64_t>(std::floor((v - start) / step));
      ++h.counts[static_cast<size_t>(std::clamp<int64_t>(k, 0, n - 1))];
    }
  return h;
}

Histogram fixed_histogram(const std::vector<double>& values, double lo, double hi, int bins) {
  Histogram h;
  bins = std::max(1, bins);
  for (int i = 0; i <= bins; ++i) h.edges.push_back(lo + (hi - lo) * i / bins);
  h.counts.assign(static_cast<size_t>(bins), 0);
  for (double v : values)
    if (std::isfinite(v)) {
      auto k = static_cast<int64_t>(std::floor((v - lo) / (hi - lo) * bins));
      ++h.counts[static_cast<size_t>(std::clamp<int64_t>(k, 0, bins - 1))];
    }
  return h;
}

EdgeValues report_edge_values(const SpatialGraph& g, const std::string& radius_attribute) {
  EdgeValues ev;
  const auto n = static_cast<size_t>(g.edge_count());
  ev.length.resize(n), ev.tortuosity.resize(n), ev.inclination.resize(n);
  const auto ra = g.point_attributes.find(radius_attribute);
  const auto em = g.edge_attributes.find("mean_radius");
  const bool has_r = em != g.edge_attributes.end() || ra != g.point_attributes.end();
  if (has_r) ev.radius.resize(n);
  for (size_t e = 0; e < n; ++e) {
    const auto& ed = g.edges[e];
    const auto& pts = ed.points;
    const double len = length_of(pts);
    ev.length[e] = len;
    const double dx = pts.back()[0] - pts.front()[0], dy = pts.back()[1] - pts.front()[1], dz = pts.back()[2] - pts.front()[2];
    const double chord = std::sqrt(dx * dx + dy * dy + dz * dz);
    if (ed.node0 == ed.node1 || chord <= 0) {
      ev.tortuosity[e] = kNaN;
      ev.inclination[e] = kNaN;
    } else {
      ev.tortuosity[e] = len / chord;
      ev.inclination[e] = std::acos(std::min(1.0, std::abs(dz) / chord)) * 180.0 / std::numbers::pi;
    }
    if (!has_r) continue;
    if (em != g.edge_attributes.end()) {
      ev.radius[e] = em->second[e];
      continue;
    }
    const auto& r = ra->second[e];
    double wsum = 0, rsum = 0;
    for (size_t i = 1; i < pts.size(); ++i) {
      const double w = length_of({pts[i - 1], pts[i]});
      wsum += w;
      rsum += w * 0.5 * (static_cast<double>(r[i - 1]) + static_cast<double>(r[i]));
    }
    ev.radius[e] = wsum > 0 ? rsum / wsum : static_cast<double>(r.empty() ? 0.0f : r[0]);
  }
  return ev;
}

std::string encode_png_gray8(int64_t width, int64_t height, const std::vector<uint8_t>& pixels) {
  if (width <= 0 || height <= 0 || static_cast<int64_t>(pixels.size()) != width * height)
    throw Error("encode_png_gray8: " + std::to_string(pixels.size()) + " pixels for " + std::to_string(width) + "x" +
                std::to_string(height));
  if (width > 0x7fffffff || height > 0x7fffffff) throw Error("encode_png_gray8: image too large for PNG");
  std::string raw;
  raw.reserve(static_cast<size_t>((width + 1) * height));
  for (int64_t y = 0; y < height; ++y) {
    raw.push_back('\0');  // filter type 0 (none)
    raw.append(reinterpret_cast<const char*>(pixels.data() + y * width), static_cast<size_t>(width));
  }
  uLongf zlen = compressBound(static_cast<uLong>(raw.size()));
  std::string z(zlen, '\0');
  if (compress2(reinterpret_cast<Bytef*>(z.data()), &zlen, reinterpret_cast<const Bytef*>(raw.data()),
                static_cast<uLong>(raw.size()), 6) != Z_OK)
    throw Error("encode_png_gray8: zlib compression failed");
  z.resize(zlen);
  auto be32 = [](std::string& s, uint32_t v) {
    for (int sh = 24; sh >= 0; sh -= 8) s.push_back(static_cast<char>((v >> sh) & 0xff));
  };
  std::string png("\x89PNG\r\n\x1a\n", 8);
  auto chunk = [&](const char* type, const std::string& data) {
    be32(png, static_cast<uint32_t>(data.size()));
    const std::string td = std::string(type, 4) + data;
    png += td;
    be32(png, static_cast<uint32_t>(crc32(0L, reinterpret_cast<const Bytef*>(td.data()), static_cast<uInt>(td.size()))));
  };
  std::string ihdr;
  be32(ihdr, static_cast<uint32_t>(width));
  be32(ihdr, static_cast<uint32_t>(height));
  ihdr += std::string("\x08\x00\x00\x00\x00", 5);  // bit depth 8, greyscale, deflate, filter 0, no interlace
  chunk("IHDR", ihdr);
  chunk("IDAT", z);
  chunk("IEND", {});
  return png;
}


std::string make_report_html(const ReportInputs& in, const ReportOptions& o) {
  if (!in.graph) throw Error("make_report_html: no graph");
  const SpatialGraph& g = *in.graph;
  const std::string& unit = g.unit;
  if (in.image) units::check_same(unit, "input 'graph'", in.image->physical_unit(), "input 'image'");
  EdgeValues ev = report_edge_values(g, o.radius);
  // Columns of the statistics table, when connected, are what analysis.network_statistics computed.
  if (in.segments) {
    if (in.segments->rows() != g.edge_count())
      throw InputError("input 'segments': " + std::to_string(in.segments->rows()) + " rows for a graph of " +
                       std::to_string(g.edge_count()) + " edges (connect the segments of the same graph)");
    auto take = [&](const char* name, std::vector<double>& dst) {
      if (in.segments->has(name)) dst = in.segments->reals(name);
    };
    take("length", ev.length);
    take("tortuosity", ev.tortuosity);
    take("mean_radius", ev.radius);
  }
  double total = 0;
  for (double l : ev.length) total += l;
  int64_t branch = 0, ends = 0;
  {
    std::vector<int64_t> deg(static_cast<size_t>(g.node_count()), 0);
    for (const auto& e : g.edges) ++deg[static_cast<size_t>(e.node0)], ++deg[static_cast<size_t>(e.node1)];
    for (int64_t d : deg) branch += d >= 3, ends += d == 1;
  }

  std::ostringstream s;
  s << "<!DOCTYPE html>\n<html lang=\"en\">\n<head>\n<meta charset=\"utf-8\">\n<title>" << esc(o.title)
    << "</title>\n<style>\nbody{font-family:sans-serif;margin:2em;color:#222;max-width:1150px}\n"
       "table{border-collapse:collapse;margin:0.5em 0 1.5em}\ntd,th{border:1px solid #bbb;padding:3px 8px;text-align:right}\n"
       "th{background:#eee}\n.plots{display:flex;flex-wrap:wrap;gap:12px}\nfigure{margin:0}\nfigcaption{font-size:90%;color:#555}\n"
       "</style>\n</head>\n<body>\n<h1>"
    << esc(o.title) << "</h1>\n";
  s << "<h2>Graph</h2>\n<table class=\"graph\">\n<tr><th>quantity</th><th>value</th><th>unit</th></tr>\n"
    << "<tr><td>nodes</td><td id=\"nodes\">" << g.node_count() << "</td><td></td></tr>\n"
    << "<tr><td>edges</td><td id=\"edges\">" << g.edge_count() << "</td><td></td></tr>\n"
    << "<tr><td>total length</td><td id=\"total_length\">" << num(total, 6) << "</td><td>" << esc(unit) << "</td></tr>\n"
    << "<tr><td>branch points (degree &ge; 3)</td><td id=\"branch_points\">" << branch << "</td><td></td></tr>\n"
    << "<tr><td>end points (degree 1)</td><td id=\"end_points\">" << ends << "</td><td></td></tr>\n</table>\n";
  if (in.summary) s << "<h2>Summary statistics</h2>\n" << html_summary(*in.summary);

  s << "<h2>Distributions</h2>\n<div class=\"plots\">\n";
  auto fig = [&](const std::string& svg, const std::string& caption) {
    s << "<figure>\n" << svg << "<figcaption>" << esc(caption) << "</figcaption>\n</figure>\n";
  };
  if (!ev.radius.empty())
    fig(svg_histogram(nice_histogram(ev.radius, o.bins), "hist_radius", "mean radius [" + unit + "]"),
        "Length-weighted mean radius per edge");
  fig(svg_histogram(nice_histogram(ev.length, o.bins), "hist_length", "segment length [" + unit + "]"),
      "Polyline length per edge");
  fig(svg_histogram(nice_histogram(ev.tortuosity, o.bins), "hist_tortuosity", "tortuosity (length / chord) [1]"),
      "Tortuosity per edge (loops excluded)");
  fig(svg_histogram(fixed_histogram(ev.inclination, 0.0, 90.0, 9), "hist_inclination", "inclination to z [°]"),
      "Angle between each edge's chord and the z axis (loops excluded)");
  s << "</div>\n";

  if (in.trees && in.trees->rows() > 0) {
    s << "<h2>Trees</h2>\n" << html_table(*in.trees, "trees");
  } else if (auto it = g.edge_labels.find("tree"); it != g.edge_labels.end()) {
    std::map<int32_t, std::pair<int64_t, double>> per;
    for (size_t e = 0; e < it->second.size(); ++e) {
      auto& p = per[it->second[e]];
      ++p.first;
      p.second += ev.length[e];
    }
    Table t;
    std::vector<int64_t> id, edges;
    std::vector<double> len;
    for (const auto& [k, v] : per) id.push_back(k), edges.push_back(v.first), len.push_back(v.second);
    t.add("tree", id).add("edges", edges).add("total_length", len, unit);
    s << "<h2>Trees</h2>\n<p>Tree 0: edges in no tree (capillary bed).</p>\n" << html_table(t, "trees");
  }

  s << "<h2>Network</h2>\n<figure>\n" << svg_network(g, in.image, o) << "<figcaption>Edges projected along z"
    << (in.image ? " over the maximum-intensity projection of the image" : "") << " (x to the right, y down, "
    << esc(unit) << ")</figcaption>\n</figure>\n</body>\n</html>\n";
  return s.str();
}

}  // namespace skel::analysis
