// Editing benchmark (issue 10): on a lattice graph of ~10⁶ segments with polylines, the time of each
// GraphEditor operation and of its undo (median and max over `reps` operations), the same with the
// fsync'd journal, replay of journal entries by position (graph.apply_edits), and screen-space
// picking / box selection with gui/graph_pick (the code the GUI's edit mode uses).
// Usage: bench_editing WORK_DIR [n = 70 (n³ nodes, 3n³ edges)] [reps = 100]
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <functional>
#include <random>
#include <string>
#include <vector>

#include "common/bench_util.hpp"
#include "graph/editor.hpp"
#include "graph_pick.hpp"

using namespace skel::graph;

using namespace skel;
using skel::bench::now_seconds;

namespace {

// n³ nodes on a grid of spacing 10; an edge to the +x, +y and +z neighbour, each a 4-point polyline
// with two jittered interior points; a radius point attribute and a label.
SpatialGraph lattice(int64_t n) {
  SpatialGraph g;
  std::mt19937_64 rng(7);
  std::uniform_real_distribution<double> jit(-1.0, 1.0);
  auto id = [n](int64_t x, int64_t y, int64_t z) { return x + n * (y + n * z); };
  g.positions.reserve(static_cast<size_t>(n * n * n));
  for (int64_t z = 0; z < n; ++z)
    for (int64_t y = 0; y < n; ++y)
      for (int64_t x = 0; x < n; ++x) g.positions.push_back({10.0 * x, 10.0 * y, 10.0 * z});
  g.edges.reserve(static_cast<size_t>(3 * n * n * n));
  for (int64_t z = 0; z < n; ++z)
    for (int64_t y = 0; y < n; ++y)
      for (int64_t x = 0; x < n; ++x) {
        const int64_t a = id(x, y, z);
        const int64_t nb[3] = {x + 1 < n ? id(x + 1, y, z) : -1, y + 1 < n ? id(x, y + 1, z) : -1,
                               z + 1 < n ? id(x, y, z + 1) : -1};
        for (int64_t b : nb) {
          if (b < 0) continue;
          const Vec3 p = g.positions[a], q = g.positions[b];
          std::vector<Vec3> pts{p};
          for (double t : {1.0 / 3, 2.0 / 3})
            pts.push_back({p[0] + t * (q[0] - p[0]) + jit(rng), p[1] + t * (q[1] - p[1]) + jit(rng),
                           p[2] + t * (q[2] - p[2]) + jit(rng)});
          pts.push_back(q);
          g.edges.push_back({a, b, std::move(pts)});
        }
      }
  auto& r = g.ensure_point_attribute("radius", 1.0f);
  for (auto& v : r) std::fill(v.begin(), v.end(), 1.5f);
  g.ensure_edge_label("kind", 0);
  return g;
}

struct Stat {
  double median = 0, max = 0;
};
Stat stat(std::vector<double> v) {
  if (v.empty()) return {};
  std::sort(v.begin(), v.end());
  return {1e3 * v[v.size() / 2], 1e3 * v.back()};
}

// Perspective camera looking at the lattice's centre from outside (world -> clip, row-major).
gui::ScreenProjection camera(double extent, double w, double h) {
  const Vec3 c{extent / 2, extent / 2, extent / 2};
  const Vec3 eye{c[0] + 1.2 * extent, c[1] + 0.9 * extent, c[2] + 1.5 * extent};
  auto sub = [](Vec3 a, Vec3 b) { return Vec3{a[0] - b[0], a[1] - b[1], a[2] - b[2]}; };
  auto norm = [](Vec3 a) {
    const double l = std::sqrt(a[0] * a[0] + a[1] * a[1] + a[2] * a[2]);
    return Vec3{a[0] / l, a[1] / l, a[2] / l};
  };
  auto cross = [](Vec3 a, Vec3 b) {
    return Vec3{a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]};
  };
  auto dot = [](Vec3 a, Vec3 b) { return a[0] * b[0] + a[1] * b[1] + a[2] * b[2]; };
  const Vec3 f = norm(sub(c, eye)), s = norm(cross(f, {0, 0, 1})), u = cross(s, f);
  const double view[16] = {s[0], s[1], s[2], -dot(s, eye), u[0], u[1], u[2], -dot(u, eye),
                           -f[0], -f[1], -f[2], dot(f, eye), 0, 0, 0, 1};
  const double fov = 30.0 * M_PI / 180, aspect = w / h, zn = 0.1 * extent, zf = 10 * extent;
  const double t = 1.0 / std::tan(fov / 2);
  const double proj[16] = {t / aspect, 0, 0, 0, 0, t, 0, 0, 0, 0, (zf + zn) / (zn - zf), 2 * zf * zn / (zn - zf),
                           0, 0, -1, 0};
  gui::ScreenProjection p;
  for (int i = 0; i < 4; ++i)
    for (int j = 0; j < 4; ++j) {
      double v = 0;
      for (int k = 0; k < 4; ++k) v += proj[4 * i + k] * view[4 * k + j];
      p.m[static_cast<size_t>(4 * i + j)] = v;
    }
  p.width = w;
  p.height = h;
  return p;
}

}  // namespace

