#include "graph/centerlines.hpp"

#include <algorithm>
#include <cmath>
#include <map>
#include <set>
#include <unordered_map>

#include "skel/error.hpp"

namespace skel::graph {

namespace {

struct CellKey {
  int64_t x, y, z;
  bool operator==(const CellKey&) const = default;
};
struct CellHash {
  size_t operator()(const CellKey& k) const {
    return static_cast<size_t>(k.x * 73856093) ^ static_cast<size_t>(k.y * 19349663) ^ static_cast<size_t>(k.z * 83492791);
  }
};

double dist(const Vec3& a, const Vec3& b) {
  return std::sqrt((a[0] - b[0]) * (a[0] - b[0]) + (a[1] - b[1]) * (a[1] - b[1]) + (a[2] - b[2]) * (a[2] - b[2]));
}

}  // namespace

SpatialGraph merge_centerlines(const SpatialGraph& in, const MergeCenterlinesOptions& o) {
  if (!(o.tolerance >= 0.0) || !std::isfinite(o.tolerance))
    throw InputError("parameter 'tolerance': expected a finite number >= 0");
  if (!(o.radius_factor > 0.0) || !std::isfinite(o.radius_factor))
    throw InputError("parameter 'radius_factor': expected a finite number > 0");
  const auto problems = in.check_invariants();
  if (!problems.empty()) throw InputError("input 'centerlines': inconsistent graph: " + problems.front());
  const auto ra = in.point_attributes.find(o.radius);
  const bool with_r = ra != in.point_attributes.end();
  if (o.tolerance == 0.0 && !with_r)
    throw InputError("parameter 'radius': the centerlines have no point attribute '" + o.radius +
                     "'; give it, or an absolute 'tolerance'");
  // Tolerance per input point and the largest one (the hash cell size).
  double cell = o.tolerance;
  if (o.tolerance == 0.0)
    for (const auto& e : ra->second)
      for (float r : e) {
        if (!std::isfinite(r) || r < 0) throw InputError("point attribute '" + o.radius + "': a radius is negative or not finite");
        cell = std::max(cell, o.radius_factor * static_cast<double>(r));
      }
  if (!(cell > 0.0)) cell = 1.0;  // all radii 0: only coinciding points merge

  // Merged points and the hash of those made by earlier paths.
  std::vector<Vec3> pos;
  std::vector<float> rad;
  std::vector<int64_t> path_of;
  std::unordered_map<CellKey, std::vector<int64_t>, CellHash> grid;
  const auto key = [&](const Vec3& p) {
    return CellKey{static_cast<int64_t>(std::floor(p[0] / cell)), static_cast<int64_t>(std::floor(p[1] / cell)),
                   static_cast<int64_t>(std::floor(p[2] / cell))};
  };
  std::set<std::pair<int64_t, int64_t>> links;
  const int64_t ne = in.edge_count();
  for (int64_t e = 0; e < ne; ++e) {
    o.interrupter.check(0.8 * static_cast<double>(e) / static_cast<double>(std::max<int64_t>(1, ne)));
    const auto& pts = in.edges[e].points;
    std::vector<int64_t> fresh;  // this path's new points (hashed after the path)
    int64_t prev = -1;
    bool prev_shared = false;
    for (size_t i = 0; i < pts.size(); ++i) {
      const Vec3& p = pts[i];
      const double r = with_r ? static_cast<double>(ra->second[e][i]) : 0.0;
      const double tol = o.tolerance > 0.0 ? o.tolerance : o.radius_factor * r;
      int64_t best = -1;
      double bd = tol;
      const CellKey c = key(p);
      for (int64_t dz = -1; dz <= 1; ++dz)
        for (int64_t dy = -1; dy <= 1; ++dy)
          for (int64_t dx = -1; dx <= 1; ++dx) {
            const auto it = grid.find({c.x + dx, c.y + dy, c.z + dz});
            if (it == grid.end()) continue;
            for (int64_t m : it->second)
              if (const double d = dist(p, pos[m]); d <= bd && (best < 0 || d < bd || m < best)) {
                bd = d;
                best = m;
              }
          }
      const bool shared = best >= 0;
      int64_t id = best;
      if (!shared) {
        id = static_cast<int64_t>(pos.size());
        pos.push_back(p);
        rad.push_back(static_cast<float>(r));
        path_of.push_back(e);
        fresh.push_back(id);
      }
      // Runs on shared points are already linked by the earlier paths.
      if (prev >= 0 && id != prev && !(prev_shared && shared)) links.emplace(std::min(prev, id), std::max(prev, id));
      prev = id;
      prev_shared = shared;
    }
    for (int64_t m : fresh) grid[key(pos[m])].push_back(m);
  }

  // Split the point graph at every point of degree != 2.
  const auto np = static_cast<int64_t>(pos.size());
  std::vector<std::vector<int64_t>> adj(static_cast<size_t>(np));
  for (const auto& [a, b] : links) {
    adj[a].push_back(b);
    adj[b].push_back(a);
  }
  SpatialGraph g;
  g.unit = in.unit;
  g.source_grid = in.source_grid;
  std::vector<int64_t> node_of(static_cast<size_t>(np), -1);
  for (int64_t m = 0; m < np; ++m)
    if (adj[m].size() != 2) node_of[m] = g.add_node(pos[m]);
  std::set<std::pair<int64_t, int64_t>> used;
  std::vector<std::vector<float>> radii;
  const auto walk = [&](int64_t start, int64_t next) {
    std::vector<int64_t> chain{start};
    int64_t prev = start, cur = next;
    used.emplace(std::min(prev, cur), std::max(prev, cur));
    while (node_of[cur] < 0) {
      chain.push_back(cur);
      const int64_t nxt = adj[cur][0] == prev ? adj[cur][1] : adj[cur][0];
      prev = cur;
      cur = nxt;
      used.emplace(std::min(prev, cur), std::max(prev, cur));
    }
    chain.push_back(cur);
    std::vector<Vec3> poly;
    std::vector<float> rr;
    for (int64_t m : chain) {
      poly.push_back(pos[m]);
      rr.push_back(rad[m]);
    }
    g.add_edge(node_of[start], node_of[cur], std::move(poly));
    radii.push_back(std::move(rr));
  };
  for (int64_t m = 0; m < np; ++m) {
    if (node_of[m] < 0) continue;
    for (int64_t n : adj[m])
      if (!used.count({std::min(m, n), std::max(m, n)})) walk(m, n);
  }
  // Closed rings of degree-2 points: one node on each.
  for (int64_t m = 0; m < np; ++m)
    if (node_of[m] < 0 && !adj[m].empty() && !used.count({std::min(m, adj[m][0]), std::max(m, adj[m][0])})) {
      node_of[m] = g.add_node(pos[m]);
      walk(m, adj[m][0]);
    }
  if (with_r) g.point_attributes["radius"] = std::move(radii);
  o.interrupter.check(1.0);
  return g;
}

}  // namespace skel::graph
