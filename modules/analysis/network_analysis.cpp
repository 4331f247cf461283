#include "analysis/network_analysis.hpp"

#include <algorithm>
#include <array>
#include <cmath>
#include <limits>
#include <numbers>
#include <queue>
#include <tuple>

#include "distance/distance.hpp"
#include "graph/graph_ops.hpp"
#include "skel/error.hpp"
#include "skel/units.hpp"

namespace skel::analysis {

namespace {

double dist3(const Vec3& a, const Vec3& b) {
  return std::sqrt((a[0] - b[0]) * (a[0] - b[0]) + (a[1] - b[1]) * (a[1] - b[1]) + (a[2] - b[2]) * (a[2] - b[2]));
}

// True when the edge's inner points (all but the two node positions) are voxel centres of `grid` and
// consecutive inner points are 26-neighbours: a voxel path of a skeleton, whose steps are a
// staircase to be measured as a digital curve. The steps to the nodes may have any length (a node is
// the centroid of its junction voxels).
bool is_voxel_path(const std::vector<Vec3>& p, const Grid& grid) {
  if (grid.voxel_count() <= 0 || p.size() < 3) return false;
  std::array<int64_t, 3> prev{};
  for (size_t i = 1; i + 1 < p.size(); ++i) {
    std::array<int64_t, 3> q{};
    for (int a = 0; a < 3; ++a) {
      const double u = (p[i][a] - grid.origin[a]) / grid.spacing[a];
      q[a] = std::llround(u);
      if (std::abs(u - static_cast<double>(q[a])) > 1e-3) return false;
    }
    if (i > 1) {
      int64_t moved = 0;
      for (int a = 0; a < 3; ++a) {
        const int64_t d = std::abs(q[a] - prev[a]);
        if (d > 1) return false;
        moved += d;
      }
      if (moved == 0) return false;
    }
    prev = q;
  }
  return true;
}

}  // namespace

namespace detail {

std::vector<double> step_lengths(const std::vector<Vec3>& p, const Grid& grid, LengthEstimator estimator,
                                 int tangent_points) {
  const size_t n = p.size();
  std::vector<double> c(n, 0.0);
  for (size_t i = 1; i < n; ++i) c[i] = dist3(p[i - 1], p[i]);
  if (estimator == LengthEstimator::polyline || !is_voxel_path(p, grid)) return c;
  if (estimator == LengthEstimator::chain_code) {
    // Kiryati & Kübler's weights for steps changing 1, 2, 3 coordinates (per voxel unit: scaled by the
    // step's physical length over its length in voxels, which is exact for isotropic spacing). The
    // steps to the nodes are not lattice steps: measured as they are.
    constexpr std::array<double, 4> w{0.0, 0.9016, 1.289, 1.615};
    for (size_t i = 2; i + 1 < n; ++i) {
      int moved = 0;
      for (int a = 0; a < 3; ++a) moved += std::llround(std::abs(p[i][a] - p[i - 1][a]) / grid.spacing[a]) != 0;
      c[i] *= w[static_cast<size_t>(moved)] / std::sqrt(static_cast<double>(moved));
    }
    return c;
  }
  // Tangent projection: step i (p[i-1] -> p[i]) counts with its projection onto the chord from
  // p[i-k] to p[i-1+k] (symmetric about the step; clamped at the ends of an open edge, wrapped
  // around a closed loop whose last point repeats the first).
  const auto k = static_cast<int64_t>(std::max(1, tangent_points));
  const auto last = static_cast<int64_t>(n) - 1;
  const bool closed = n > 3 && p.front() == p.back();
  const auto at = [&](int64_t j) -> const Vec3& {
    if (closed) return p[static_cast<size_t>(((j % last) + last) % last)];
    return p[static_cast<size_t>(std::clamp<int64_t>(j, 0, last))];
  };
  for (int64_t i = 1; i <= last; ++i) {
    const Vec3& a = at(i - k);
    const Vec3& b = at(i - 1 + k);
    const Vec3 t{b[0] - a[0], b[1] - a[1], b[2] - a[2]};
    const double tn = std::sqrt(t[0] * t[0] + t[1] * t[1] + t[2] * t[2]);
    if (!(tn > 0)) continue;  // keeps the step's own length
    const Vec3& u = p[static_cast<size_t>(i - 1)];
    const Vec3& v = p[static_cast<size_t>(i)];
    c[static_cast<size_t>(i)] = ((v[0] - u[0]) * t[0] + (v[1] - u[1]) * t[1] + (v[2] - u[2]) * t[2]) / tn;
  }
  return c;
}

}  // namespace detail

double mask_volume(const VolumeU8& mask) {
  int64_t n = 0;
  for (auto v : mask) n += v != 0;
  return static_cast<double>(n) * mask.spacing()[0] * mask.spacing()[1] * mask.spacing()[2];
}

double mask_volume(const DataObject& region, const std::string& what) {
  return visit_volume(region, what, [](const auto& v) {
    int64_t n = 0;
    for (auto x : v) n += x != 0;
    return static_cast<double>(n) * v.spacing()[0] * v.spacing()[1] * v.spacing()[2];
  });
}

NetworkStatistics network_statistics(const SpatialGraph& g, const NetworkStatisticsOptions& options) {
  if (options.orientation_bins < 1)
    throw InputError("parameter 'orientation_bins': expected >= 1, got " + std::to_string(options.orientation_bins));
  const auto problems = g.check_invariants();
  if (!problems.empty()) throw InputError("input 'graph': inconsistent graph: " + problems.front());
  const auto it = g.point_attributes.find(options.radius);
  const bool with_r = it != g.point_attributes.end();
  const int64_t ne = g.edge_count(), nn = g.node_count();
  const int bins = options.orientation_bins;
  const double pi = std::numbers::pi;

  std::vector<int64_t> eid(ne), n0(ne), n1(ne);
  std::vector<double> len(ne), chord(ne), tort(ne), mean_r(ne), min_r(ne), max_r(ne), vol(ne), surf(ne);
  std::vector<double> orient(bins, 0.0);
  double total_len = 0.0, total_vol = 0.0, total_surf = 0.0;
  double window = options.orientation_window;
  if (!(window > 0.0)) {
    std::vector<double> steps;
    for (const auto& ed : g.edges)
      for (size_t i = 1; i < ed.points.size(); ++i)
        if (double h = dist3(ed.points[i - 1], ed.points[i]); h > 0) steps.push_back(h);
    window = 1.0;
    if (!steps.empty()) {
      std::nth_element(steps.begin(), steps.begin() + static_cast<std::ptrdiff_t>(steps.size() / 2), steps.end());
      window = 10.0 * steps[steps.size() / 2];
    }
  }
  if (options.tangent_points < 1)
    throw InputError("parameter 'tangent_points': expected >= 1, got " + std::to_string(options.tangent_points));
  const auto deg = g.degrees();
  std::vector<std::vector<double>> steps(static_cast<size_t>(ne));
  for (int64_t e = 0; e < ne; ++e)
    steps[e] = detail::step_lengths(g.edges[e].points, g.source_grid, options.length_estimator, options.tangent_points);
  // A piece of arc length `arc` whose chord runs from a to b adds `arc` to the bin of the chord's
  // angle to the axis (closed loops whose piece returns to its start have no direction: skipped).
  const auto add_piece = [&](const Vec3& a, const Vec3& b, double arc) {
    const double c = dist3(a, b);
    if (!(c > 0)) return;
    const auto ax = static_cast<size_t>(options.axis);
    const double cosine = std::abs(b[ax] - a[ax]) / c;
    const double angle = std::acos(std::min(1.0, cosine)) * 180.0 / pi;
    orient[std::min(bins - 1, static_cast<int>(angle / (90.0 / bins)))] += arc;
  };
  for (int64_t e = 0; e < ne; ++e) {
    const auto& ed = g.edges[e];
    const auto& p = ed.points;
    eid[e] = e;
    n0[e] = ed.node0;
    n1[e] = ed.node1;
    double l = 0.0, poly = 0.0, wr = 0.0, v = 0.0, s = 0.0;
    // The measured length: the estimator's step lengths; never below the chord (no curve is shorter).
    // The orientation pieces are cut along the polyline and count in the same proportion, so that
    // the histogram sums to the total length.
    for (size_t i = 1; i < p.size(); ++i) l += steps[e][i];
    chord[e] = dist3(p.front(), p.back());
    l = std::max(l, chord[e]);
    const double polyline_length = g.edge_length(e);
    const double scale = polyline_length > 0 ? l / polyline_length : 1.0;
    size_t piece_start = 0;
    double piece = 0.0;
    double rmin = std::numeric_limits<double>::infinity(), rmax = -rmin;
    for (size_t i = 0; i < p.size(); ++i) {
      if (with_r) {
        const double r = it->second[e][i];
        rmin = std::min(rmin, r);
        rmax = std::max(rmax, r);
      }
      if (i == 0) continue;
      const double h = dist3(p[i - 1], p[i]);
      poly += h;
      piece += h;
      if (piece >= window || i + 1 == p.size()) {
        add_piece(p[piece_start], p[i], piece * scale);
        piece_start = i;
        piece = 0.0;
      }
      if (with_r) {
        const double r1 = it->second[e][i - 1], r2 = it->second[e][i];
        wr += 0.5 * (r1 + r2) * h;
        v += pi * h / 3.0 * (r1 * r1 + r1 * r2 + r2 * r2);
        s += pi * (r1 + r2) * std::sqrt(h * h + (r1 - r2) * (r1 - r2));
      }
    }
    len[e] = l;
    tort[e] = chord[e] > 0 ? l / chord[e] : std::numeric_limits<double>::quiet_NaN();
    if (with_r) {
      mean_r[e] = poly > 0 ? wr / poly : 0.5 * (rmin + rmax);
      min_r[e] = rmin;
      max_r[e] = rmax;
      vol[e] = v;
      surf[e] = s;
    }
    total_len += l;
    total_vol += v;
    total_surf += s;
  }
  NetworkStatistics st;
  st.graph = g;
  {
    SpatialGraph& sg = st.graph;
    // Connected components (ids from 0, in node order).
    std::vector<int32_t> comp(static_cast<size_t>(nn), -1);
    {
      const auto adj = g.adjacency();
      int32_t next = 0;
      std::vector<int64_t> stack;
      for (int64_t s = 0; s < nn; ++s) {
        if (comp[s] >= 0) continue;
        comp[s] = next;
        stack.assign(1, s);
        while (!stack.empty()) {
          const int64_t u = stack.back();
          stack.pop_back();
          for (int64_t k = adj.offsets[u]; k < adj.offsets[u + 1]; ++k) {
            const auto& ed = g.edges[adj.edge_ids[k]];
            const int64_t v = ed.node0 == u ? ed.node1 : ed.node0;
            if (comp[v] < 0) {
              comp[v] = next;
              stack.push_back(v);
            }
          }
        }
        ++next;
      }
    }
    auto& nd = sg.ensure_node_label("degree");
    auto& nc = sg.ensure_node_label("component");
    for (int64_t n = 0; n < nn; ++n) {
      nd[n] = static_cast<int32_t>(deg[n]);
      nc[n] = comp[n];
    }
    auto put = [&](const char* name, const std::vector<double>& v) {
      auto& a = sg.ensure_edge_attribute(name);
      for (int64_t e = 0; e < ne; ++e) a[e] = static_cast<float>(v[e]);
    };
    put("length", len);
    put("chord", chord);
    put("tortuosity", tort);
    if (with_r) {
      put("mean_radius", mean_r);
      put("min_radius", min_r);
      put("max_radius", max_r);
      put("volume", vol);
      put("surface", surf);
    }
    auto& orientation = sg.ensure_edge_attribute("orientation");
    auto& dx = sg.ensure_edge_attribute("direction_x");
    auto& dy = sg.ensure_edge_attribute("direction_y");
    auto& dz = sg.ensure_edge_attribute("direction_z");
    auto& ec = sg.ensure_edge_label("component");
    auto& bt = sg.ensure_edge_label("branch_type");
    const auto ax = static_cast<size_t>(options.axis);
    for (int64_t e = 0; e < ne; ++e) {
      const auto& ed = g.edges[e];
      const Vec3& a = ed.points.front();
      const Vec3& b = ed.points.back();
      const double c = chord[e];
      const float nan = std::numeric_limits<float>::quiet_NaN();
      dx[e] = c > 0 ? static_cast<float>((b[0] - a[0]) / c) : nan;
      dy[e] = c > 0 ? static_cast<float>((b[1] - a[1]) / c) : nan;
      dz[e] = c > 0 ? static_cast<float>((b[2] - a[2]) / c) : nan;
      orientation[e] = c > 0 ? static_cast<float>(std::acos(std::min(1.0, std::abs(b[ax] - a[ax]) / c)) * 180.0 / pi) : nan;
      ec[e] = comp[ed.node0];
      const bool end0 = deg[ed.node0] == 1, end1 = deg[ed.node1] == 1;
      const BranchType t = ed.node0 == ed.node1 ? BranchType::loop
                           : end0 && end1       ? BranchType::isolated
                           : end0 || end1       ? BranchType::terminal
                                                : BranchType::internal;
      bt[e] = static_cast<int32_t>(t);
    }
  }
  const std::string& u = g.unit;
  const std::string u2 = units::power(u, 2), u3 = units::power(u, 3);
  st.segments.add("edge", eid).add("node0", n0).add("node1", n1);
  st.segments.add("length", len, u).add("chord", chord, u).add("tortuosity", tort);
  if (with_r) {
    st.segments.add("mean_radius", mean_r, u).add("min_radius", min_r, u).add("max_radius", max_r, u);
    st.segments.add("volume", vol, u3).add("surface", surf, u2);
  }

  std::vector<int64_t> nid(nn);
  std::vector<double> x(nn), y(nn), z(nn);
  int64_t branch = 0, ends = 0;
  for (int64_t n = 0; n < nn; ++n) {
    nid[n] = n;
    x[n] = g.positions[n][0];
    y[n] = g.positions[n][1];
    z[n] = g.positions[n][2];
    branch += deg[n] >= 3;
    ends += deg[n] == 1;
  }
  st.nodes.add("node", nid).add("degree", std::vector<int64_t>(deg)).add("x", x, u).add("y", y, u).add("z", z, u);
  if (auto nr = g.node_attributes.find(options.radius); nr != g.node_attributes.end())
    st.nodes.add("radius", std::vector<double>(nr->second.begin(), nr->second.end()), u);

  double ref = options.reference_volume;
  if (ref <= 0.0) {
    const Grid& sg = g.source_grid;
    if (sg.voxel_count() > 0) {
      ref = 1.0;
      for (int a = 0; a < 3; ++a) ref *= static_cast<double>(sg.dims[a]) * sg.spacing[a];
    } else if (g.point_count() > 0) {
      Vec3 lo{1e300, 1e300, 1e300}, hi{-1e300, -1e300, -1e300};
      for (const auto& ed : g.edges)
        for (const auto& p : ed.points)
          for (int a = 0; a < 3; ++a) {
            lo[a] = std::min(lo[a], p[a]);
            hi[a] = std::max(hi[a], p[a]);
          }
      ref = (hi[0] - lo[0]) * (hi[1] - lo[1]) * (hi[2] - lo[2]);
    } else {
      ref = 0.0;
    }
  }
  st.summary.add("nodes", std::vector<int64_t>{nn}).add("edges", std::vector<int64_t>{ne});
  st.summary.add("components", std::vector<int64_t>{g.connected_components()});
  st.summary.add("total_length", std::vector<double>{total_len}, u);
  st.summary.add("reference_volume", std::vector<double>{ref}, u3);
  st.summary.add("length_density",
                 std::vector<double>{ref > 0 ? total_len / ref : std::numeric_limits<double>::quiet_NaN()}, units::power(u, -2));
  st.summary.add("branch_points", std::vector<int64_t>{branch}).add("end_points", std::vector<int64_t>{ends});
  st.summary.add("loops", std::vector<int64_t>{g.cyclomatic_number()});
  if (with_r) {
    st.summary.add("total_volume", std::vector<double>{total_vol}, u3);
    st.summary.add("total_surface", std::vector<double>{total_surf}, u2);
  }
  st.summary.add("orientation_window", std::vector<double>{window}, u);
  for (int b = 0; b < bins; ++b) st.summary.add("orientation_" + std::to_string(b), std::vector<double>{orient[b]}, u);
  return st;
}

TreeStats extract_trees(SpatialGraph& g, const TreeOptions& options) {
  TreeStats stats;
  for (int64_t r : options.roots) {
    if (r < 0 || r >= g.node_count())
      throw InputError("parameter 'roots': node id " + std::to_string(r) + " out of range (graph has " +
                       std::to_string(g.node_count()) + " nodes)");
    stats.root_nodes.push_back(r);
  }
  for (const auto& p : options.root_points) {
    if (g.node_count() == 0) throw InputError("parameter 'root_points': the graph has no nodes");
    int64_t best = 0;
    double bd = std::numeric_limits<double>::infinity();
    for (int64_t n = 0; n < g.node_count(); ++n) {
      const double d = dist3(g.positions[n], p);
      if (d < bd) {
        bd = d;
        best = n;
      }
    }
    stats.root_nodes.push_back(best);
  }
  if (stats.root_nodes.empty()) throw InputError("parameters 'roots' / 'root_points': give at least one root");
  std::vector<double> diam(g.edges.size(), std::numeric_limits<double>::infinity());
  if (options.min_diameter > 0) {
    diam = graph::edge_values(g, options.radius, "parameter 'radius'");
    for (auto& d : diam) d *= 2.0;
  }
  const auto deg = g.degrees();
  const auto adj = g.adjacency();
  const int64_t nn = g.node_count();
  std::vector<double> dist(nn, std::numeric_limits<double>::infinity());
  std::vector<int64_t> root_of(nn, -1), gen(nn, 0);
  using Item = std::tuple<double, int64_t, int64_t>;  // distance, root index, node
  std::priority_queue<Item, std::vector<Item>, std::greater<>> pq;
  for (size_t r = 0; r < stats.root_nodes.size(); ++r) {
    const int64_t n = stats.root_nodes[r];
    if (dist[n] == 0.0) continue;
    dist[n] = 0.0;
    root_of[n] = static_cast<int64_t>(r);
    gen[n] = 1;
    pq.emplace(0.0, static_cast<int64_t>(r), n);
  }
  std::vector<double> len(g.edges.size());
  for (int64_t e = 0; e < g.edge_count(); ++e) len[e] = g.edge_length(e);
  while (!pq.empty()) {
    const auto [d, r, u] = pq.top();
    pq.pop();
    if (d > dist[u] || r != root_of[u]) continue;
    for (int64_t a = adj.offsets[u]; a < adj.offsets[u + 1]; ++a) {
      const int64_t e = adj.edge_ids[a];
      if (!(diam[e] >= options.min_diameter)) continue;
      const int64_t v = g.edges[e].node0 == u ? g.edges[e].node1 : g.edges[e].node0;
      const double nd = d + len[e];
      if (nd < dist[v] || (nd == dist[v] && r < root_of[v])) {
        dist[v] = nd;
        root_of[v] = r;
        gen[v] = gen[u] + (deg[v] >= 3 ? 1 : 0);
        pq.emplace(nd, r, v);
      }
    }
  }
  auto& tree = g.ensure_edge_label("tree");
  auto& order = g.ensure_edge_label("branch_order");
  for (int64_t e = 0; e < g.edge_count(); ++e) {
    const int64_t a = g.edges[e].node0, b = g.edges[e].node1;
    if (!(diam[e] >= options.min_diameter) || root_of[a] < 0) {
      tree[e] = 0;
      order[e] = 0;
      ++stats.capillary_edges;
      continue;
    }
    const int64_t near = (std::tie(dist[a], root_of[a]) <= std::tie(dist[b], root_of[b])) ? a : b;
    tree[e] = static_cast<int32_t>(root_of[near] + 1);
    order[e] = static_cast<int32_t>(gen[near]);
    ++stats.tree_edges;
  }
  return stats;
}

namespace {

// Every object voxel takes the label of its nearest seed (exact Euclidean feature transform).
VolumeU32 nearest_seed(const VolumeU8& mask, VolumeU32 lab, const LabelPropagationOptions& o) {
  VolumeU8 not_seed(mask.grid(), 1);
  bool any = false;
  for (int64_t i = 0; i < mask.size(); ++i)
    if (lab[i] != 0) {
      not_seed[i] = 0;
      any = true;
    }
  if (!any) return lab;
  distance::DistanceOptions d;
  d.border_is_object = true;
  d.threads = o.threads;
  d.interrupter = o.interrupter.sub(0.0, 0.9);
  const DataPtr ft = distance::feature_transform(not_seed, d);
  VolumeU32 out(mask.grid(), 0);
  visit_volume(*ft, "feature transform", [&](const auto& f) {
    using I = typename std::decay_t<decltype(f)>::value_type;
    if constexpr (std::is_integral_v<I>) {
      for (int64_t i = 0; i < mask.size(); ++i)
        if (mask[i]) out[i] = lab[static_cast<int64_t>(f[i])];
    }
  });
  return out;
}

VolumeU32 wave(const VolumeU8& mask, VolumeU32 lab, std::vector<int64_t> queue, const Interrupter& intr) {
  const int64_t nx = mask.nx(), ny = mask.ny(), nz = mask.nz();
  size_t head = 0;
  uint64_t done = 0;
  const uint64_t total = static_cast<uint64_t>(std::max<int64_t>(mask.size(), 1));
  while (head < queue.size()) {
    const int64_t i = queue[head++];
    const int64_t x = i % nx, y = i / nx % ny, z = i / (nx * ny);
    const uint32_t l = lab[i];
    for (int dz = -1; dz <= 1; ++dz)
      for (int dy = -1; dy <= 1; ++dy)
        for (int dx = -1; dx <= 1; ++dx) {
          const int64_t X = x + dx, Y = y + dy, Z = z + dz;
          if (X < 0 || Y < 0 || Z < 0 || X >= nx || Y >= ny || Z >= nz) continue;
          const int64_t j = X + nx * (Y + ny * Z);
          if (!mask[j] || lab[j] != 0) continue;
          lab[j] = l;
          queue.push_back(j);
        }
    if ((++done & ((1u << 22) - 1)) == 0) intr.check(static_cast<double>(done) / static_cast<double>(total));
  }
  return lab;
}

}  // namespace

VolumeU32 propagate_edge_labels(const VolumeU8& mask, const SpatialGraph& g, const LabelPropagationOptions& options) {
  const std::vector<int32_t>* labels = nullptr;
  if (!options.label.empty()) {
    auto it = g.edge_labels.find(options.label);
    if (it == g.edge_labels.end()) throw InputError("parameter 'label': the graph has no edge label '" + options.label + "'");
    labels = &it->second;
  }
  const Grid& grid = mask.grid();
  VolumeU32 lab(grid, 0);
  std::vector<int64_t> queue;
  for (int64_t e = 0; e < g.edge_count(); ++e) {
    int64_t value = e + 1;
    if (labels != nullptr) {
      if ((*labels)[e] < 0) throw InputError("parameter 'label': edge " + std::to_string(e) + " has a negative label");
      value = static_cast<int64_t>((*labels)[e]) + 1;
    }
    const auto& p = g.edges[e].points;
    for (size_t i = 0; i + 1 < p.size(); ++i) {
      double m = 0.0;
      for (int a = 0; a < 3; ++a) m = std::max(m, std::abs(p[i + 1][a] - p[i][a]) / grid.spacing[a]);
      const int64_t steps = static_cast<int64_t>(std::ceil(2.0 * m)) + 1;
      for (int64_t s = 0; s <= steps; ++s) {
        const double t = static_cast<double>(s) / static_cast<double>(steps);
        int64_t c[3];
        for (int a = 0; a < 3; ++a)
          c[a] = std::llround((p[i][a] + t * (p[i + 1][a] - p[i][a]) - grid.origin[a]) / grid.spacing[a]);
        if (!grid.contains(c[0], c[1], c[2])) continue;
        const int64_t j = grid.index(c[0], c[1], c[2]);
        if (!mask[j] || lab[j] != 0) continue;
        lab[j] = static_cast<uint32_t>(value);
        queue.push_back(j);
      }
    }
  }
  if (options.metric == PropagationMetric::euclidean) return nearest_seed(mask, std::move(lab), options);
  return wave(mask, std::move(lab), std::move(queue), options.interrupter);
}

VolumeU32 propagate_labels(const VolumeU8& mask, const VolumeU32& seeds, const LabelPropagationOptions& options) {
  if (seeds.dims() != mask.dims()) throw InputError("input 'seeds': dims differ from the mask's");
  VolumeU32 lab(mask.grid(), 0);
  std::vector<int64_t> queue;
  for (int64_t i = 0; i < mask.size(); ++i)
    if (seeds[i] != 0 && mask[i]) {
      lab[i] = seeds[i];
      queue.push_back(i);
    }
  if (options.metric == PropagationMetric::euclidean) return nearest_seed(mask, std::move(lab), options);
  return wave(mask, std::move(lab), std::move(queue), options.interrupter);
}

}  // namespace skel::analysis
