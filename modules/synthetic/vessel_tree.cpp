#include "synthetic/vessel_tree.hpp"

#include <algorithm>
#include <cmath>
#include <deque>
#include <limits>
#include <queue>
#include <string>
#include <vector>

#include "skel/error.hpp"
#include "skel/parallel.hpp"
#include "skel/union_find.hpp"
#include "synthetic/network.hpp"

namespace skel::synthetic {

namespace {

using V = std::array<double, 3>;
V add(V a, V b) { return {a[0] + b[0], a[1] + b[1], a[2] + b[2]}; }
V sub(V a, V b) { return {a[0] - b[0], a[1] - b[1], a[2] - b[2]}; }
V mul(V a, double s) { return {a[0] * s, a[1] * s, a[2] * s}; }
double dot(V a, V b) { return a[0] * b[0] + a[1] * b[1] + a[2] * b[2]; }
V cross(V a, V b) { return {a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]}; }
double norm(V a) { return std::sqrt(dot(a, a)); }
V unit(V a) {
  const double n = norm(a);
  return n > 0 ? mul(a, 1.0 / n) : V{1, 0, 0};
}

// Distance between point p and segment [a, b].
double point_segment(V p, V a, V b) {
  const V ab = sub(b, a);
  const double l2 = dot(ab, ab);
  double t = l2 > 0 ? dot(sub(p, a), ab) / l2 : 0.0;
  t = std::clamp(t, 0.0, 1.0);
  return norm(sub(p, add(a, mul(ab, t))));
}

// Exact distance between segments [a0, a1] and [b0, b1] (closest points by clamped parameters).
double segment_segment(V a0, V a1, V b0, V b1) {
  const V d1 = sub(a1, a0), d2 = sub(b1, b0), r = sub(a0, b0);
  const double a = dot(d1, d1), e = dot(d2, d2), f = dot(d2, r);
  double s = 0, t = 0;
  if (a <= 1e-12 && e <= 1e-12) return norm(r);
  if (a <= 1e-12) {
    t = std::clamp(f / e, 0.0, 1.0);
  } else {
    const double c = dot(d1, r);
    if (e <= 1e-12) {
      s = std::clamp(-c / a, 0.0, 1.0);
    } else {
      const double bb = dot(d1, d2), den = a * e - bb * bb;
      s = den > 1e-12 ? std::clamp((bb * f - c * e) / den, 0.0, 1.0) : 0.0;
      t = (bb * s + f) / e;
      if (t < 0) {
        t = 0;
        s = std::clamp(-c / a, 0.0, 1.0);
      } else if (t > 1) {
        t = 1;
        s = std::clamp((bb - c) / a, 0.0, 1.0);
      }
    }
  }
  return norm(sub(add(a0, mul(d1, s)), add(b0, mul(d2, t))));
}

// Polynomial smooth minimum: equals min(a, b) where they differ by more than k, and blends them
// (at most k/4 lower) where they are close. Fills the crevice between two vessels that meet at a
// node, whose digitisation would otherwise trap background voxels (spurious tunnels and cavities).
double smooth_min(double a, double b, double k) {
  const double h = std::max(k - std::abs(a - b), 0.0) / k;
  return std::min(a, b) - h * h * k * 0.25;
}
constexpr double kFillet = 4.0;       // smooth-min width at nodes, voxels
constexpr double kMinAngleDeg = 35.0;  // least angle between two capillaries' or vessels' directions at a node

struct Seg {
  int64_t n0, n1;
  double radius;
  int tree;  // 0 artery, 1 vein, 2 capillary
};

}  // namespace

