// Lee94 profile driver: times thin_lee94 alone (no peer) on the benchmark phantoms and prints its
// statistics and a hash of the skeleton, so that speed changes can be checked for identical results.
// Usage: lee94_profile SIZE [rods|plates] [threads] [repeats]
#include <algorithm>
#include <cstdio>
#include <ctime>
#include <string>

#include "common/bench_util.hpp"
#include "skel/parallel.hpp"
#include "synthetic/network.hpp"
#include "thinning/lee94.hpp"

using namespace skel;
using namespace skel::thinning;

int main(int argc, char** argv) {
  if (argc < 2) {
    std::fprintf(stderr, "usage: %s SIZE [rods|plates] [threads] [repeats]\n", argv[0]);
    return 2;
  }
  const int64_t n = std::stoll(argv[1]);
  const std::string shape = argc > 2 ? argv[2] : "rods";
  const int threads = argc > 3 ? std::stoi(argv[3]) : hardware_threads();
  const int repeats = argc > 4 ? std::stoi(argv[4]) : 1;
  synthetic::NetworkOptions no;
  no.shape = parse_enum<synthetic::Shape>(shape, "shape");
  no.size = {n, n, n};
  no.seed = 1;
  no.threads = threads;
  const VolumeU8 mask = synthetic::make_network(no).mask;
  Lee94Options o;
  o.threads = threads;
  Lee94Result r;
  double cpu = 1e30;  // process CPU seconds of the best repeat (less sensitive than wall time to a loaded machine)
  const double t = bench::best_of(repeats, [&] {
    const std::clock_t c0 = std::clock();
    r = thin_lee94(mask, o);
    cpu = std::min(cpu, static_cast<double>(std::clock() - c0) / CLOCKS_PER_SEC);
  });
  uint64_t h = 1469598103934665603ull;  // FNV-1a over the skeleton
  for (int64_t i = 0; i < r.skeleton.size(); ++i) {
    h ^= r.skeleton[i];
    h *= 1099511628211ull;
  }
  const Lee94Statistics& s = r.stats;
  std::printf("%s %lld^3 threads %d: %.3f s wall, %.3f s CPU (best of %d)\n", shape.c_str(),
              static_cast<long long>(n), threads, t, cpu, repeats);
  std::printf("object %lld skeleton %lld passes %lld candidates %lld removed %lld rejected %lld vanished %lld "
              "scanned_rows %lld bytes %llu hash %016llx\n",
              static_cast<long long>(s.object_voxels), static_cast<long long>(s.skeleton_voxels),
              static_cast<long long>(s.passes), static_cast<long long>(s.candidates),
              static_cast<long long>(s.removed), static_cast<long long>(s.rejected),
              static_cast<long long>(s.vanished_components), static_cast<long long>(s.scanned_rows),
              static_cast<unsigned long long>(s.bytes), static_cast<unsigned long long>(h));
  return 0;
}
