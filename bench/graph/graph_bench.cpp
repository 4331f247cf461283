// Benchmark: geometry.skeleton_to_graph + analysis.network_statistics on a synthetic skeleton of
// random 26-connected line segments (n³ grid), vs a SciPy pixel-graph peer on the same .npy volume.
// Usage: bench_graph WORK_DIR n [segments]  -> prints markdown rows; writes WORK_DIR/skeleton.npy.
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <random>
#include <string>

#include "common/bench_util.hpp"
#include "analysis/network_analysis.hpp"
#include "geometry/skeleton_to_graph.hpp"

using namespace skel::analysis;
using namespace skel::geometry;

using namespace skel;

int main(int argc, char** argv) {
  if (argc < 3) {
    std::fprintf(stderr, "usage: bench_graph WORK_DIR n [segments]\n");
    return 2;
  }
  const std::string work = argv[1];
  const int64_t n = std::stoll(argv[2]);
  const int64_t segments = argc > 3 ? std::stoll(argv[3]) : n * n / 12;
  VolumeU8 v({n, n, n}, 0);
  std::mt19937_64 rng(42);
  std::uniform_int_distribution<int64_t> pos(0, n - 1), len(8, 64), dir(-1000, 1000);
  for (int64_t s = 0; s < segments; ++s) {
    int64_t a[3], b[3];
    double d[3], norm = 0.0;
    for (int k = 0; k < 3; ++k) {
      a[k] = pos(rng);
      d[k] = static_cast<double>(dir(rng));
      norm += d[k] * d[k];
    }
    const double l = static_cast<double>(len(rng)) / std::sqrt(std::max(norm, 1.0));
    int64_t steps = 0;
    for (int k = 0; k < 3; ++k) {
      b[k] = std::clamp<int64_t>(a[k] + std::llround(d[k] * l), 0, n - 1);
      steps = std::max<int64_t>(steps, std::llabs(b[k] - a[k]));
    }
    for (int64_t t = 0; t <= steps; ++t) {
      int64_t p[3];
      for (int k = 0; k < 3; ++k)
        p[k] = a[k] + (steps ? std::llround(static_cast<double>((b[k] - a[k]) * t) / static_cast<double>(steps)) : 0);
      v(p[0], p[1], p[2]) = 1;
    }
  }
  int64_t vox = 0;
  for (auto x : v) vox += x;
  bench::write_npy(work + "/skeleton.npy", v);
  const double rss0 = bench::peak_rss_mib();
  for (int threads : {1, 2}) {
    SpatialGraph g;
    const double t_graph = bench::best_of(1, [&] {
      SkeletonToGraphOptions o;
      o.threads = threads;
      g = skeleton_to_graph(v, nullptr, o).graph;
    });
    const double rss_graph = bench::peak_rss_mib();
    NetworkStatistics st;
    const double t_stats = bench::best_of(1, [&] { st = network_statistics(g); });
    std::printf("| %lld³ | %d | %lld | %lld | %lld | %lld | %.3f | %.1f | %.3f | %.0f (%.0f after generating the volume) |\n",
                static_cast<long long>(n), threads, static_cast<long long>(vox),
                static_cast<long long>(g.node_count()), static_cast<long long>(g.edge_count()),
                static_cast<long long>(st.summary.ints("branch_points")[0]), t_graph,
                static_cast<double>(v.size()) / t_graph / 1e6, t_stats, rss_graph, rss0);
  }
  return 0;
}
