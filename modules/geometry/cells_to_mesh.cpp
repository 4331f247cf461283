// Grid cell skeleton -> mesh (simple and detailed piecewise linear geometry, thesis §3.2) and graph.
#include "geometry/cells_to_mesh.hpp"

#include <cmath>
#include <unordered_map>

namespace skel::geometry {

namespace {

using K = std::array<int64_t, 3>;

int cell_dim(const K& k) { return static_cast<int>((k[0] & 1) + (k[1] & 1) + (k[2] & 1)); }
bool has(const GridCells& c, const K& k) { return c.has(k[0], k[1], k[2]); }
K shifted(K k, int axis, int64_t s) {
  k[static_cast<size_t>(axis)] += s;
  return k;
}

// Number of present cofaces of 1-cell e of dimension 2 and 3.
std::array<int, 2> edge_cofaces(const GridCells& c, const K& e) {
  int axis = 0;
  while (!(e[static_cast<size_t>(axis)] & 1)) ++axis;
  const int a = (axis + 1) % 3, b = (axis + 2) % 3;
  int n2 = 0, n3 = 0;
  for (int s = -1; s <= 1; s += 2) {
    n2 += has(c, shifted(e, a, s));
    n2 += has(c, shifted(e, b, s));
    for (int t = -1; t <= 1; t += 2) n3 += has(c, shifted(shifted(e, a, s), b, t));
  }
  return {n2, n3};
}

bool manifold_class(ManifoldType t) {
  return t == ManifoldType::line || t == ManifoldType::line_end || t == ManifoldType::surface ||
         t == ManifoldType::surface_edge;
}

}  // namespace

ManifoldType classify_cell(const GridCells& c, int64_t kx, int64_t ky, int64_t kz) {
  const K k{kx, ky, kz};
  if (!has(c, k)) return ManifoldType::background;
  switch (cell_dim(k)) {
    case 0: {
      int n1 = 0, bare = 0, ones = 0, twos = 0, other = 0, n3 = 0, n2 = 0;
      for (int a = 0; a < 3; ++a)
        for (int s = -1; s <= 1; s += 2) {
          const K e = shifted(k, a, s);
          if (!has(c, e)) continue;
          ++n1;
          const auto f = edge_cofaces(c, e);
          n2 += f[0];
          if (f[0] == 0) ++bare;
          else if (f[0] == 1) ++ones;
          else if (f[0] == 2) ++twos;
          else ++other;
        }
      for (int s = -1; s <= 1; s += 2)
        for (int t = -1; t <= 1; t += 2)
          for (int u = -1; u <= 1; u += 2) n3 += has(c, K{kx + s, ky + t, kz + u});
      if (n3 == 0 && n2 == 0) {
        if (n1 == 0) return ManifoldType::point;
        if (n1 == 1) return ManifoldType::line_end;
        if (n1 == 2) return ManifoldType::line;
        return ManifoldType::line_junction;
      }
      if (bare > 0) return ManifoldType::line_junction;
      if (n3 == 0 && other == 0 && ones == 0) return ManifoldType::surface;
      if (n3 == 0 && other == 0 && ones == 2) return ManifoldType::surface_edge;
      return ManifoldType::junction;
    }
    case 1: {
      const auto f = edge_cofaces(c, k);
      if (f[0] == 0) return ManifoldType::line;
      if (f[1] == 0 && f[0] == 2) return ManifoldType::surface;
      if (f[1] == 0 && f[0] == 1) return ManifoldType::surface_edge;
      return ManifoldType::junction;
    }
    case 2: {
      int axis = 0;
      while (k[static_cast<size_t>(axis)] & 1) ++axis;
      return has(c, shifted(k, axis, -1)) || has(c, shifted(k, axis, 1)) ? ManifoldType::junction : ManifoldType::surface;
    }
    default:
      return ManifoldType::junction;
  }
}

namespace {

// Visits the present cells of dimension `dims_mask` bit d in raster order of the lattice (bits ascending).
template <class F>
void for_each_cell(const GridCells& c, unsigned dims_mask, F&& f) {
  const Dims ld = c.lattice_dims();
  const auto& bytes = c.bytes_data();
  for (int64_t li = 0, n = c.lattice_size(); li < n; ++li) {
    const uint8_t b = bytes[static_cast<size_t>(li)];
    if (!b) continue;
    const int64_t i = li % ld[0], j = (li / ld[0]) % ld[1], l = li / (ld[0] * ld[1]);
    for (int bit = 0; bit < 8; ++bit)
      if (((b >> bit) & 1) && ((dims_mask >> GridCells::bit_dimension(bit)) & 1))
        f(K{2 * i + (bit & 1), 2 * j + ((bit >> 1) & 1), 2 * l + ((bit >> 2) & 1)});
  }
}

class MeshBuilder {
public:
  MeshBuilder(const GridCells& c) : c_(c) {
    const Dims d = c.grid().dims;
    sx_ = 3 * d[0] + 4;
    sy_ = 3 * d[1] + 4;
    mesh_.unit = c.grid().unit;
    mesh_.vertex_attributes["manifold"] = std::vector<int32_t>{};
    mesh_.vertex_attributes["fixed"] = std::vector<int32_t>{};
  }
  // Vertex at subdivided position s (3 per voxel edge; a 0-cell at lattice p is s = 3p).
  int64_t vertex(const K& s) {
    const uint64_t key = static_cast<uint64_t>(s[0] + sx_ * (s[1] + sy_ * s[2]));
    auto [it, fresh] = ids_.try_emplace(key, mesh_.vertex_count());
    if (!fresh) return it->second;
    const Grid& g = c_.grid();
    Mesh::Point p{};
    for (size_t a = 0; a < 3; ++a)
      p[a] = static_cast<float>(g.origin[a] + (static_cast<double>(s[a]) / 3.0 - 0.5) * g.spacing[a]);
    mesh_.add_vertex(p);
    // The cell the vertex lies in.
    K k{};
    for (size_t a = 0; a < 3; ++a) k[a] = s[a] % 3 == 0 ? 2 * (s[a] / 3) : 2 * (s[a] / 3) + 1;
    const ManifoldType t = classify_cell(c_, k[0], k[1], k[2]);
    std::get<std::vector<int32_t>>(mesh_.vertex_attributes["manifold"]).push_back(static_cast<int32_t>(t));
    std::get<std::vector<int32_t>>(mesh_.vertex_attributes["fixed"]).push_back(t == ManifoldType::line_junction ? 1 : 0);
    return it->second;
  }
  void triangle(int64_t a, int64_t b, int64_t d, bool manifold, ManifoldType cls) {
    mesh_.add_triangle(a, b, d);
    tri_manifold_.push_back(manifold ? 1 : 0);
    tri_class_.push_back(static_cast<int32_t>(cls));
  }
  void line(int64_t a, int64_t b, bool manifold, ManifoldType cls) {
    mesh_.add_line({a, b});
    line_manifold_.push_back(manifold ? 1 : 0);
    line_class_.push_back(static_cast<int32_t>(cls));
  }
  Mesh finish() {
    mesh_.triangle_attributes["manifold"] = std::move(tri_manifold_);
    mesh_.triangle_attributes["cell_class"] = std::move(tri_class_);
    mesh_.line_attributes["manifold"] = std::move(line_manifold_);
    mesh_.line_attributes["cell_class"] = std::move(line_class_);
    return std::move(mesh_);
  }

private:
  const GridCells& c_;
  int64_t sx_ = 0, sy_ = 0;
  Mesh mesh_;
  std::unordered_map<uint64_t, int64_t> ids_;
  std::vector<int32_t> tri_manifold_, tri_class_, line_manifold_, line_class_;
};

K subdivided(const K& k0) { return {3 * (k0[0] / 2), 3 * (k0[1] / 2), 3 * (k0[2] / 2)}; }

}  // namespace

Mesh cells_to_mesh(const GridCells& c, const CellsToMeshOptions& o) {
  MeshBuilder mb(c);
  const bool detailed = o.geometry == CellGeometry::detailed;
  int64_t done = 0;
  auto cls = [&](const K& k) { return classify_cell(c, k[0], k[1], k[2]); };
  for_each_cell(c, 0b0110, [&](const K& k) {
    if ((++done & 0xFFFFF) == 0) o.interrupter.check();
    const ManifoldType t = cls(k);
    if (cell_dim(k) == 1) {
      if (t != ManifoldType::line) return;  // bounds a 2-cell: drawn by the quads
      int axis = 0;
      while (!(k[static_cast<size_t>(axis)] & 1)) ++axis;
      const K lo = shifted(k, axis, -1), hi = shifted(k, axis, 1);
      const ManifoldType tl = cls(lo), th = cls(hi);
      if (!detailed) {
        mb.line(mb.vertex(subdivided(lo)), mb.vertex(subdivided(hi)), manifold_class(tl) && manifold_class(th), t);
        return;
      }
      const K s0 = subdivided(lo);
      const int64_t v0 = mb.vertex(s0), v1 = mb.vertex(shifted(s0, axis, 1)), v2 = mb.vertex(shifted(s0, axis, 2)),
                    v3 = mb.vertex(shifted(s0, axis, 3));
      mb.line(v0, v1, manifold_class(tl), tl);
      mb.line(v1, v2, true, t);
      mb.line(v2, v3, manifold_class(th), th);
      return;
    }
    // A 2-cell: axes a < b in its plane.
    int a = -1, b = -1;
    for (int x = 0; x < 3; ++x)
      if (k[static_cast<size_t>(x)] & 1) (a < 0 ? a : b) = x;
    const K base = shifted(shifted(k, a, -1), b, -1);  // its lowest 0-cell
    if (!detailed) {
      bool all = t == ManifoldType::surface;
      K corner[4] = {base, shifted(base, a, 2), shifted(shifted(base, a, 2), b, 2), shifted(base, b, 2)};
      int64_t v[4];
      for (int i = 0; i < 4; ++i) {
        all = all && manifold_class(cls(corner[i]));
        v[i] = mb.vertex(subdivided(corner[i]));
      }
      mb.triangle(v[0], v[1], v[2], all, t);
      mb.triangle(v[0], v[2], v[3], all, t);
      return;
    }
    const K s0 = subdivided(base);
    for (int j = 0; j < 3; ++j)
      for (int i = 0; i < 3; ++i) {
        // The cell this tile represents: per axis, tile 0 / 2 lies at the low / high 0-cell coordinate,
        // tile 1 inside the 2-cell's span.
        K rep = base;
        rep[static_cast<size_t>(a)] += i;
        rep[static_cast<size_t>(b)] += j;
        const ManifoldType rt = cls(rep);
        const bool manifold = cell_dim(rep) == 2 ? rt == ManifoldType::surface : manifold_class(rt);
        const K p = shifted(shifted(s0, a, i), b, j);
        const int64_t v0 = mb.vertex(p), v1 = mb.vertex(shifted(p, a, 1)), v2 = mb.vertex(shifted(shifted(p, a, 1), b, 1)),
                      v3 = mb.vertex(shifted(p, b, 1));
        mb.triangle(v0, v1, v2, manifold, rt);
        mb.triangle(v0, v2, v3, manifold, rt);
      }
  });
  return mb.finish();
}

SpatialGraph cells_to_graph(const GridCells& c, const Interrupter& interrupter) {
  SpatialGraph g;
  g.unit = c.grid().unit;
  g.source_grid = c.grid();
  auto bare_edge = [&](const K& e) { return has(c, e) && edge_cofaces(c, e)[0] == 0; };
  auto bare_count = [&](const K& v) {
    int n = 0;
    for (int a = 0; a < 3; ++a)
      for (int s = -1; s <= 1; s += 2) n += bare_edge(shifted(v, a, s));
    return n;
  };
  auto is_node = [&](const K& v) {
    const int n = bare_count(v);
    if (n == 0) return false;
    if (n != 2) return true;
    return classify_cell(c, v[0], v[1], v[2]) != ManifoldType::line;  // attached to a surface or a 3-cell
  };
  auto position = [&](const K& v) {
    const Grid& gr = c.grid();
    Vec3 p{};
    for (size_t a = 0; a < 3; ++a) p[a] = gr.origin[a] + (static_cast<double>(v[a] / 2) - 0.5) * gr.spacing[a];
    return p;
  };
  GridCells visited(c.grid());  // the bare 1-cells already in an edge
  std::unordered_map<uint64_t, int64_t> node_of;
  const Dims kd = c.cell_dims();
  auto key = [&](const K& v) { return static_cast<uint64_t>(v[0] + kd[0] * (v[1] + kd[1] * v[2])); };
  auto node = [&](const K& v) {
    auto [it, fresh] = node_of.try_emplace(key(v), g.node_count());
    if (fresh) g.add_node(position(v));
    return it->second;
  };
  std::vector<int32_t> node_class;
  std::vector<float> lengths;
  // Walks from node 0-cell v along bare 1-cell e until a node 0-cell; adds the edge.
  auto trace = [&](const K& v0, const K& e0) {
    std::vector<Vec3> pts{position(v0)};
    K v = v0, e = e0;
    double len = 0;
    while (true) {
      visited.set(e[0], e[1], e[2], true);
      const K w{2 * e[0] - v[0], 2 * e[1] - v[1], 2 * e[2] - v[2]};
      pts.push_back(position(w));
      const Vec3& p = pts[pts.size() - 2];
      const Vec3& q = pts.back();
      len += std::sqrt((p[0] - q[0]) * (p[0] - q[0]) + (p[1] - q[1]) * (p[1] - q[1]) + (p[2] - q[2]) * (p[2] - q[2]));
      if (w == v0 || node_of.count(key(w)) || is_node(w)) {
        const int64_t n1 = node(w);
        g.add_edge(node_of.at(key(v0)), n1, std::move(pts));
        lengths.push_back(static_cast<float>(len));
        return;
      }
      K next{};
      bool found = false;
      for (int a = 0; a < 3 && !found; ++a)
        for (int s = -1; s <= 1 && !found; s += 2) {
          const K f = shifted(w, a, s);
          if (f != e && bare_edge(f)) {
            next = f;
            found = true;
          }
        }
      v = w;
      e = next;
    }
  };
  int64_t done = 0;
  for_each_cell(c, 0b0001, [&](const K& v) {
    if ((++done & 0xFFFFF) == 0) interrupter.check();
    if (!is_node(v)) return;
    node(v);
    for (int a = 0; a < 3; ++a)
      for (int s = -1; s <= 1; s += 2) {
        const K e = shifted(v, a, s);
        if (bare_edge(e) && !visited.has(e[0], e[1], e[2])) trace(v, e);
      }
  });
  // Closed chains without a node.
  for_each_cell(c, 0b0010, [&](const K& e) {
    if (!bare_edge(e) || visited.has(e[0], e[1], e[2])) return;
    int axis = 0;
    while (!(e[static_cast<size_t>(axis)] & 1)) ++axis;
    const K v = shifted(e, axis, -1);
    node(v);
    trace(v, e);
  });
  node_class.resize(static_cast<size_t>(g.node_count()));
  for (const auto& [k, n] : node_of) {
    const auto kk = static_cast<int64_t>(k);
    node_class[static_cast<size_t>(n)] =
        static_cast<int32_t>(classify_cell(c, kk % kd[0], (kk / kd[0]) % kd[1], kk / (kd[0] * kd[1])));
  }
  g.ensure_node_label("manifold") = std::move(node_class);
  g.ensure_edge_attribute("length") = std::move(lengths);
  return g;
}

}  // namespace skel::geometry