int main(int argc, char** argv) {
  const std::string work = argc > 1 ? argv[1] : "/tmp";
  const int64_t n = argc > 2 ? std::stoll(argv[2]) : 70;
  const int reps = argc > 3 ? std::stoi(argv[3]) : 100;
  double t0 = now_seconds();
  SpatialGraph g0 = lattice(n);
  const double t_build = now_seconds() - t0;
  std::printf("Lattice: %lld nodes, %lld edges, %lld polyline points (built in %.2f s).\n\n",
              static_cast<long long>(g0.node_count()), static_cast<long long>(g0.edge_count()),
              static_cast<long long>(g0.point_count()), t_build);

  std::printf("| op | op median ms | op max ms | undo median ms | undo max ms | op + journal (fsync) median ms | op + journal max ms |\n");
  std::printf("|---|---|---|---|---|---|---|\n");
  std::mt19937_64 rng(11);
  auto rnd = [&](int64_t k) { return static_cast<int64_t>(rng() % static_cast<uint64_t>(k)); };

  graph::GraphEditor plain{SpatialGraph(g0)};
  graph::GraphEditor journaled{SpatialGraph(g0)};
  journaled.set_journal(work + "/bench.edits.yaml", 1.0);
  const int64_t nodes = g0.node_count();
  auto grid_node = [&](int64_t x, int64_t y, int64_t z) { return x + n * (y + n * z); };

  // Each case: prepare (untimed, may return false to skip), op (timed), then undo (timed); the
  // graph returns to the lattice after every repetition.
  struct Case {
    const char* name;
    std::function<void(graph::GraphEditor&)> op;
    std::function<void(graph::GraphEditor&)> before;  // untimed set-up step (undone afterwards)
  };
  int64_t a = 0, b = 0, e = 0;
  std::vector<Case> cases = {
      {"delete_edge", [&](graph::GraphEditor& ed) { ed.delete_edges({e}); }, nullptr},
      {"delete_node", [&](graph::GraphEditor& ed) { ed.delete_node(a); }, nullptr},
      {"connect node-node (straight)", [&](graph::GraphEditor& ed) { ed.connect(a, b); }, nullptr},
      {"connect node-edge point", [&](graph::GraphEditor& ed) { ed.connect(a, -1, e, 1); }, nullptr},
      {"split", [&](graph::GraphEditor& ed) { ed.split(e, 1); }, nullptr},
      {"merge", [&](graph::GraphEditor& ed) { ed.merge(ed.graph().node_count() - 1); },
       [&](graph::GraphEditor& ed) { ed.split(e, 1); }},
      {"move_node", [&](graph::GraphEditor& ed) { ed.move_node(a, {ed.graph().positions[a][0] + 2, ed.graph().positions[a][1] + 1, ed.graph().positions[a][2]}); }, nullptr},
      {"set radius (edge points)", [&](graph::GraphEditor& ed) { ed.set_attribute(graph::Level::edge, {e}, "radius", 2.5); }, nullptr},
  };
  for (const auto& c : cases) {
    std::vector<double> t_op, t_undo, t_journal;
    for (int r = 0; r < reps; ++r) {
      const int64_t x = 1 + rnd(n - 3), y = 1 + rnd(n - 3), z = 1 + rnd(n - 3);
      a = grid_node(x, y, z);
      b = grid_node(x + 2, y, z);
      e = rnd(g0.edge_count());
      for (graph::GraphEditor* ed : {&plain, &journaled}) {
        if (c.before) c.before(*ed);
        double s = now_seconds();
        c.op(*ed);
        const double top = now_seconds() - s;
        s = now_seconds();
        ed->undo();
        const double tundo = now_seconds() - s;
        if (c.before) ed->undo();
        if (ed == &plain) {
          t_op.push_back(top);
          t_undo.push_back(tundo);
        } else {
          t_journal.push_back(top);
        }
      }
    }
    const Stat so = stat(t_op), su = stat(t_undo), sj = stat(t_journal);
    std::printf("| %s | %.3f | %.3f | %.3f | %.3f | %.3f | %.3f |\n", c.name, so.median, so.max, su.median, su.max,
                sj.median, sj.max);
  }
  const bool same = graph::same_graph(plain.graph(), g0) && graph::same_graph(journaled.graph(), g0);
  std::printf("\nAfter %d × %zu ops and undos both graphs are %s the lattice.\n\n", reps, cases.size(),
              same ? "identical to" : "DIFFERENT from");

  // Replay by position (graph.apply_edits): resolving `at` needs a search over all nodes / points.
  {
    std::vector<double> t_node, t_edge;
    for (int r = 0; r < std::min(reps, 20); ++r) {
      const int64_t k = grid_node(1 + rnd(n - 3), 1 + rnd(n - 3), 1 + rnd(n - 3));
      graph::EditOp op(graph::EditKind::delete_node);
      op.at.push_back(plain.graph().positions[k]);
      double s = now_seconds();
      plain.apply(op, 0.5);
      t_node.push_back(now_seconds() - s);
      plain.undo();
      graph::EditOp op2(graph::EditKind::delete_edge);
      op2.at.push_back(plain.graph().edges[rnd(plain.graph().edge_count())].points[1]);
      s = now_seconds();
      plain.apply(op2, 0.5);
      t_edge.push_back(now_seconds() - s);
      plain.undo();
    }
    const Stat sn = stat(t_node), se = stat(t_edge);
    std::printf("| replay entry (apply by position) | median ms | max ms |\n|---|---|---|\n");
    std::printf("| delete_node {at} (node search) | %.2f | %.2f |\n", sn.median, sn.max);
    std::printf("| delete_edge {at} (polyline search) | %.2f | %.2f |\n\n", se.median, se.max);
  }

  // Batch operations (one undo step each; not interactive single edits).
  {
    std::printf("| batch op | op ms | undo ms | changed |\n|---|---|---|---|\n");
    graph::GraphEditor ed{SpatialGraph(g0)};
    // Make 1000 dangling ends first (untimed): a random node keeps one of its 6 lattice edges, so it
    // ends a 10-long spur pointing at the next lattice node — prune {15} removes the spurs,
    // bridge_gaps {12} (on the state before the prune, which is undone) reconnects them.
    std::vector<std::vector<int64_t>> incident(static_cast<size_t>(g0.node_count()));
    for (int64_t e = 0; e < g0.edge_count(); ++e) {
      incident[static_cast<size_t>(g0.edges[static_cast<size_t>(e)].node0)].push_back(e);
      incident[static_cast<size_t>(g0.edges[static_cast<size_t>(e)].node1)].push_back(e);
    }
    std::vector<int64_t> del;
    std::vector<char> touched(static_cast<size_t>(g0.node_count()), 0);
    for (int made = 0; made < 1000;) {
      const int64_t v = rnd(g0.node_count());
      if (touched[static_cast<size_t>(v)] || incident[static_cast<size_t>(v)].size() < 6) continue;
      bool ok = true;  // keep the ends apart: no neighbour may be an end already
      for (int64_t e : incident[static_cast<size_t>(v)]) {
        const auto& ed0 = g0.edges[static_cast<size_t>(e)];
        ok = ok && !touched[static_cast<size_t>(ed0.node0 == v ? ed0.node1 : ed0.node0)];
      }
      if (!ok) continue;
      touched[static_cast<size_t>(v)] = 1;
      for (size_t k = 1; k < incident[static_cast<size_t>(v)].size(); ++k) del.push_back(incident[static_cast<size_t>(v)][k]);
      ++made;
    }
    std::sort(del.begin(), del.end());
    del.erase(std::unique(del.begin(), del.end()), del.end());
    ed.delete_edges(del);
    const int64_t e0 = ed.graph().edge_count();
    for (const char* name : {"prune {max_length: 15}", "bridge_gaps {max_distance: 12}"}) {
      double s = now_seconds();
      if (name[0] == 'p') ed.prune(15.0);
      else ed.bridge_gaps(12.0);
      const double top = now_seconds() - s;
      const int64_t changed = ed.graph().edge_count() - e0;
      s = now_seconds();
      ed.undo();
      const double tundo = now_seconds() - s;
      std::printf("| %s | %.1f | %.1f | %+lld edges |\n", name, 1e3 * top, 1e3 * tundo, static_cast<long long>(changed));
    }
    std::printf("\n");
  }

  // Picking as in the GUI: nearest node / edge segment within 8 px on a 1200×900 view.
  {
    const gui::ScreenProjection cam = camera(10.0 * (n - 1), 1200, 900);
    std::printf("| picking (gui/graph_pick, %lld points, 1200×900 view) | threads | median ms | max ms | hits |\n|---|---|---|---|---|\n",
                static_cast<long long>(g0.point_count()));
    for (int threads : {1, 2}) {
      std::vector<double> t;
      int hits = 0;
      std::mt19937_64 prng(5);
      for (int r = 0; r < 100; ++r) {
        const double x = 200 + static_cast<double>(prng() % 800), y = 150 + static_cast<double>(prng() % 600);
        const double s = now_seconds();
        const auto p = gui::pick_graph(g0, cam, x, y, 8.0, threads);
        t.push_back(now_seconds() - s);
        hits += p.valid();
      }
      const Stat st = stat(t);
      std::printf("| pick (100 clicks) | %d | %.1f | %.1f | %d |\n", threads, st.median, st.max, hits);
    }
    std::vector<double> t;
    size_t selected = 0;
    for (int r = 0; r < 20; ++r) {
      const double s = now_seconds();
      const auto box = gui::select_box(g0, cam, 500, 350, 700, 550, 2);
      t.push_back(now_seconds() - s);
      selected = box.nodes.size() + box.edge_points.size();
    }
    const Stat st = stat(t);
    std::printf("| box select 200×200 px (20 times) | 2 | %.1f | %.1f | %zu elements |\n", st.median, st.max, selected);
  }
  (void)nodes;
  std::printf("\nPeak RSS: %.0f MiB.\n", skel::bench::peak_rss_mib());
  return same ? 0 : 1;
}
