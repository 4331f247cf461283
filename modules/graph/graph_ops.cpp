#include "graph/graph_ops.hpp"

#include <algorithm>
#include <cmath>
#include <tuple>

#include "skel/error.hpp"

namespace skel::graph {

namespace {

double seg(const Vec3& a, const Vec3& b) {
  return std::sqrt((a[0] - b[0]) * (a[0] - b[0]) + (a[1] - b[1]) * (a[1] - b[1]) + (a[2] - b[2]) * (a[2] - b[2]));
}

void reverse_edge(SpatialGraph& g, int64_t e) {
  auto& ed = g.edges[e];
  std::reverse(ed.points.begin(), ed.points.end());
  std::swap(ed.node0, ed.node1);
  for (auto& [name, v] : g.point_attributes) std::reverse(v[e].begin(), v[e].end());
}

}  // namespace

int64_t merge_degree_two(SpatialGraph& g) {
  std::vector<std::vector<int64_t>> inc(g.positions.size());
  for (int64_t e = 0; e < g.edge_count(); ++e) {
    inc[g.edges[e].node0].push_back(e);
    inc[g.edges[e].node1].push_back(e);
  }
  std::vector<int64_t> dead_edges, dead_nodes;
  std::vector<double> len(g.edges.size());
  for (int64_t e = 0; e < g.edge_count(); ++e) len[e] = g.edge_length(e);
  for (int64_t n = 0; n < g.node_count(); ++n) {
    if (inc[n].size() != 2 || inc[n][0] == inc[n][1]) continue;
    int64_t e1 = std::min(inc[n][0], inc[n][1]), e2 = std::max(inc[n][0], inc[n][1]);
    if (g.edges[e1].node1 != n) reverse_edge(g, e1);
    if (g.edges[e2].node0 != n) reverse_edge(g, e2);
    auto& a = g.edges[e1];
    auto& b = g.edges[e2];
    a.points.insert(a.points.end(), b.points.begin() + 1, b.points.end());
    for (auto& [name, v] : g.point_attributes) v[e1].insert(v[e1].end(), v[e2].begin() + 1, v[e2].end());
    const double l1 = len[e1], l2 = len[e2];
    for (auto& [name, v] : g.edge_attributes)
      v[e1] = l1 + l2 > 0 ? static_cast<float>((v[e1] * l1 + v[e2] * l2) / (l1 + l2)) : v[e1];
    len[e1] = l1 + l2;
    a.node1 = b.node1;
    auto& ib = inc[b.node1];
    for (auto& x : ib)
      if (x == e2) x = e1;
    inc[n].clear();
    b.points.clear();
    dead_edges.push_back(e2);
    dead_nodes.push_back(n);
  }
  if (!dead_edges.empty()) {
    // Dead edges' points were cleared; remove them before the nodes so no invariant is checked midway.
    std::sort(dead_edges.begin(), dead_edges.end());
    g.remove_edges(dead_edges);
    g.remove_nodes(dead_nodes);
  }
  return static_cast<int64_t>(dead_nodes.size());
}

std::vector<Spur> find_spurs(const SpatialGraph& g, const std::vector<int64_t>& deg, const PruneOptions& options) {
  const auto* radius = options.radius_factor > 0.0 ? &g.point_attributes.at(options.radius) : nullptr;
  std::vector<Spur> spurs;
  for (int64_t e = 0; e < g.edge_count(); ++e) {
    const auto& ed = g.edges[e];
    if (ed.node0 == ed.node1) continue;
    const bool tip0 = deg[ed.node0] == 1;
    const int64_t tip = tip0 ? ed.node0 : ed.node1, junction = tip0 ? ed.node1 : ed.node0;
    if (deg[tip] != 1 || deg[junction] < 3) continue;
    double limit = options.min_length;
    if (radius) {
      // Points run from node0 to node1: the junction end is the last point when the tip is node0.
      const auto& r = (*radius)[e];
      if (!r.empty()) limit = std::max(limit, options.radius_factor * (tip0 ? r.back() : r.front()));
    }
    const double l = g.edge_length(e);
    if (l < limit) spurs.push_back({e, tip, junction, l});
  }
  return spurs;
}

PruneStats prune(SpatialGraph& g, const PruneOptions& options) {
  if (!(options.min_length >= 0.0))
    throw InputError("parameter 'min_length': expected >= 0, got " + std::to_string(options.min_length));
  if (!(options.radius_factor >= 0.0))
    throw InputError("parameter 'radius_factor': expected >= 0, got " + std::to_string(options.radius_factor));
  const bool relative = options.radius_factor > 0.0;
  if (relative && !g.point_attributes.contains(options.radius))
    throw InputError("input 'graph': radius_factor > 0 needs the point attribute '" + options.radius +
                     "' (give skeleton_to_graph a distance input), but the graph has none");
  PruneStats stats;
  while (options.max_iterations <= 0 || stats.iterations < options.max_iterations) {
    options.interrupter.check();
    const auto deg = g.degrees();
    // Per junction (ascending), its spurs shortest first, never leaving it with fewer than two edges.
    std::vector<Spur> spurs = find_spurs(g, deg, options);
    std::sort(spurs.begin(), spurs.end(), [](const Spur& a, const Spur& b) {
      return std::tie(a.junction, a.length, a.edge) < std::tie(b.junction, b.length, b.edge);
    });
    std::vector<int64_t> remove_e, remove_n;
    for (size_t k = 0; k < spurs.size();) {
      const int64_t n = spurs[k].junction;
      int64_t left = deg[n];
      for (; k < spurs.size() && spurs[k].junction == n; ++k) {
        if (left <= 2) continue;
        remove_e.push_back(spurs[k].edge);
        remove_n.push_back(spurs[k].tip);
        --left;
      }
    }
    if (remove_e.empty()) break;
    ++stats.iterations;
    stats.removed_edges += static_cast<int64_t>(remove_e.size());
    std::sort(remove_e.begin(), remove_e.end());
    g.remove_edges(remove_e);
    g.remove_nodes(remove_n);
    stats.merged_nodes += merge_degree_two(g);
  }
  return stats;
}

std::vector<double> edge_values(const SpatialGraph& g, const std::string& name, const std::string& what) {
  std::vector<double> out(g.edges.size());
  if (name == "length") {
    for (int64_t e = 0; e < g.edge_count(); ++e) out[e] = g.edge_length(e);
  } else if (auto it = g.edge_attributes.find(name); it != g.edge_attributes.end()) {
    for (size_t e = 0; e < out.size(); ++e) out[e] = it->second[e];
  } else if (auto il = g.edge_labels.find(name); il != g.edge_labels.end()) {
    for (size_t e = 0; e < out.size(); ++e) out[e] = il->second[e];
  } else if (auto ip = g.point_attributes.find(name); ip != g.point_attributes.end()) {
    for (size_t e = 0; e < out.size(); ++e) {
      const auto& p = g.edges[e].points;
      const auto& v = ip->second[e];
      double wsum = 0.0, sum = 0.0;
      for (size_t i = 1; i < p.size(); ++i) {
        const double l = seg(p[i - 1], p[i]);
        wsum += l;
        sum += 0.5 * (v[i - 1] + v[i]) * l;
      }
      if (wsum > 0) {
        out[e] = sum / wsum;
      } else {
        double s = 0.0;
        for (float x : v) s += x;
        out[e] = v.empty() ? 0.0 : s / static_cast<double>(v.size());
      }
    }
  } else {
    std::string known = "length";
    for (const auto& [n, v] : g.edge_attributes) known += ", " + n;
    for (const auto& [n, v] : g.edge_labels) known += ", " + n;
    for (const auto& [n, v] : g.point_attributes) known += ", " + n;
    throw InputError(what + ": the graph has no attribute '" + name + "' (it has: " + known + ")");
  }
  return out;
}

int64_t filter_edges(SpatialGraph& g, const FilterOptions& options) {
  if (options.min > options.max)
    throw InputError("parameter 'min' (" + std::to_string(options.min) + ") is larger than 'max' (" +
                     std::to_string(options.max) + ")");
  const auto val = edge_values(g, options.attribute, "parameter 'attribute'");
  std::vector<int64_t> drop;
  for (size_t e = 0; e < val.size(); ++e)
    if (!(val[e] >= options.min && val[e] <= options.max)) drop.push_back(static_cast<int64_t>(e));
  g.remove_edges(drop);
  if (options.remove_isolated_nodes) {
    const auto d = g.degrees();
    std::vector<int64_t> iso;
    for (int64_t n = 0; n < g.node_count(); ++n)
      if (d[n] == 0) iso.push_back(n);
    g.remove_nodes(iso);
  }
  if (options.merge) merge_degree_two(g);
  return static_cast<int64_t>(drop.size());
}

}  // namespace skel::graph
