// Geodesic boundary distance: time against the threshold t and against size on plates and mixed
// phantoms, memory per object voxel, and the project's own Euclidean DT on the same volume as the
// yardstick (there is no external implementation of this measure to compare with).
#include <cstdio>
#include <sys/resource.h>
#include <cstdlib>
#include <string>
#include <vector>

#include "common/bench_util.hpp"
#include "distance/distance.hpp"
#include "geodesic/geodesic.hpp"
#include "synthetic/network.hpp"

using namespace skel;

namespace {
// CPU seconds (user + system, all threads) of this process so far: on a shared machine the wall
// time depends on the load, the CPU time much less.
double cpu_seconds() {
  rusage u{};
  getrusage(RUSAGE_SELF, &u);
  return static_cast<double>(u.ru_utime.tv_sec + u.ru_stime.tv_sec) + 1e-6 * static_cast<double>(u.ru_utime.tv_usec + u.ru_stime.tv_usec);
}
// FNV-1a over the importance's bytes: equal hashes across builds = bit-identical output.
uint64_t importance_hash(const VolumeF32& v) {
  uint64_t h = 1469598103934665603ull;
  const auto* p = reinterpret_cast<const unsigned char*>(v.data());
  for (size_t i = 0; i < static_cast<size_t>(v.size()) * sizeof(float); ++i) h = (h ^ p[i]) * 1099511628211ull;
  return h;
}
}  // namespace

int main(int argc, char** argv) {
  const int threads = argc > 1 ? std::atoi(argv[1]) : 2;
  // Second argument: "big" (256³ and 512³), or the sizes to run, comma-separated (e.g. 1024); default 256.
  std::vector<int64_t> sizes = {256};
  if (argc > 2 && std::string(argv[2]) == "big") sizes.push_back(512);
  else if (argc > 2 && std::string(argv[2]) != "small") {
    sizes.clear();
    for (const char* p = argv[2]; *p;) {
      char* e = nullptr;
      const long long n = std::strtoll(p, &e, 10);
      if (e == p || n < 16 || n > 4096) {
        std::fprintf(stderr, "bench_geodesic: sizes must be 16..4096, e.g. 512,1024 (or big / small)\n");
        return 2;
      }
      sizes.push_back(n);
      p = *e == ',' ? e + 1 : e;
    }
  }
  // Fourth argument: the phantoms, comma-separated (default plates,mixed).
  std::vector<std::string> shapes = {"plates", "mixed"};
  if (argc > 4) {
    shapes.clear();
    std::string all = argv[4];
    for (size_t b = 0; b <= all.size();) {
      const size_t e = std::min(all.find(',', b), all.size());
      shapes.push_back(all.substr(b, e - b));
      b = e + 1;
    }
  }
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
              "CPU = user + system seconds of all threads (the machine is shared: wall times depend on the load, CPU times much less); prepare/search = the algorithm's own phase timers (wall); k = object voxels, |L| = boundary-layer voxels; searches = searches run (one A* search per base point with targets left that no monotone path of at most 4 steps settles, "
              "plus pivots: breadth-first to t + t/4), of them pivots and long (own searches that ended at t with targets left); bytes/k = working memory of the algorithm per object voxel (mask and outputs excluded).\n\n", threads);
  std::printf("| phantom | size | t | object %% | time (s) | CPU (s) | prepare (s) | search (s) | EDT (s) | EDT CPU (s) | time / EDT | CPU / EDT CPU | |L| / k | searches | pivots | long | landmarks | visited / k | bytes / k | prepare / search B/k | importance hash |\n");
  std::printf("|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|\n");
  for (const std::string& shape : shapes) {
    for (int64_t n : sizes) {
      synthetic::NetworkOptions no;
      no.shape = parse_enum<synthetic::Shape>(shape, "shape");
      no.size = {n, n, n};
      no.threads = threads;
      auto ph = synthetic::make_network(no);
      // Only the mask is used: the phantom's float image (4 bytes per voxel, 8 GiB at 1280³) would
      // otherwise stay resident beside the EDT's and the geodesic's outputs and push this 24 GiB
      // machine into reclaim during the timed runs.
      ph.image = VolumeF32();
      int64_t k = 0;
      for (auto v : ph.mask) k += v;
      distance::EuclideanOptions eo;
      eo.threads = threads;
      const double c0 = cpu_seconds();
      const double edt = bench::best_of(1, [&] { (void)distance::euclidean(ph.mask, eo); });
      const double edt_cpu = cpu_seconds() - c0;
      for (int64_t t : thresholds) {
        if (n >= 512 && t == 80) continue;  // minutes; the trend is clear from the rest
        geodesic::Options go;
        go.threshold = t;
        go.threads = threads;
        if (const char* lm = std::getenv("GEO_LANDMARKS")) go.landmarks = std::string(lm) != "0";
        geodesic::Result r;
        const double c1 = cpu_seconds();
        const double s = bench::best_of(1, [&] { r = geodesic::boundary_distance(ph.mask, go); });
        const double cpu = cpu_seconds() - c1;
        std::printf("| %s | %lld³ | %lld | %.1f | %.2f | %.2f | %.2f | %.2f | %.2f | %.2f | %.0f | %.0f | %.2f | %lld | %lld | %lld | %lld | %.0f | %.1f | %.1f / %.1f | %016llx |\n", shape.c_str(),
                    static_cast<long long>(n), static_cast<long long>(t), 100.0 * static_cast<double>(k) / static_cast<double>(ph.mask.size()),
                    s, cpu, r.stats.seconds_prepare, r.stats.seconds_search, edt, edt_cpu, s / edt, cpu / edt_cpu, static_cast<double>(r.stats.layer_voxels) / static_cast<double>(k),
                    static_cast<long long>(r.stats.searches), static_cast<long long>(r.stats.pivots),
                    static_cast<long long>(r.stats.long_searches), static_cast<long long>(r.stats.landmarks),
                    static_cast<double>(r.stats.visited) / static_cast<double>(k), static_cast<double>(r.stats.bytes) / static_cast<double>(k),
                    static_cast<double>(r.stats.bytes_prepare) / static_cast<double>(k), static_cast<double>(r.stats.bytes_search) / static_cast<double>(k),
                    static_cast<unsigned long long>(importance_hash(r.importance)));
        std::fflush(stdout);
      }
    }
  }
  std::printf("\nPeak RSS %.0f MiB.\n", bench::peak_rss_mib());
  return 0;
}
