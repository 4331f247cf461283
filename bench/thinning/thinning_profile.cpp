// Thinning profile driver: times thin_doht alone (no peer) on the benchmark phantoms and prints the
// statistics, a hash of the skeleton and its topology numbers, so that speed changes can be checked
// for identical results. Usage: thinning_profile SIZE [rods|plates] [basic|smooth] [threads] [repeats]
#include <chrono>
#include <cstdio>
#include <string>

#include "common/bench_util.hpp"
#include "distance/distance.hpp"
#include "skel/parallel.hpp"
#include "synthetic/network.hpp"
#include "thinning/thinning.hpp"
#include "analysis/topology.hpp"
#include "thinning/local_topology.hpp"

using namespace skel::thinning;
using namespace skel::analysis;

using namespace skel;

int main(int argc, char** argv) {
  if (argc < 2) {
    std::fprintf(stderr, "usage: %s SIZE [rods|plates] [basic|smooth] [threads] [repeats]\n", argv[0]);
    return 2;
  }
  const int64_t n = std::stoll(argv[1]);
  const std::string shape = argc > 2 ? argv[2] : "rods";
  const ThinningVariant variant = parse_enum<ThinningVariant>(argc > 3 ? argv[3] : "smooth", "variant");
  const int threads = argc > 4 ? std::stoi(argv[4]) : hardware_threads();
  const int repeats = argc > 5 ? std::stoi(argv[5]) : 1;

  synthetic::NetworkOptions no;
  no.shape = parse_enum<synthetic::Shape>(shape, "shape");
  no.size = {n, n, n};
  no.seed = 1;
  no.threads = threads;
  const VolumeU8 mask = synthetic::make_network(no).mask;
  distance::EuclideanOptions eo;
  eo.threads = threads;
  const VolumeF32 dt = distance::euclidean(mask, eo);

  ThinningOptions o;
  o.variant = variant;
  o.end_point_length = 2;
  o.threads = threads;
  ThinningResult r;
  const double t = bench::best_of(repeats, [&] { r = thin_doht(mask, dt, nullptr, o); });

  uint64_t h = 1469598103934665603ull;  // FNV-1a over the skeleton
  for (int64_t i = 0; i < r.skeleton.size(); ++i) {
    h ^= r.skeleton[i];
    h *= 1099511628211ull;
  }
  const TopologyNumbers tn = topology(r.skeleton);
  const ThinningStatistics& s = r.stats;
  std::printf("%s %lld^3 %s threads %d: %.3f s (best of %d)\n", shape.c_str(), static_cast<long long>(n),
              argc > 3 ? argv[3] : "smooth", threads, t, repeats);
  std::printf("object %lld skeleton %lld levels %lld tests %lld removed %lld sub_iterations %lld kept_end %lld "
              "stuck %lld/%lld interior %lld\n",
              static_cast<long long>(s.object_voxels), static_cast<long long>(s.skeleton_voxels),
              static_cast<long long>(s.priority_levels), static_cast<long long>(s.tests),
              static_cast<long long>(s.removed), static_cast<long long>(s.sub_iterations),
              static_cast<long long>(s.kept_end_points), static_cast<long long>(s.stuck_components),
              static_cast<long long>(s.stuck_voxels), static_cast<long long>(s.interior_voxels));
  std::printf("skeleton hash %016llx topology voxels %lld components %lld cavities %lld euler %lld tunnels %lld\n",
              static_cast<unsigned long long>(h), static_cast<long long>(tn.object_voxels),
              static_cast<long long>(tn.components), static_cast<long long>(tn.cavities),
              static_cast<long long>(tn.euler), static_cast<long long>(tn.tunnels));
  return 0;
}