VesselTreeResult make_vessel_tree(const VesselTreeOptions& o) {
  const Grid grid(o.size, o.spacing, {0.0, 0.0, 0.0}, o.unit);
  grid.validate();
  if (o.roots < 2) throw InputError("roots must be >= 2 (at least one arterial and one venous tree)");
  if (o.min_radius < 1.0) throw InputError("min_radius must be >= 1 voxel");
  if (o.root_radius < o.min_radius) throw InputError("root_radius must be >= min_radius");
  const double nx = static_cast<double>(o.size[0]), ny = static_cast<double>(o.size[1]), nz = static_cast<double>(o.size[2]);
  if (o.length_scale < 0) throw InputError("length_scale must be >= 0 (0 = automatic)");
  // Vessel and capillary lengths grow with the volume so that the network fills it.
  const double scale = o.length_scale > 0 ? o.length_scale
                                          : std::max(1.0, static_cast<double>(std::min({o.size[0], o.size[1], o.size[2]})) / 128.0);
  const double capillary_length = o.capillary_length * scale;
  const double clearance = 4.0;  // free voxels between vessels that are not connected (> kFillet / 4 + 2)
  std::vector<V> nodes;
  std::vector<int> kind;
  std::vector<Seg> segs;
  uint64_t counter = 0;
  auto rnd = [&]() { return hash_uniform(o.seed, 7, static_cast<int64_t>(counter++), 0); };

  auto inside = [&](V p, double r) {
    const double m = r + 2.0;
    return p[0] >= m && p[1] >= m && p[2] >= m && p[0] <= nx - 1 - m && p[1] <= ny - 1 - m && p[2] <= nz - 1 - m;
  };
  // May a segment a–b of radius r be added? Not within clearance of any segment that does not share
  // an end node with it (segments meeting at a node overlap by design).
  auto free_path = [&](V a, V b, double r, int64_t na, int64_t nb) {
    for (const auto& s : segs) {
      if (s.n0 == na || s.n1 == na || (nb >= 0 && (s.n0 == nb || s.n1 == nb))) continue;
      // Also skip segments touching the neighbours of na (the parent's other children).
      if (segment_segment(a, b, nodes[s.n0], nodes[s.n1]) < r + s.radius + clearance) return false;
    }
    for (int64_t n = 0; n < static_cast<int64_t>(nodes.size()); ++n) {
      if (n == na || n == nb) continue;
      if (point_segment(nodes[n], a, b) < r + clearance + 1.0 && norm(sub(nodes[n], a)) > r + 1) return false;
    }
    return true;
  };

  // A capillary a–v must keep clear of other vessels and leave both ends at >= kMinAngleDeg from the
  // vessels already there (shallow junctions make thin crevices).
  const double cos_min = std::cos(kMinAngleDeg * 3.14159265358979 / 180.0);
  auto angle_ok = [&](int64_t n, V dir) {
    for (const auto& s : segs) {
      if (s.n0 != n && s.n1 != n) continue;
      const V other = unit(sub(nodes[s.n0 == n ? s.n1 : s.n0], nodes[n]));
      if (dot(other, dir) > cos_min) return false;
    }
    return true;
  };
  // The loop a capillary closes must be long enough to leave an open hole in the mask (a short
  // triangle of vessels fills in): the path a ~> v already in the graph plus |a v| >= min_loop.
  const double min_loop = 14.0 * (o.min_radius + 2.0);
  auto path_length = [&](int64_t from, int64_t to, double limit) {
    std::vector<double> dist(nodes.size(), std::numeric_limits<double>::infinity());
    using Item = std::pair<double, int64_t>;
    std::priority_queue<Item, std::vector<Item>, std::greater<>> queue;
    dist[from] = 0;
    queue.push({0.0, from});
    while (!queue.empty()) {
      const auto [d, n] = queue.top();
      queue.pop();
      if (n == to) return d;
      if (d > dist[n] || d > limit) continue;
      for (const auto& s : segs) {
        const int64_t m = s.n0 == n ? s.n1 : s.n1 == n ? s.n0 : -1;
        if (m < 0) continue;
        const double nd = d + norm(sub(nodes[s.n0], nodes[s.n1]));
        if (nd < dist[m]) {
          dist[m] = nd;
          queue.push({nd, m});
        }
      }
    }
    return std::numeric_limits<double>::infinity();
  };
  auto capillary_ok = [&](int64_t a, int64_t v) {
    const V d = unit(sub(nodes[v], nodes[a]));
    const double len = norm(sub(nodes[v], nodes[a]));
    return angle_ok(a, d) && angle_ok(v, mul(d, -1.0)) && len + path_length(a, v, min_loop) >= min_loop &&
           free_path(nodes[a], nodes[v], o.min_radius, a, v);
  };

  struct Tip {
    int64_t node;
    V dir;
    double radius;
    int tree;
  };
  std::deque<Tip> tips;
  const int arteries = std::max(1, o.roots / 2), veins = std::max(1, o.roots - o.roots / 2);
  for (int i = 0; i < arteries + veins; ++i) {
    const bool artery = i < arteries;
    const int k = artery ? i : i - arteries;
    const int count = artery ? arteries : veins;
    // Roots on the x = 0 face (arteries) and x = max face (veins), spread in y.
    const double y = ny * (k + 0.5) / count + (rnd() - 0.5) * 0.1 * ny;
    const double z = nz * (0.35 + 0.3 * rnd());
    V p{artery ? 0.0 : nx - 1.0, std::clamp(y, o.root_radius + 3, ny - o.root_radius - 4), z};
    nodes.push_back(p);
    kind.push_back(0);
    tips.push_back({static_cast<int64_t>(nodes.size()) - 1, V{artery ? 1.0 : -1.0, 0, 0}, o.root_radius, artery ? 0 : 1});
  }
  std::vector<int64_t> ends_a, ends_v;
  while (!tips.empty()) {
    Tip t = tips.front();
    tips.pop_front();
    const V a = nodes[t.node];
    bool placed = false;
    for (int attempt = 0; attempt < 8 && !placed; ++attempt) {
      // Length ~ 7 radii (at least 10 voxels), direction perturbed more on later attempts.
      const double len = std::max(10.0, 5.0 * t.radius) * scale * (0.8 + 0.4 * rnd());
      V jitter{rnd() - 0.5, rnd() - 0.5, rnd() - 0.5};
      const V dir = unit(add(t.dir, mul(jitter, 0.3 + 0.3 * attempt)));
      const V b = add(a, mul(dir, len));
      const bool root_segment = kind[t.node] == 0;
      if (!inside(b, t.radius)) continue;
      if (!free_path(root_segment ? add(a, mul(dir, t.radius + 2)) : a, b, t.radius, t.node, -1)) continue;
      nodes.push_back(b);
      kind.push_back(1);
      const int64_t nb = static_cast<int64_t>(nodes.size()) - 1;
      segs.push_back({t.node, nb, t.radius, t.tree});
      placed = true;
      const double child_r = t.radius * 0.79;
      if (child_r < o.min_radius) {
        kind[nb] = 2;
        (t.tree == 0 ? ends_a : ends_v).push_back(nb);
        break;
      }
      // Two children at 25–45 degrees either side, in a random plane through dir.
      V perp = unit(cross(dir, V{rnd() - 0.5, rnd() - 0.5, rnd() - 0.5}));
      const double ang = (25.0 + 20.0 * rnd()) * 3.14159265358979 / 180.0;
      for (int side = -1; side <= 1; side += 2) {
        const V cd = unit(add(mul(dir, std::cos(ang)), mul(perp, side * std::sin(ang))));
        tips.push_back({nb, cd, std::max(child_r, o.min_radius), t.tree});
      }
    }
    if (!placed && kind[t.node] != 0) {
      // No room to grow: this node ends here (a branch node with one child is a plain joint).
      int deg = 0;
      for (const auto& s : segs) deg += (s.n0 == t.node) + (s.n1 == t.node);
      if (deg == 1) {
        kind[t.node] = 2;
        (t.tree == 0 ? ends_a : ends_v).push_back(t.node);
      }
    }
    o.interrupter.check();
  }
  // Capillaries: each arterial end to the nearest reachable venous end (then to a second, closing
  // more loops); each end takes at most two capillaries.
  std::vector<int> used(nodes.size(), 0);
  for (int round = 0; round < 2; ++round)
    for (int64_t a : ends_a) {
      if (used[a] >= 2) continue;
      std::vector<std::pair<double, int64_t>> cand;
      for (int64_t v : ends_v)
        if (used[v] < 2) cand.push_back({norm(sub(nodes[a], nodes[v])), v});
      for (int64_t a2 : ends_a)
        if (a2 != a && used[a2] < 1 && round == 1) cand.push_back({norm(sub(nodes[a], nodes[a2])) * 1.5, a2});
      std::sort(cand.begin(), cand.end());
      for (const auto& [d, v] : cand) {
        if (d > capillary_length) break;
        bool exists = false;
        for (const auto& s : segs) exists = exists || (s.n0 == a && s.n1 == v) || (s.n0 == v && s.n1 == a);
        if (exists) continue;
        if (!capillary_ok(a, v)) continue;
        segs.push_back({a, v, o.min_radius, 2});
        ++used[a];
        ++used[v];
        break;
      }
    }
  // Join what is still disconnected (a tree no capillary reached): capillaries between ends of
  // different components, allowing longer ones step by step.
  auto components = [&]() {
    UnionFind uf(static_cast<int64_t>(nodes.size()));
    for (const auto& s : segs) uf.unite(s.n0, s.n1);
    std::vector<int64_t> comp(nodes.size());
    for (size_t i = 0; i < comp.size(); ++i) comp[i] = uf.find(static_cast<int64_t>(i));
    return comp;
  };
  for (double reach = capillary_length; reach <= 4 * capillary_length; reach *= 1.5) {
    auto comp = components();
    std::vector<int64_t> ends;
    for (int64_t e : ends_a) ends.push_back(e);
    for (int64_t e : ends_v) ends.push_back(e);
    bool joined = false;
    for (int64_t a : ends) {
      comp = components();
      double best = reach;
      int64_t bv = -1;
      for (int64_t v : ends)
        if (comp[v] != comp[a] && used[v] < 3 && used[a] < 3) {
          const double d = norm(sub(nodes[a], nodes[v]));
          if (d < best && capillary_ok(a, v)) {
            best = d;
            bv = v;
          }
        }
      if (bv >= 0) {
        segs.push_back({a, bv, o.min_radius, 2});
        ++used[a];
        ++used[bv];
        joined = true;
      }
    }
    comp = components();
    bool single = true;
    for (size_t n = 0; n < nodes.size(); ++n) single = single && comp[n] == comp[0];
    if (single) break;
    (void)joined;
  }
  // Node kinds after capillaries: degree 1 ends, degree >= 3 branches, degree 2 capillary joints.
  std::vector<int> degree(nodes.size(), 0);
  for (const auto& s : segs) {
    ++degree[s.n0];
    ++degree[s.n1];
  }
  for (size_t n = 0; n < nodes.size(); ++n) {
    if (kind[n] == 0) continue;
    kind[n] = degree[n] >= 3 ? 1 : degree[n] == 1 ? 2 : 3;
  }

  VesselTreeResult res;
  // Ground truth in physical units.
  auto phys = [&](V p) { return grid.position(p[0], p[1], p[2]); };
  const double mean_spacing = (o.spacing[0] + o.spacing[1] + o.spacing[2]) / 3.0;
  for (const auto& p : nodes) res.truth.add_node(phys(p));
  auto& kinds = res.truth.ensure_node_label("kind");
  for (size_t n = 0; n < nodes.size(); ++n) kinds[n] = kind[n];
  for (const auto& s : segs) res.truth.add_edge(s.n0, s.n1);
  auto& rad = res.truth.ensure_point_attribute("radius");
  auto& tree = res.truth.ensure_edge_label("tree");
  for (size_t e = 0; e < segs.size(); ++e) {
    std::fill(rad[e].begin(), rad[e].end(), static_cast<float>(segs[e].radius * mean_spacing));
    tree[e] = segs[e].tree;
  }
  res.truth.source_grid = grid;
  res.truth.unit = grid.unit;
  {
    std::vector<int64_t> id, deg;
    std::vector<std::string> k;
    std::vector<double> x, y, z;
    for (size_t n = 0; n < nodes.size(); ++n) {
      id.push_back(static_cast<int64_t>(n));
      const Vec3 p = phys(nodes[n]);
      x.push_back(p[0]);
      y.push_back(p[1]);
      z.push_back(p[2]);
      static const char* const kind_names[] = {"root", "branch", "end", "junction"};
      k.push_back(kind_names[kind[n]]);
      deg.push_back(degree[n]);
    }
    res.nodes.add("id", id).add("x", x, grid.unit).add("y", y, grid.unit).add("z", z, grid.unit).add("kind", k).add("degree", deg);
    std::vector<int64_t> eid, n0, n1;
    std::vector<std::string> tr;
    std::vector<double> len, r;
    for (size_t e = 0; e < segs.size(); ++e) {
      eid.push_back(static_cast<int64_t>(e));
      n0.push_back(segs[e].n0);
      n1.push_back(segs[e].n1);
      len.push_back(res.truth.edge_length(static_cast<int64_t>(e)));
      r.push_back(segs[e].radius * mean_spacing);
      static const char* const tree_names[] = {"artery", "vein", "capillary"};
      tr.push_back(tree_names[segs[e].tree]);
    }
    for (size_t n = 0; n < nodes.size(); ++n) {
      res.branch_points += degree[n] >= 3;
      res.end_points += degree[n] == 1;
    }
    for (double l : len) res.total_length += l;
    res.edges.add("id", eid).add("node0", n0).add("node1", n1).add("length", len, grid.unit).add("radius", r, grid.unit).add("tree", tr);
  }

  // Rasterise: signed distance to the union of the capsules (and of a ball at every node with the
  // largest radius of its vessels, which fills the crotch of shallow junctions), then a smooth
  // profile 0.5·(1 − tanh(d / sigma)). Parallel over fixed z-chunks: each voxel is written by one
  // chunk, so the result does not depend on the thread count.
  // Each node's star (its incident vessels, smooth-min blended), and the plain minimum over stars.
  std::vector<std::vector<int64_t>> star(nodes.size());
  for (size_t e = 0; e < segs.size(); ++e) {
    star[segs[e].n0].push_back(static_cast<int64_t>(e));
    if (segs[e].n1 != segs[e].n0) star[segs[e].n1].push_back(static_cast<int64_t>(e));
  }
  struct Box {
    int64_t lo[3], hi[3];
  };
  std::vector<Box> boxes(nodes.size());
  const int64_t NX = o.size[0], NY = o.size[1], NZ = o.size[2];
  const int64_t dims[3] = {NX, NY, NZ};
  for (size_t n = 0; n < nodes.size(); ++n) {
    Box& bx = boxes[n];
    for (int k = 0; k < 3; ++k) {
      bx.lo[k] = dims[k];
      bx.hi[k] = -1;
    }
    for (int64_t e : star[n]) {
      const V a = nodes[segs[e].n0], b = nodes[segs[e].n1];
      const double m = segs[e].radius + 3.0 * o.sigma + 1.0;
      for (int k = 0; k < 3; ++k) {
        bx.lo[k] = std::min(bx.lo[k], std::max<int64_t>(0, static_cast<int64_t>(std::floor(std::min(a[k], b[k]) - m))));
        bx.hi[k] = std::max(bx.hi[k], std::min<int64_t>(dims[k] - 1, static_cast<int64_t>(std::ceil(std::max(a[k], b[k]) + m))));
      }
    }
  }
  res.image = VolumeF32(grid, std::numeric_limits<float>::infinity());
  VolumeF32& sd = res.image;
  const int64_t chunks = std::max<int64_t>(1, (NZ + 3) / 4);
  parallel_chunks(0, NZ, chunks, o.threads, [&](int64_t c, int64_t z0, int64_t z1) {
    for (size_t n = 0; n < nodes.size(); ++n) {
      if (star[n].empty()) continue;
      const Box& bx = boxes[n];
      for (int64_t z = std::max(bx.lo[2], z0); z <= std::min(bx.hi[2], z1 - 1); ++z)
        for (int64_t y = bx.lo[1]; y <= bx.hi[1]; ++y) {
          float* row = sd.data() + sd.index(0, y, z);
          for (int64_t x = bx.lo[0]; x <= bx.hi[0]; ++x) {
            const V p{static_cast<double>(x), static_cast<double>(y), static_cast<double>(z)};
            double d = std::numeric_limits<double>::infinity();
            for (int64_t e : star[n]) {
              const double de = point_segment(p, nodes[segs[e].n0], nodes[segs[e].n1]) - segs[e].radius;
              d = std::isfinite(d) ? smooth_min(d, de, kFillet) : de;
            }
            row[x] = std::min(row[x], static_cast<float>(d));
          }
        }
    }
    if (c % 16 == 0) o.interrupter.check(0.8 * static_cast<double>(z1) / static_cast<double>(NZ));
  });
  parallel_for(0, grid.voxel_count(), o.threads, [&](int64_t i0, int64_t i1) {
    for (int64_t i = i0; i < i1; ++i)
      sd[i] = std::isfinite(sd[i]) ? static_cast<float>(0.5 * (1.0 - std::tanh(sd[i] / o.sigma))) : 0.0f;
  }, 1 << 20);
  add_two_frequency_noise(sd, o.seed, o.noise, o.threads);
  res.mask = VolumeU8::uninitialized(grid);
  parallel_for(0, grid.voxel_count(), o.threads, [&](int64_t i0, int64_t i1) {
    for (int64_t i = i0; i < i1; ++i) res.mask[i] = sd[i] > 0.5f ? 1 : 0;
  }, 1 << 20);
  o.interrupter.check(1.0);
  return res;
}

}  // namespace skel::synthetic
