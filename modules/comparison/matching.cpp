// Minimum-cost maximum-cardinality bipartite matching (sparse successive shortest paths) and the
// matching of two spatial graphs (nodes, edges, length; NetMets-style errors).
#include <algorithm>
#include <atomic>
#include <cmath>
#include <limits>
#include <map>
#include <memory>
#include <numeric>
#include <queue>
#include <tuple>

#include "comparison/comparison.hpp"
#include "comparison/point_index.hpp"
#include "skel/error.hpp"
#include "skel/units.hpp"
#include "skel/parallel.hpp"
#include "skel/union_find.hpp"

namespace skel::comparison {

namespace {

constexpr double kInf = std::numeric_limits<double>::infinity();

// Successive shortest augmenting paths on one connected component. Local ids: left 0..L-1,
// right 0..R-1; adj[l] = (right, cost) in candidate order. Potentials keep reduced costs >= 0
// (Johnson); free left nodes are the sources (their potential stays 0), free right nodes lead to
// the sink with reduced cost pot[r] - pot_sink.
void solve_component(const std::vector<std::vector<std::pair<int64_t, double>>>& adj, int64_t R,
                     std::vector<int64_t>& match_l, std::vector<int64_t>& match_r) {
  const int64_t L = static_cast<int64_t>(adj.size());
  match_l.assign(static_cast<size_t>(L), -1);
  match_r.assign(static_cast<size_t>(R), -1);
  std::vector<double> pot_l(static_cast<size_t>(L), 0.0), pot_r(static_cast<size_t>(R), 0.0);
  double pot_sink = 0.0;
  std::vector<double> dist_l(static_cast<size_t>(L)), dist_r(static_cast<size_t>(R));
  std::vector<int64_t> prev_r(static_cast<size_t>(R));  // left node we came from
  std::vector<char> done_l(static_cast<size_t>(L)), done_r(static_cast<size_t>(R));
  // Heap entries: (distance, kind (0 left, 1 right), id); ties by kind then id: deterministic.
  using Entry = std::tuple<double, int, int64_t>;
  for (int64_t round = 0; round < std::min(L, R); ++round) {
    std::fill(dist_l.begin(), dist_l.end(), kInf);
    std::fill(dist_r.begin(), dist_r.end(), kInf);
    std::fill(done_l.begin(), done_l.end(), 0);
    std::fill(done_r.begin(), done_r.end(), 0);
    std::priority_queue<Entry, std::vector<Entry>, std::greater<>> heap;
    for (int64_t l = 0; l < L; ++l)
      if (match_l[static_cast<size_t>(l)] < 0) {
        dist_l[static_cast<size_t>(l)] = 0.0;
        heap.emplace(0.0, 0, l);
      }
    double best = kInf;
    int64_t best_r = -1;
    while (!heap.empty()) {
      const auto [d, kind, id] = heap.top();
      heap.pop();
      if (d >= best) break;  // the sink is settled: nothing can beat it
      if (kind == 0) {
        if (done_l[static_cast<size_t>(id)]) continue;
        done_l[static_cast<size_t>(id)] = 1;
        for (const auto& [r, c] : adj[static_cast<size_t>(id)]) {
          if (match_l[static_cast<size_t>(id)] == r) continue;  // matched edge: only usable backwards
          const double rc = std::max(0.0, c + pot_l[static_cast<size_t>(id)] - pot_r[static_cast<size_t>(r)]);
          if (d + rc < dist_r[static_cast<size_t>(r)]) {
            dist_r[static_cast<size_t>(r)] = d + rc;
            prev_r[static_cast<size_t>(r)] = id;
            heap.emplace(d + rc, 1, r);
          }
        }
      } else {
        if (done_r[static_cast<size_t>(id)]) continue;
        done_r[static_cast<size_t>(id)] = 1;
        const int64_t l2 = match_r[static_cast<size_t>(id)];
        if (l2 < 0) {
          const double to_sink = d + std::max(0.0, pot_r[static_cast<size_t>(id)] - pot_sink);
          if (to_sink < best) {
            best = to_sink;
            best_r = id;
          }
        } else if (d < dist_l[static_cast<size_t>(l2)]) {  // matched edge backwards, reduced cost 0
          dist_l[static_cast<size_t>(l2)] = d;
          heap.emplace(d, 0, l2);
        }
      }
    }
    if (best_r < 0) break;  // no augmenting path: maximum cardinality reached
    // Potentials: + min(dist, best) keeps every residual reduced cost >= 0.
    for (int64_t l = 0; l < L; ++l) pot_l[static_cast<size_t>(l)] += std::min(dist_l[static_cast<size_t>(l)], best);
    for (int64_t r = 0; r < R; ++r) pot_r[static_cast<size_t>(r)] += std::min(dist_r[static_cast<size_t>(r)], best);
    pot_sink += best;
    // Augment along the path back from best_r.
    int64_t r = best_r;
    while (r >= 0) {
      const int64_t l = prev_r[static_cast<size_t>(r)];
      const int64_t next_r = match_l[static_cast<size_t>(l)];
      match_l[static_cast<size_t>(l)] = r;
      match_r[static_cast<size_t>(r)] = l;
      r = next_r;
    }
  }
}

struct Sampled {
  std::vector<Vec3> points;
  std::vector<double> weights;
  std::vector<int64_t> edge;     // edge id per sample
  std::vector<int64_t> offsets;  // samples of edge e: [offsets[e], offsets[e+1])
};

// Two parallel passes over the edges: sample counts (for the offsets), then each edge's samples
// written in place: no reallocation of the multi-million-sample arrays. resample_polyline is
// deterministic, so both passes see the same samples.
Sampled sample_graph(const SpatialGraph& g, double spacing, int threads) {
  Sampled s;
  const int64_t E = static_cast<int64_t>(g.edges.size());
  s.offsets.assign(static_cast<size_t>(E) + 1, 0);
  parallel_for(0, E, threads, [&](int64_t a, int64_t b) {
    std::vector<Vec3> p;
    std::vector<double> w;
    for (int64_t e = a; e < b; ++e) {
      resample_polyline(g.edges[static_cast<size_t>(e)].points, spacing, p, w);
      s.offsets[static_cast<size_t>(e) + 1] = static_cast<int64_t>(p.size());
    }
  }, 1024);
  for (int64_t e = 0; e < E; ++e) s.offsets[static_cast<size_t>(e) + 1] += s.offsets[static_cast<size_t>(e)];
  const auto total = static_cast<size_t>(s.offsets.back());
  s.points.resize(total);
  s.weights.resize(total);
  s.edge.resize(total);
  parallel_for(0, E, threads, [&](int64_t a, int64_t b) {
    std::vector<Vec3> p;
    std::vector<double> w;
    for (int64_t e = a; e < b; ++e) {
      resample_polyline(g.edges[static_cast<size_t>(e)].points, spacing, p, w);
      const auto o = static_cast<size_t>(s.offsets[static_cast<size_t>(e)]);
      std::copy(p.begin(), p.end(), s.points.begin() + static_cast<std::ptrdiff_t>(o));
      std::copy(w.begin(), w.end(), s.weights.begin() + static_cast<std::ptrdiff_t>(o));
      std::fill_n(s.edge.begin() + static_cast<std::ptrdiff_t>(o), p.size(), e);
    }
  }, 1024);
  return s;
}

// covered[i] = some sample of `index` lies within tol of sample i.
std::vector<char> coverage(const Sampled& s, const detail::PointIndex& index, double tol, int threads,
                           const Interrupter& intr) {
  std::vector<char> covered(s.points.size(), 0);
  const int64_t n = static_cast<int64_t>(s.points.size());
  const int64_t chunks = std::max<int64_t>(1, std::min<int64_t>(64, n / 4096 + 1));
  std::atomic<int64_t> done{0};
  parallel_chunks(0, n, chunks, threads, [&](int64_t, int64_t a, int64_t b) {
    for (int64_t i = a; i < b; ++i)
      covered[static_cast<size_t>(i)] = index.any_within(s.points[static_cast<size_t>(i)], tol) ? 1 : 0;
    intr.check(static_cast<double>(++done) / static_cast<double>(chunks));
  });
  return covered;
}

// Fraction of the samples of edge `e` (in `s`) that have a sample of edge `f` (in `t`) within tol.
// Direct comparison of the two edges' samples (a few dozen each): the same squared distance
// (summed over x, y, z in that order) and the same <= tol² test as PointIndex::within, so the result
// equals the k-d tree query filtered to edge f. Once so many samples are missed that the fraction
// cannot reach `overlap`, returns an upper bound that is < overlap (callers only compare it then).
double edge_coverage(const Sampled& s, int64_t e, const Sampled& t, int64_t f, double tol, double overlap) {
  const int64_t a = s.offsets[static_cast<size_t>(e)], b = s.offsets[static_cast<size_t>(e) + 1];
  const int64_t c = t.offsets[static_cast<size_t>(f)], d = t.offsets[static_cast<size_t>(f) + 1];
  if (b <= a) return 0.0;
  const double n = static_cast<double>(b - a), r2 = tol * tol;
  int64_t hit = 0, miss = 0;
  for (int64_t i = a; i < b; ++i) {
    const Vec3& p = s.points[static_cast<size_t>(i)];
    bool covered = false;
    for (int64_t j = c; j < d && !covered; ++j) {
      const Vec3& q = t.points[static_cast<size_t>(j)];
      const double dx = p[0] - q[0], dy = p[1] - q[1], dz = p[2] - q[2];
      covered = dx * dx + dy * dy + dz * dz <= r2;
    }
    if (covered) {
      ++hit;
    } else if (static_cast<double>(b - a - ++miss) / n < overlap) {
      return static_cast<double>(b - a - miss) / n;
    }
  }
  return static_cast<double>(hit) / n;
}

MatchCounts counts(double reference, double other, double tp, double fp, double fn) {
  MatchCounts c;
  c.reference = reference;
  c.other = other;
  c.tp = tp;
  c.fp = fp;
  c.fn = fn;
  c.precision = other > 0 ? (other - fp) / other : 1.0;
  c.recall = reference > 0 ? tp / reference : 1.0;
  c.f1 = c.precision + c.recall > 0 ? 2 * c.precision * c.recall / (c.precision + c.recall) : 0.0;
  return c;
}

void check_graph(const SpatialGraph& g, const std::string& port) {
  const auto problems = g.check_invariants();
  if (!problems.empty()) throw InputError(port + ": inconsistent graph: " + problems.front());
}

}  // namespace

std::vector<int64_t> min_cost_matching(int64_t n_left, int64_t n_right, const std::vector<AssignmentCandidate>& cands) {
  if (n_left < 0 || n_right < 0) throw Error("min_cost_matching: negative sizes");
  for (const auto& c : cands) {
    if (c.left < 0 || c.left >= n_left || c.right < 0 || c.right >= n_right)
      throw Error("min_cost_matching: candidate (" + std::to_string(c.left) + ", " + std::to_string(c.right) +
                  ") out of range");
    if (!(c.cost >= 0) || !std::isfinite(c.cost)) throw Error("min_cost_matching: costs must be finite and >= 0");
  }
  std::vector<int64_t> result(static_cast<size_t>(n_left), -1);
  // Components: union-find over left ids (0..n_left-1) and right ids (n_left..).
  UnionFind uf(n_left + n_right);
  for (const auto& c : cands) uf.unite(c.left, n_left + c.right);
  // Group candidates by component (in candidate order), map to local ids.
  std::map<int64_t, std::vector<size_t>> by_comp;
  for (size_t i = 0; i < cands.size(); ++i) by_comp[uf.find(cands[i].left)].push_back(i);
  std::vector<int64_t> local_l(static_cast<size_t>(n_left), -1), local_r(static_cast<size_t>(n_right), -1);
  std::vector<int64_t> global_l, global_r;
  std::vector<std::vector<std::pair<int64_t, double>>> adj;
  std::vector<int64_t> ml, mr;
  for (const auto& [root, ids] : by_comp) {
    global_l.clear();
    global_r.clear();
    adj.clear();
    for (size_t i : ids) {
      const auto& c = cands[i];
      if (local_l[static_cast<size_t>(c.left)] < 0) {
        local_l[static_cast<size_t>(c.left)] = static_cast<int64_t>(global_l.size());
        global_l.push_back(c.left);
        adj.emplace_back();
      }
      if (local_r[static_cast<size_t>(c.right)] < 0) {
        local_r[static_cast<size_t>(c.right)] = static_cast<int64_t>(global_r.size());
        global_r.push_back(c.right);
      }
      adj[static_cast<size_t>(local_l[static_cast<size_t>(c.left)])].emplace_back(local_r[static_cast<size_t>(c.right)],
                                                                                 c.cost);
    }
    solve_component(adj, static_cast<int64_t>(global_r.size()), ml, mr);
    for (size_t l = 0; l < global_l.size(); ++l)
      if (ml[l] >= 0) result[static_cast<size_t>(global_l[l])] = global_r[static_cast<size_t>(ml[l])];
  }
  return result;
}

GraphMatchResult graph_match(const SpatialGraph& reference, const SpatialGraph& other, const GraphMatchOptions& o) {
  if (!(o.node_tolerance >= 0)) throw InputError("node_tolerance: expected >= 0 (physical units)");
  if (!(o.edge_tolerance >= 0)) throw InputError("edge_tolerance: expected >= 0 (physical units)");
  if (!(o.sample_spacing > 0)) throw InputError("sample_spacing: expected > 0 (physical units)");
  if (!(o.overlap > 0 && o.overlap <= 1)) throw InputError("overlap: expected a fraction in (0, 1]");
  check_graph(reference, "reference");
  check_graph(other, "other");
  units::check_same(reference.unit, "input 'reference'", other.unit, "input 'other'");
  const Interrupter& intr = o.interrupter;
  const int th = o.threads;
  GraphMatchResult res;
  res.reference = reference;
  res.other = other;
  const int64_t NR = reference.node_count(), NO = other.node_count();
  const int64_t ER = reference.edge_count(), EO = other.edge_count();

  // 1. Nodes.
  std::vector<int64_t> node_match_r(static_cast<size_t>(NR), -1), node_match_o(static_cast<size_t>(NO), -1);
  {
    detail::PointIndex index(other.positions);
    std::vector<std::vector<AssignmentCandidate>> per(static_cast<size_t>(NR));
    parallel_for(0, NR, th, [&](int64_t a, int64_t b) {
      std::vector<std::pair<size_t, double>> scratch;
      std::vector<int64_t> found;
      for (int64_t n = a; n < b; ++n) {
        const Vec3& p = reference.positions[static_cast<size_t>(n)];
        index.within(p, o.node_tolerance, scratch, found);
        for (int64_t m : found) {
          const Vec3& q = other.positions[static_cast<size_t>(m)];
          const double d = std::sqrt((p[0] - q[0]) * (p[0] - q[0]) + (p[1] - q[1]) * (p[1] - q[1]) + (p[2] - q[2]) * (p[2] - q[2]));
          per[static_cast<size_t>(n)].push_back({n, m, d});
        }
      }
    }, 1024);
    std::vector<AssignmentCandidate> cands;
    for (auto& v : per) cands.insert(cands.end(), v.begin(), v.end());
    node_match_r = min_cost_matching(NR, NO, cands);
    for (int64_t n = 0; n < NR; ++n)
      if (node_match_r[static_cast<size_t>(n)] >= 0) node_match_o[static_cast<size_t>(node_match_r[static_cast<size_t>(n)])] = n;
  }
  intr.check(0.15);

  // 2. Samples and geometric coverage.
  const Sampled sr = sample_graph(reference, o.sample_spacing, th);
  const Sampled so = sample_graph(other, o.sample_spacing, th);
  // The two k-d trees are independent: built side by side when there are threads for it.
  std::unique_ptr<const detail::PointIndex> index_r, index_o;
  parallel_for(0, 2, th, [&](int64_t a, int64_t b) {
    for (int64_t k = a; k < b; ++k)
      (k == 0 ? index_r : index_o) = std::make_unique<const detail::PointIndex>(k == 0 ? sr.points : so.points);
  });
  const detail::PointIndex& ir = *index_r;
  const detail::PointIndex& io = *index_o;
  const std::vector<char> cov_r = coverage(sr, io, o.edge_tolerance, th, intr.sub(0.15, 0.35));
  const std::vector<char> cov_o = coverage(so, ir, o.edge_tolerance, th, intr.sub(0.35, 0.55));
  res.reference_samples = static_cast<int64_t>(sr.points.size());
  res.other_samples = static_cast<int64_t>(so.points.size());

  auto edge_cov = [](const Sampled& s, const std::vector<char>& cov, int64_t E) {
    std::vector<double> c(static_cast<size_t>(E), 0.0);
    for (int64_t e = 0; e < E; ++e) {
      const int64_t a = s.offsets[static_cast<size_t>(e)], b = s.offsets[static_cast<size_t>(e) + 1];
      int64_t h = 0;
      for (int64_t i = a; i < b; ++i) h += cov[static_cast<size_t>(i)];
      c[static_cast<size_t>(e)] = b > a ? static_cast<double>(h) / static_cast<double>(b - a) : 0.0;
    }
    return c;
  };
  const std::vector<double> ecov_r = edge_cov(sr, cov_r, ER), ecov_o = edge_cov(so, cov_o, EO);

  // 3. Edges: candidates share matched end nodes and overlap both ways.
  std::map<std::pair<int64_t, int64_t>, std::vector<int64_t>> other_by_nodes;
  for (int64_t f = 0; f < EO; ++f) {
    const auto& ed = other.edges[static_cast<size_t>(f)];
    other_by_nodes[{std::min(ed.node0, ed.node1), std::max(ed.node0, ed.node1)}].push_back(f);
  }
  std::vector<std::vector<AssignmentCandidate>> per_edge(static_cast<size_t>(ER));
  std::atomic<int64_t> done{0};
  const int64_t chunks = std::max<int64_t>(1, std::min<int64_t>(64, ER / 1024 + 1));
  parallel_chunks(0, ER, chunks, th, [&](int64_t, int64_t a, int64_t b) {
    for (int64_t e = a; e < b; ++e) {
      const auto& ed = reference.edges[static_cast<size_t>(e)];
      const int64_t m0 = node_match_r[static_cast<size_t>(ed.node0)], m1 = node_match_r[static_cast<size_t>(ed.node1)];
      if (m0 < 0 || m1 < 0) continue;
      auto it = other_by_nodes.find({std::min(m0, m1), std::max(m0, m1)});
      if (it == other_by_nodes.end()) continue;
      for (int64_t f : it->second) {
        const double c1 = edge_coverage(sr, e, so, f, o.edge_tolerance, o.overlap);
        if (c1 < o.overlap) continue;
        const double c2 = edge_coverage(so, f, sr, e, o.edge_tolerance, o.overlap);
        if (c2 < o.overlap) continue;
        per_edge[static_cast<size_t>(e)].push_back({e, f, std::max(0.0, 2.0 - c1 - c2)});
      }
    }
    intr.sub(0.55, 0.95).check(static_cast<double>(++done) / static_cast<double>(chunks));
  });
  std::vector<AssignmentCandidate> ecands;
  for (auto& v : per_edge) ecands.insert(ecands.end(), v.begin(), v.end());
  const std::vector<int64_t> edge_match_r = min_cost_matching(ER, EO, ecands);
  std::vector<int64_t> edge_match_o(static_cast<size_t>(EO), -1);
  for (int64_t e = 0; e < ER; ++e)
    if (edge_match_r[static_cast<size_t>(e)] >= 0) edge_match_o[static_cast<size_t>(edge_match_r[static_cast<size_t>(e)])] = e;

  // 4. Scores.
  int64_t node_tp = 0, edge_tp = 0;
  for (auto m : node_match_r) node_tp += m >= 0;
  for (auto m : edge_match_r) edge_tp += m >= 0;
  res.nodes = counts(static_cast<double>(NR), static_cast<double>(NO), static_cast<double>(node_tp),
                     static_cast<double>(NO - node_tp), static_cast<double>(NR - node_tp));
  res.edges = counts(static_cast<double>(ER), static_cast<double>(EO), static_cast<double>(edge_tp),
                     static_cast<double>(EO - edge_tp), static_cast<double>(ER - edge_tp));
  double len_r = 0, len_o = 0, cov_len_r = 0, cov_len_o = 0;
  for (size_t i = 0; i < sr.points.size(); ++i) {
    len_r += sr.weights[i];
    if (cov_r[i]) cov_len_r += sr.weights[i];
  }
  for (size_t i = 0; i < so.points.size(); ++i) {
    len_o += so.weights[i];
    if (cov_o[i]) cov_len_o += so.weights[i];
  }
  res.length = counts(len_r, len_o, cov_len_r, len_o - cov_len_o, len_r - cov_len_r);
  res.geometric_fnr = len_r > 0 ? (len_r - cov_len_r) / len_r : 0.0;
  res.geometric_fpr = len_o > 0 ? (len_o - cov_len_o) / len_o : 0.0;
  auto conn = [&](const std::vector<double>& ecov, const std::vector<int64_t>& match) {
    int64_t found = 0, wrong = 0;
    for (size_t e = 0; e < ecov.size(); ++e)
      if (ecov[e] >= o.overlap) {
        ++found;
        wrong += match[e] < 0;
      }
    return found > 0 ? static_cast<double>(wrong) / static_cast<double>(found) : 0.0;
  };
  res.connectivity_fnr = conn(ecov_r, edge_match_r);
  res.connectivity_fpr = conn(ecov_o, edge_match_o);

  // 5. Attributes on the output copies.
  auto mark = [&](SpatialGraph& g, const std::vector<int64_t>& nm, const std::vector<int64_t>& em,
                  const std::vector<double>& ecov, const detail::PointIndex& other_index, double tol) {
    auto& nmatched = g.ensure_node_label("matched");
    auto& nmatch = g.ensure_node_label("match", -1);
    for (size_t n = 0; n < nm.size(); ++n) {
      nmatched[n] = nm[n] >= 0 ? 1 : 0;
      nmatch[n] = static_cast<int32_t>(nm[n]);
    }
    auto& ematched = g.ensure_edge_label("matched");
    auto& ematch = g.ensure_edge_label("match", -1);
    auto& ecoverage = g.ensure_edge_attribute("coverage");
    for (size_t e = 0; e < em.size(); ++e) {
      ematched[e] = em[e] >= 0 ? 1 : 0;
      ematch[e] = static_cast<int32_t>(em[e]);
      ecoverage[e] = static_cast<float>(ecov[e]);
    }
    auto& pcovered = g.ensure_point_attribute("covered");
    parallel_for(0, static_cast<int64_t>(g.edges.size()), th, [&](int64_t a, int64_t b) {
      for (int64_t e = a; e < b; ++e) {
        const auto& pts = g.edges[static_cast<size_t>(e)].points;
        for (size_t i = 0; i < pts.size(); ++i)
          pcovered[static_cast<size_t>(e)][i] = other_index.any_within(pts[i], tol) ? 1.0f : 0.0f;
      }
    }, 256);
  };
  mark(res.reference, node_match_r, edge_match_r, ecov_r, io, o.edge_tolerance);
  mark(res.other, node_match_o, edge_match_o, ecov_o, ir, o.edge_tolerance);

  res.table.add("level", std::vector<std::string>{"nodes", "edges", "length"});
  const MatchCounts* rows[3] = {&res.nodes, &res.edges, &res.length};
  auto col = [&](double MatchCounts::*m) {
    std::vector<double> v;
    for (const MatchCounts* r : rows) v.push_back(r->*m);
    return v;
  };
  res.table.add("reference", col(&MatchCounts::reference))
      .add("other", col(&MatchCounts::other))
      .add("tp", col(&MatchCounts::tp))
      .add("fp", col(&MatchCounts::fp))
      .add("fn", col(&MatchCounts::fn))
      .add("precision", col(&MatchCounts::precision))
      .add("recall", col(&MatchCounts::recall))
      .add("f1", col(&MatchCounts::f1));
  res.errors.add("geometric_fnr", std::vector<double>{res.geometric_fnr})
      .add("geometric_fpr", std::vector<double>{res.geometric_fpr})
      .add("connectivity_fnr", std::vector<double>{res.connectivity_fnr})
      .add("connectivity_fpr", std::vector<double>{res.connectivity_fpr})
      .add("reference_length", std::vector<double>{len_r}, reference.unit)
      .add("other_length", std::vector<double>{len_o}, reference.unit)
      .add("reference_samples", std::vector<int64_t>{res.reference_samples})
      .add("other_samples", std::vector<int64_t>{res.other_samples});
  intr.check(1.0);
  return res;
}

}  // namespace skel::comparison
