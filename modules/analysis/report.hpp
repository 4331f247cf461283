#pragma once
// analysis.report: one self-contained HTML file for a graph and its statistics. Histograms are
// hand-written SVG, the picture of the network is an SVG of the edges projected along z over a
// maximum-intensity projection embedded as a PNG data URI (minimal PNG writer on zlib). No
// JavaScript, no external file: the report can be mailed or attached as it is.
#include <cstdint>
#include <string>
#include <vector>

#include "skel/data.hpp"
#include "skel/spatial_graph.hpp"
#include "skel/table.hpp"

namespace skel::analysis {

struct ReportOptions {
  std::string title = "Skelflow network report";
  int bins = 20;                  // histogram bins (radius, length, tortuosity); edges are rounded to nice numbers
  std::string radius = "radius";  // point attribute with radii (edge attribute mean_radius is used when present)
  int64_t max_image_size = 1024;  // the MIP is subsampled so that its longer side is at most this many pixels
};

// Inputs of a report: the graph is required, everything else may be null.
struct ReportInputs {
  const SpatialGraph* graph = nullptr;
  const Table* summary = nullptr;
  const Table* segments = nullptr;
  const Table* trees = nullptr;
  const DataObject* image = nullptr;  // any volume
};

// Histogram with "nice" bin edges (steps 1, 2, 2.5 or 5 × 10^k) covering [min, max] of the finite
// values; counts.size() == edges.size() - 1 and the counts sum to the number of finite values.
struct Histogram {
  std::vector<double> edges;
  std::vector<int64_t> counts;
};
Histogram nice_histogram(const std::vector<double>& values, int bins);
// Histogram over the fixed range [lo, hi] with `bins` equal bins (values outside are clamped).
Histogram fixed_histogram(const std::vector<double>& values, double lo, double hi, int bins);

// Per-edge values used by the report (NaN where undefined): polyline length, tortuosity
// (length / chord, NaN for loops), inclination to the z axis in degrees (0..90, NaN for loops) and
// mean radius (length-weighted over the point attribute, or edge attribute mean_radius; empty when
// the graph has neither).
struct EdgeValues {
  std::vector<double> length, tortuosity, inclination, radius;
};
EdgeValues report_edge_values(const SpatialGraph& graph, const std::string& radius_attribute);

// 8-bit greyscale PNG (colour type 0, filter 0 on every row, one zlib IDAT chunk).
std::string encode_png_gray8(int64_t width, int64_t height, const std::vector<uint8_t>& pixels);

// The HTML text of the report.
std::string make_report_html(const ReportInputs& inputs, const ReportOptions& options = {});

}  // namespace skel::analysis
