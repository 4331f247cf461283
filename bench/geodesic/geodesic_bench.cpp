// Geodesic boundary distance: time against the threshold t and against size on plates and mixed
// phantoms, memory per object voxel, and the project's own Euclidean DT on the same volume as the
// yardstick (there is no external implementation of this measure to compare with).
#include <cstdio>
#include <cstdlib>
#include <string>
#include <vector>

#include "common/bench_util.hpp"
#include "distance/distance.hpp"
#include "geodesic/geodesic.hpp"
#include "synthetic/network.hpp"

using namespace skel;

int main(int argc, char** argv) {
  const int threads = argc > 1 ? std::atoi(argv[1]) : 2;
  const bool big = argc > 2 && std::string(argv[2]) == "big";
  // Optional third argument: the thresholds to run, comma-separated (default 20,40,80), for quick
  // before/after comparisons.
  std::vector<int64_t> thresholds = {20, 40, 80};
  if (argc > 3) {
    thresholds.clear();
    for (const char* p = argv[3]; *p;) {
      char* e = nullptr;
      const long long t = std::strtoll(p, &e, 10);
      if (e == p || t < 1) {
        std::fprintf(stderr, "bench_geodesic: thresholds must be positive integers, e.g. 20,40\n");
        return 2;
      }
      thresholds.push_back(t);
      p = *e == ',' ? e + 1 : e;
    }
  }
  std::printf("## Geodesic boundary distance\n\n");
  std::printf("Threshold mode, %d threads. Yardstick: `distance.euclidean` (exact EDT) on the same mask in the same run. "
              "k = object voxels, |L| = boundary-layer voxels; searches = breadth-first searches run (one per base point, "
              "plus pivots), of them pivots and long (own searches that ran to t); bytes/k = working memory of the algorithm per object voxel (mask and outputs excluded).\n\n", threads);
  std::printf("| phantom | size | t | object %% | time (s) | EDT (s) | time / EDT | |L| / k | searches | pivots | long | visited / k | bytes / k |\n");
  std::printf("|---|---|---|---|---|---|---|---|---|---|---|---|---|\n");
  for (const char* shape : {"plates", "mixed"}) {
    std::vector<int64_t> sizes = {256};
    if (big) sizes.push_back(512);
    for (int64_t n : sizes) {
      synthetic::NetworkOptions no;
      no.shape = parse_enum<synthetic::Shape>(shape, "shape");
      no.size = {n, n, n};
      no.threads = threads;
      auto ph = synthetic::make_network(no);
      int64_t k = 0;
      for (auto v : ph.mask) k += v;
      distance::EuclideanOptions eo;
      eo.threads = threads;
      const double edt = bench::best_of(1, [&] { (void)distance::euclidean(ph.mask, eo); });
      for (int64_t t : thresholds) {
        if (n == 512 && t == 80) continue;  // minutes; the trend is clear from the rest
        geodesic::Options go;
        go.threshold = t;
        go.threads = threads;
        geodesic::Result r;
        const double s = bench::best_of(1, [&] { r = geodesic::boundary_distance(ph.mask, go); });
        std::printf("| %s | %lld³ | %lld | %.1f | %.2f | %.2f | %.0f | %.2f | %lld | %lld | %lld | %.0f | %.1f |\n", shape,
                    static_cast<long long>(n), static_cast<long long>(t), 100.0 * static_cast<double>(k) / static_cast<double>(ph.mask.size()),
                    s, edt, s / edt, static_cast<double>(r.stats.layer_voxels) / static_cast<double>(k),
                    static_cast<long long>(r.stats.searches), static_cast<long long>(r.stats.pivots),
                    static_cast<long long>(r.stats.long_searches),
                    static_cast<double>(r.stats.visited) / static_cast<double>(k), static_cast<double>(r.stats.bytes) / static_cast<double>(k));
        std::fflush(stdout);
      }
    }
  }
  std::printf("\nPeak RSS %.0f MiB.\n", bench::peak_rss_mib());
  return 0;
}
