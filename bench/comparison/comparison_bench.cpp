// Benchmark of the comparison family (issue 9): comparison::skeleton_distance on an n³ skeleton pair
// and comparison::graph_match on a ~100k-edge graph against a perturbed copy. Each measurement runs
// in its own process so that its peak RSS is its own.
//
//   bench_comparison make_skeletons WORK_DIR n            writes WORK_DIR/reference.npy, other.npy
//   bench_comparison distance WORK_DIR transform|kdtree THREADS    -> one markdown row
//   bench_comparison match m k j THREADS                   -> one markdown row (m³ lattice nodes)
//
// Skeletons: random 26-connected line segments (8–64 voxels, n²/12 of them, as bench/graph); the other
// skeleton is the same segments shifted by one voxel in x, with 10 % of the segments left out (they
// "vanished"). Graph: an m × m × m lattice of nodes 10 µm apart, edges to the +x/+y/+z neighbours
// with three jittered interior points; the copy has k random edges deleted and j edges added (bent
// face diagonals, half of them to a new node), so the exact answer is k false negatives and j false
// positives, which the row checks.
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <random>
#include <string>

#include "common/bench_util.hpp"
#include "comparison/comparison.hpp"
#include "thinning/npy_read.hpp"

using namespace skel;

namespace {

void draw_segments(VolumeU8& ref, VolumeU8& other, int64_t n, int64_t segments) {
  std::mt19937_64 rng(42);
  std::uniform_int_distribution<int64_t> pos(0, n - 1), len(8, 64), dir(-1000, 1000), drop(0, 9);
  for (int64_t s = 0; s < segments; ++s) {
    int64_t a[3], b[3];
    double d[3], norm = 0.0;
    for (int k = 0; k < 3; ++k) {
      a[k] = pos(rng);
      d[k] = static_cast<double>(dir(rng));
      norm += d[k] * d[k];
    }
    const double l = static_cast<double>(len(rng)) / std::sqrt(std::max(norm, 1.0));
    const bool vanished = drop(rng) == 0;
    int64_t steps = 0;
    for (int k = 0; k < 3; ++k) {
      b[k] = std::clamp<int64_t>(a[k] + std::llround(d[k] * l), 0, n - 1);
      steps = std::max<int64_t>(steps, std::llabs(b[k] - a[k]));
    }
    for (int64_t t = 0; t <= steps; ++t) {
      int64_t p[3];
      for (int k = 0; k < 3; ++k)
        p[k] = a[k] + (steps ? std::llround(static_cast<double>((b[k] - a[k]) * t) / static_cast<double>(steps)) : 0);
      ref(p[0], p[1], p[2]) = 1;
      if (!vanished && p[0] + 1 < n) other(p[0] + 1, p[1], p[2]) = 1;
    }
  }
}

int make_skeletons(const std::string& work, int64_t n) {
  VolumeU8 ref({n, n, n}, 0), other({n, n, n}, 0);
  draw_segments(ref, other, n, n * n / 12);
  bench::write_npy(work + "/reference.npy", ref);
  bench::write_npy(work + "/other.npy", other);
  return 0;
}

int distance(const std::string& work, const std::string& method, int threads) {
  const VolumeU8 ref = bench::read_npy_u8(work + "/reference.npy");
  const VolumeU8 other = bench::read_npy_u8(work + "/other.npy");
  const double rss_inputs = bench::peak_rss_mib();
  comparison::SkeletonDistanceOptions o;
  o.threshold = 2.0;
  o.method = comparison::parse_distance_method(method);
  o.threads = threads;
  comparison::SkeletonInput a, b;
  a.volume = &ref;
  b.volume = &other;
  b.name = "other";
  comparison::SkeletonDistanceResult r;
  const double t = bench::best_of(1, [&] { r = comparison::skeleton_distance(a, b, o); });
  const auto& s = r.reference.stats;
  std::printf("| Skelflow skeleton_distance (%s) | %lld³ | %d | %lld | %.3f | %.1f | %.4f | %lld | %.0f (%.0f inputs) |\n",
              method.c_str(), static_cast<long long>(ref.nx()), threads, static_cast<long long>(s.points), t,
              static_cast<double>(ref.size()) / t / 1e6, s.mean, static_cast<long long>(s.changed_points),
              bench::peak_rss_mib(), rss_inputs);
  return 0;
}

SpatialGraph lattice(int m) {
  std::mt19937 rng(7);
  auto jitter = [&] { return (static_cast<double>(rng() % 1000) / 1000.0 - 0.5) * 1.0; };
  SpatialGraph g;
  auto id = [&](int i, int j, int k) { return static_cast<int64_t>(i) + m * (static_cast<int64_t>(j) + static_cast<int64_t>(m) * k); };
  for (int k = 0; k < m; ++k)
    for (int j = 0; j < m; ++j)
      for (int i = 0; i < m; ++i) g.add_node({10.0 * i, 10.0 * j, 10.0 * k});
  for (int k = 0; k < m; ++k)
    for (int j = 0; j < m; ++j)
      for (int i = 0; i < m; ++i)
        for (int a = 0; a < 3; ++a) {
          const int i2 = i + (a == 0), j2 = j + (a == 1), k2 = k + (a == 2);
          if (i2 >= m || j2 >= m || k2 >= m) continue;
          const Vec3 p = g.positions[static_cast<size_t>(id(i, j, k))], q = g.positions[static_cast<size_t>(id(i2, j2, k2))];
          std::vector<Vec3> pts{p};
          for (int s = 1; s <= 3; ++s) {
            const double t = s / 4.0;
            pts.push_back({p[0] + t * (q[0] - p[0]) + jitter(), p[1] + t * (q[1] - p[1]) + jitter(),
                           p[2] + t * (q[2] - p[2]) + jitter()});
          }
          pts.push_back(q);
          g.add_edge(id(i, j, k), id(i2, j2, k2), std::move(pts));
        }
  return g;
}

int match(int m, int64_t k, int64_t j, int threads) {
  const SpatialGraph g = lattice(m);
  SpatialGraph h = g;
  std::mt19937_64 rng(11);
  std::vector<uint8_t> gone(static_cast<size_t>(g.edge_count()), 0);
  std::vector<int64_t> del;
  while (static_cast<int64_t>(del.size()) < k) {
    const int64_t e = static_cast<int64_t>(rng() % static_cast<uint64_t>(g.edge_count()));
    if (!gone[static_cast<size_t>(e)]) {
      gone[static_cast<size_t>(e)] = 1;
      del.push_back(e);
    }
  }
  h.remove_edges(del);
  // Added: face diagonals in the xy plane (never an existing node pair), bent 3 µm out of the plane;
  // every second one ends at a new node in the middle of the face.
  std::vector<uint8_t> used(static_cast<size_t>(g.node_count()), 0);
  for (int64_t a = 0; a < j;) {
    const int i = static_cast<int>(rng() % static_cast<uint64_t>(m - 1)), jj = static_cast<int>(rng() % static_cast<uint64_t>(m - 1)),
              kk = static_cast<int>(rng() % static_cast<uint64_t>(m));
    const int64_t n0 = i + static_cast<int64_t>(m) * (jj + static_cast<int64_t>(m) * kk);
    if (used[static_cast<size_t>(n0)]) continue;  // one added edge per face: no two added edges overlap
    used[static_cast<size_t>(n0)] = 1;
    int64_t end = (i + 1) + static_cast<int64_t>(m) * ((jj + 1) + static_cast<int64_t>(m) * kk);
    if (a % 2) end = h.add_node({10.0 * i + 5, 10.0 * jj + 5, 10.0 * kk + 4.5});
    const Vec3 p = h.positions[static_cast<size_t>(n0)], q = h.positions[static_cast<size_t>(end)];
    h.add_edge(n0, end, {p, {0.5 * (p[0] + q[0]), 0.5 * (p[1] + q[1]), 0.5 * (p[2] + q[2]) + 3.0}, q});
    ++a;
  }
  const double rss_inputs = bench::peak_rss_mib();
  comparison::GraphMatchOptions o;
  o.node_tolerance = 2.0;
  o.edge_tolerance = 1.5;
  o.sample_spacing = 0.5;
  o.overlap = 0.8;
  o.threads = threads;
  comparison::GraphMatchResult r;
  const double t = bench::best_of(1, [&] { r = comparison::graph_match(g, h, o); });
  const bool exact = r.edges.fn == static_cast<double>(k) && r.edges.fp == static_cast<double>(j);
  std::printf("| %lld | %lld | %lld | %lld | %d | %lld | %.0f | %.0f | %s | %.3f | %.0f (%.0f inputs) |\n",
              static_cast<long long>(g.node_count()), static_cast<long long>(g.edge_count()), static_cast<long long>(k),
              static_cast<long long>(j), threads, static_cast<long long>(r.reference_samples + r.other_samples), r.edges.fn,
              r.edges.fp, exact ? "yes" : "NO", t, bench::peak_rss_mib(), rss_inputs);
  return exact ? 0 : 1;
}

}  // namespace

int main(int argc, char** argv) {
  try {
    const std::string mode = argc > 1 ? argv[1] : "";
    if (mode == "make_skeletons" && argc == 4) return make_skeletons(argv[2], std::stoll(argv[3]));
    if (mode == "distance" && argc == 5) return distance(argv[2], argv[3], std::stoi(argv[4]));
    if (mode == "match" && argc == 6) return match(std::stoi(argv[2]), std::stoll(argv[3]), std::stoll(argv[4]), std::stoi(argv[5]));
  } catch (const std::exception& e) {
    std::fprintf(stderr, "bench_comparison: %s\n", e.what());
    return 1;
  }
  std::fprintf(stderr,
               "usage: bench_comparison make_skeletons WORK_DIR n | distance WORK_DIR transform|kdtree THREADS | "
               "match m k j THREADS\n");
  return 2;
}
