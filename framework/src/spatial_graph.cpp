#include "skel/spatial_graph.hpp"

#include <algorithm>
#include <cmath>
#include <sstream>

#include "skel/error.hpp"
#include "skel/union_find.hpp"

namespace skel {

namespace {

double distance(const Vec3& a, const Vec3& b) {
  const double dx = a[0] - b[0], dy = a[1] - b[1], dz = a[2] - b[2];
  return std::sqrt(dx * dx + dy * dy + dz * dz);
}

template <class V>
void swap_pop(V& v, int64_t i) {
  if (i != static_cast<int64_t>(v.size()) - 1) v[i] = std::move(v.back());
  v.pop_back();
}

template <class V>
void compact(V& v, const std::vector<int64_t>& old_to_new) {
  int64_t out = 0;
  for (size_t i = 0; i < v.size(); ++i) {
    if (old_to_new[i] < 0) continue;
    if (out != static_cast<int64_t>(i)) v[out] = std::move(v[i]);
    ++out;
  }
  v.resize(out);
}

}  // namespace

int64_t SpatialGraph::point_count() const {
  int64_t n = 0;
  for (const auto& e : edges) n += static_cast<int64_t>(e.points.size());
  return n;
}

int64_t SpatialGraph::add_node(const Vec3& position) {
  positions.push_back(position);
  for (auto& [name, v] : node_attributes) v.resize(positions.size(), 0.0f);
  for (auto& [name, v] : node_labels) v.resize(positions.size(), 0);
  return node_count() - 1;
}

int64_t SpatialGraph::add_edge(int64_t node0, int64_t node1, std::vector<Vec3> points) {
  if (node0 < 0 || node1 < 0 || node0 >= node_count() || node1 >= node_count())
    throw Error("SpatialGraph::add_edge: node id out of range (" + std::to_string(node0) + ", " +
                std::to_string(node1) + "; " + std::to_string(node_count()) + " nodes)");
  if (points.empty()) points = {positions[node0], positions[node1]};
  if (points.size() < 2) throw Error("SpatialGraph::add_edge: a polyline needs at least 2 points");
  const size_t np = points.size();
  edges.push_back(GraphEdge{node0, node1, std::move(points)});
  for (auto& [name, v] : edge_attributes) v.resize(edges.size(), 0.0f);
  for (auto& [name, v] : edge_labels) v.resize(edges.size(), 0);
  for (auto& [name, v] : point_attributes) {
    v.resize(edges.size());
    v.back().assign(np, 0.0f);
  }
  return edge_count() - 1;
}

int64_t SpatialGraph::remove_edge(int64_t e) {
  if (e < 0 || e >= edge_count()) throw Error("SpatialGraph::remove_edge: edge id out of range");
  const int64_t last = edge_count() - 1;
  swap_pop(edges, e);
  for (auto& [name, v] : edge_attributes) swap_pop(v, e);
  for (auto& [name, v] : edge_labels) swap_pop(v, e);
  for (auto& [name, v] : point_attributes) swap_pop(v, e);
  return e == last ? -1 : last;
}

int64_t SpatialGraph::remove_node(int64_t n) {
  if (n < 0 || n >= node_count()) throw Error("SpatialGraph::remove_node: node id out of range");
  for (int64_t e = edge_count() - 1; e >= 0; --e)
    if (edges[e].node0 == n || edges[e].node1 == n) remove_edge(e);
  const int64_t last = node_count() - 1;
  swap_pop(positions, n);
  for (auto& [name, v] : node_attributes) swap_pop(v, n);
  for (auto& [name, v] : node_labels) swap_pop(v, n);
  if (n == last) return -1;
  for (auto& e : edges) {
    if (e.node0 == last) e.node0 = n;
    if (e.node1 == last) e.node1 = n;
  }
  return last;
}

std::vector<int64_t> SpatialGraph::remove_edges(const std::vector<int64_t>& ids) {
  std::vector<int64_t> map(edges.size(), 0);
  for (int64_t e : ids) {
    if (e < 0 || e >= edge_count()) throw Error("SpatialGraph::remove_edges: edge id out of range");
    map[e] = -1;
  }
  int64_t next = 0;
  for (auto& m : map)
    if (m == 0) m = next++;
  compact(edges, map);
  for (auto& [name, v] : edge_attributes) compact(v, map);
  for (auto& [name, v] : edge_labels) compact(v, map);
  for (auto& [name, v] : point_attributes) compact(v, map);
  return map;
}

std::vector<int64_t> SpatialGraph::remove_nodes(const std::vector<int64_t>& ids) {
  std::vector<int64_t> map(positions.size(), 0);
  for (int64_t n : ids) {
    if (n < 0 || n >= node_count()) throw Error("SpatialGraph::remove_nodes: node id out of range");
    map[n] = -1;
  }
  std::vector<int64_t> dead_edges;
  for (int64_t e = 0; e < edge_count(); ++e)
    if (map[edges[e].node0] < 0 || map[edges[e].node1] < 0) dead_edges.push_back(e);
  if (!dead_edges.empty()) remove_edges(dead_edges);
  int64_t next = 0;
  for (auto& m : map)
    if (m == 0) m = next++;
  compact(positions, map);
  for (auto& [name, v] : node_attributes) compact(v, map);
  for (auto& [name, v] : node_labels) compact(v, map);
  for (auto& e : edges) {
    e.node0 = map[e.node0];
    e.node1 = map[e.node1];
  }
  return map;
}

std::vector<float>& SpatialGraph::ensure_node_attribute(const std::string& name, float fill) {
  auto& v = node_attributes[name];
  v.resize(positions.size(), fill);
  return v;
}
std::vector<int32_t>& SpatialGraph::ensure_node_label(const std::string& name, int32_t fill) {
  auto& v = node_labels[name];
  v.resize(positions.size(), fill);
  return v;
}
std::vector<float>& SpatialGraph::ensure_edge_attribute(const std::string& name, float fill) {
  auto& v = edge_attributes[name];
  v.resize(edges.size(), fill);
  return v;
}
std::vector<int32_t>& SpatialGraph::ensure_edge_label(const std::string& name, int32_t fill) {
  auto& v = edge_labels[name];
  v.resize(edges.size(), fill);
  return v;
}
std::vector<std::vector<float>>& SpatialGraph::ensure_point_attribute(const std::string& name,
                                                                       float fill) {
  auto& v = point_attributes[name];
  v.resize(edges.size());
  for (size_t e = 0; e < edges.size(); ++e) v[e].resize(edges[e].points.size(), fill);
  return v;
}

std::vector<int64_t> SpatialGraph::degrees() const {
  std::vector<int64_t> d(positions.size(), 0);
  for (const auto& e : edges) {
    ++d[e.node0];
    ++d[e.node1];
  }
  return d;
}

GraphAdjacency SpatialGraph::adjacency() const {
  GraphAdjacency a;
  a.offsets.assign(positions.size() + 1, 0);
  for (const auto& e : edges) {
    ++a.offsets[e.node0 + 1];
    ++a.offsets[e.node1 + 1];
  }
  for (size_t i = 1; i < a.offsets.size(); ++i) a.offsets[i] += a.offsets[i - 1];
  a.edge_ids.resize(a.offsets.back());
  std::vector<int64_t> fill(a.offsets.begin(), a.offsets.end() - 1);
  for (int64_t e = 0; e < edge_count(); ++e) {
    a.edge_ids[fill[edges[e].node0]++] = e;
    a.edge_ids[fill[edges[e].node1]++] = e;
  }
  return a;
}

double SpatialGraph::edge_length(int64_t e) const {
  const auto& p = edges[e].points;
  double len = 0.0;
  for (size_t i = 1; i < p.size(); ++i) len += distance(p[i - 1], p[i]);
  return len;
}

double SpatialGraph::total_length() const {
  double len = 0.0;
  for (int64_t e = 0; e < edge_count(); ++e) len += edge_length(e);
  return len;
}

int64_t SpatialGraph::connected_components() const {
  UnionFind uf(node_count());
  int64_t comps = node_count();
  for (const auto& e : edges) comps -= uf.unite(e.node0, e.node1) ? 1 : 0;
  return comps;
}

int64_t SpatialGraph::cyclomatic_number() const {
  return edge_count() - node_count() + connected_components();
}

std::vector<std::string> SpatialGraph::check_invariants() const {
  std::vector<std::string> problems;
  const int64_t nn = node_count();
  for (int64_t i = 0; i < edge_count(); ++i) {
    const auto& e = edges[i];
    const std::string id = "edge " + std::to_string(i);
    if (e.node0 < 0 || e.node0 >= nn || e.node1 < 0 || e.node1 >= nn) {
      problems.push_back(id + ": node id out of range (" + std::to_string(e.node0) + ", " +
                         std::to_string(e.node1) + ")");
      continue;
    }
    if (e.points.size() < 2) {
      problems.push_back(id + ": polyline has " + std::to_string(e.points.size()) +
                         " points, expected >= 2");
      continue;
    }
    if (e.points.front() != positions[e.node0])
      problems.push_back(id + ": first point differs from node " + std::to_string(e.node0));
    if (e.points.back() != positions[e.node1])
      problems.push_back(id + ": last point differs from node " + std::to_string(e.node1));
  }
  auto sized = [&](const std::string& level, const std::string& name, size_t have, size_t want) {
    if (have != want)
      problems.push_back(level + " attribute '" + name + "' has " + std::to_string(have) +
                         " values, expected " + std::to_string(want));
  };
  for (const auto& [n, v] : node_attributes) sized("node", n, v.size(), positions.size());
  for (const auto& [n, v] : node_labels) sized("node label", n, v.size(), positions.size());
  for (const auto& [n, v] : edge_attributes) sized("edge", n, v.size(), edges.size());
  for (const auto& [n, v] : edge_labels) sized("edge label", n, v.size(), edges.size());
  for (const auto& [n, v] : point_attributes) {
    sized("point", n, v.size(), edges.size());
    if (v.size() != edges.size()) continue;
    for (size_t e = 0; e < edges.size(); ++e)
      if (v[e].size() != edges[e].points.size()) {
        problems.push_back("point attribute '" + n + "' of edge " + std::to_string(e) + " has " +
                           std::to_string(v[e].size()) + " values, expected " +
                           std::to_string(edges[e].points.size()));
        break;
      }
  }
  return problems;
}

uint64_t SpatialGraph::bytes() const {
  uint64_t b = positions.size() * sizeof(Vec3) + edges.size() * sizeof(GraphEdge);
  for (const auto& e : edges) b += e.points.size() * sizeof(Vec3);
  for (const auto& [n, v] : node_attributes) b += v.size() * sizeof(float);
  for (const auto& [n, v] : node_labels) b += v.size() * sizeof(int32_t);
  for (const auto& [n, v] : edge_attributes) b += v.size() * sizeof(float);
  for (const auto& [n, v] : edge_labels) b += v.size() * sizeof(int32_t);
  for (const auto& [n, v] : point_attributes) {
    b += v.size() * sizeof(std::vector<float>);
    for (const auto& p : v) b += p.size() * sizeof(float);
  }
  return b;
}

std::string SpatialGraph::describe() const {
  std::ostringstream s;
  s << "graph " << node_count() << " nodes, " << edge_count() << " edges, " << point_count()
    << " points, length " << total_length() << " " << unit;
  auto list = [&](const char* what, const auto& m) {
    if (m.empty()) return;
    s << ", " << what << ":";
    for (const auto& [n, v] : m) s << " " << n;
  };
  list("node attributes", node_attributes);
  list("node labels", node_labels);
  list("edge attributes", edge_attributes);
  list("edge labels", edge_labels);
  list("point attributes", point_attributes);
  return s.str();
}

bool is_length_attribute(const std::string& name) {
  for (const char* w : {"radius", "thickness", "diameter", "length"})
    if (name.find(w) != std::string::npos) return true;
  return false;
}

void scale_graph(SpatialGraph& g, double factor) {
  if (!(factor > 0.0) || !std::isfinite(factor))
    throw InputError("scale: expected a finite factor > 0, got " + std::to_string(factor));
  for (auto& p : g.positions)
    for (double& c : p) c *= factor;
  for (auto& e : g.edges)
    for (auto& p : e.points)
      for (double& c : p) c *= factor;
  const auto f = static_cast<float>(factor);
  for (auto& [name, values] : g.node_attributes)
    if (is_length_attribute(name)) for (auto& v : values) v *= f;
  for (auto& [name, values] : g.edge_attributes)
    if (is_length_attribute(name)) for (auto& v : values) v *= f;
  for (auto& [name, values] : g.point_attributes)
    if (is_length_attribute(name))
      for (auto& per_edge : values)
        for (auto& v : per_edge) v *= f;
  for (int a = 0; a < 3; ++a) {
    g.source_grid.spacing[a] *= factor;
    g.source_grid.origin[a] *= factor;
  }
}

}  // namespace skel
