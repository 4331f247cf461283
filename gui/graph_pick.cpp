#include "graph_pick.hpp"

#include <algorithm>
#include <cmath>
#include <limits>

#include "skel/parallel.hpp"

namespace skel::gui {

namespace {
constexpr int64_t kChunks = 64;  // fixed: results do not depend on the thread count

struct Candidate {
  double pixels = std::numeric_limits<double>::infinity();
  double depth = 0;
  int64_t a = -1, b = -1;  // node, or edge + vertex
};

// Nearer on screen wins; within half a pixel the one nearer to the camera wins.
bool better(const Candidate& x, const Candidate& y) {
  if (x.a < 0) return false;
  if (y.a < 0) return true;
  if (std::abs(x.pixels - y.pixels) < 0.5) return x.depth < y.depth;
  return x.pixels < y.pixels;
}
}  // namespace

bool ScreenProjection::project(const Vec3& p, double& sx, double& sy, double& depth) const {
  const double cx = m[0] * p[0] + m[1] * p[1] + m[2] * p[2] + m[3];
  const double cy = m[4] * p[0] + m[5] * p[1] + m[6] * p[2] + m[7];
  const double cz = m[8] * p[0] + m[9] * p[1] + m[10] * p[2] + m[11];
  const double cw = m[12] * p[0] + m[13] * p[1] + m[14] * p[2] + m[15];
  if (cw <= 0) return false;
  const double nx = cx / cw, ny = cy / cw, nz = cz / cw;
  if (nz < -1 || nz > 1) return false;
  sx = 0.5 * (nx + 1) * width;
  sy = 0.5 * (1 - ny) * height;
  depth = nz;
  return true;
}

GraphPick pick_graph(const SpatialGraph& g, const ScreenProjection& proj, double x, double y, double radius_px,
                     int threads) {
  // Nodes.
  std::vector<Candidate> node_best(kChunks), edge_best(kChunks);
  parallel_chunks(0, g.node_count(), kChunks, threads, [&](int64_t c, int64_t b, int64_t e) {
    Candidate best;
    for (int64_t n = b; n < e; ++n) {
      double sx, sy, d;
      if (!proj.project(g.positions[n], sx, sy, d)) continue;
      const double px = std::hypot(sx - x, sy - y);
      if (px > radius_px) continue;
      Candidate cand{px, d, n, -1};
      if (better(cand, best)) best = cand;
    }
    node_best[c] = best;
  });
  // Edge segments.
  parallel_chunks(0, g.edge_count(), kChunks, threads, [&](int64_t c, int64_t b, int64_t e) {
    Candidate best;
    for (int64_t k = b; k < e; ++k) {
      const auto& pts = g.edges[k].points;
      double ax = 0, ay = 0, ad = 0;
      bool a_ok = proj.project(pts[0], ax, ay, ad);
      for (size_t i = 1; i < pts.size(); ++i) {
        double bx = 0, by = 0, bd = 0;
        const bool b_ok = proj.project(pts[i], bx, by, bd);
        if (a_ok && b_ok) {
          const double vx = bx - ax, vy = by - ay;
          const double len2 = vx * vx + vy * vy;
          double t = len2 > 0 ? ((x - ax) * vx + (y - ay) * vy) / len2 : 0.0;
          t = std::clamp(t, 0.0, 1.0);
          const double px = std::hypot(ax + t * vx - x, ay + t * vy - y);
          if (px <= radius_px) {
            const int64_t vertex = t < 0.5 ? static_cast<int64_t>(i - 1) : static_cast<int64_t>(i);
            Candidate cand{px, ad + t * (bd - ad), k, vertex};
            if (better(cand, best)) best = cand;
          }
        }
        ax = bx;
        ay = by;
        ad = bd;
        a_ok = b_ok;
      }
    }
    edge_best[c] = best;
  });
  Candidate nb, eb;
  for (const auto& c : node_best) {
    if (better(c, nb)) nb = c;
  }
  for (const auto& c : edge_best) {
    if (better(c, eb)) eb = c;
  }
  GraphPick r;
  if (nb.a >= 0 && (eb.a < 0 || nb.pixels <= eb.pixels + 3.0)) {
    r.kind = GraphPick::Kind::Node;
    r.node = nb.a;
    r.position = g.positions[nb.a];
    r.pixels = nb.pixels;
  } else if (eb.a >= 0) {
    r.kind = GraphPick::Kind::EdgePoint;
    r.edge = eb.a;
    r.point = eb.b;
    r.position = g.edges[eb.a].points[eb.b];
    r.pixels = eb.pixels;
  }
  return r;
}

BoxSelection select_box(const SpatialGraph& g, const ScreenProjection& proj, double x0, double y0, double x1,
                        double y1, int threads) {
  if (x0 > x1) std::swap(x0, x1);
  if (y0 > y1) std::swap(y0, y1);
  auto inside = [&](const Vec3& p) {
    double sx, sy, d;
    return proj.project(p, sx, sy, d) && sx >= x0 && sx <= x1 && sy >= y0 && sy <= y1;
  };
  std::vector<std::vector<int64_t>> nodes(kChunks);
  std::vector<std::vector<std::pair<int64_t, int64_t>>> edges(kChunks);
  parallel_chunks(0, g.node_count(), kChunks, threads, [&](int64_t c, int64_t b, int64_t e) {
    for (int64_t n = b; n < e; ++n) {
      if (inside(g.positions[n])) nodes[c].push_back(n);
    }
  });
  parallel_chunks(0, g.edge_count(), kChunks, threads, [&](int64_t c, int64_t b, int64_t e) {
    for (int64_t k = b; k < e; ++k) {
      const auto& pts = g.edges[k].points;
      for (size_t i = 0; i < pts.size(); ++i) {
        if (inside(pts[i])) {
          edges[c].emplace_back(k, static_cast<int64_t>(i));
          break;
        }
      }
    }
  });
  BoxSelection r;
  for (auto& v : nodes) r.nodes.insert(r.nodes.end(), v.begin(), v.end());
  for (auto& v : edges) r.edge_points.insert(r.edge_points.end(), v.begin(), v.end());
  return r;
}

}  // namespace skel::gui
