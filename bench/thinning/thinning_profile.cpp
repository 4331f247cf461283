// Thinning profile driver: times thin_doht alone (no peer) on the benchmark phantoms and prints the
// statistics, a hash of the skeleton and its topology numbers, so that speed changes can be checked
// for identical results, and the peak memory of priority + thinning beyond the mask (VmHWM is reset after
// the phantom is made, so the phantom's own float image does not count).
// Usage: thinning_profile SIZE [rods|plates] [basic|smooth] [threads] [repeats] [edt|chamfer|chamfer8]
// [inplace]
// (chamfer: uint16 distances; chamfer8: ChamferOptions::narrow, uint8 where every distance fits;
// inplace: thin_doht_in_place on a copy of the mask made before the peak is reset, as the pipeline
// thins in the mask's buffer when it is the mask's last reader: the skeleton costs no bytes beyond it)
#include <algorithm>
#include <atomic>
#include <chrono>
#include <cstdlib>
#include <fstream>
#include <cstdio>
#include <ctime>
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

namespace {
// A line "Key:  N kB" of /proc/self/status, in bytes (0 if absent).
double status_bytes(const char* key) {
  std::ifstream f("/proc/self/status");
  std::string line;
  const std::string k = std::string(key) + ":";
  while (std::getline(f, line))
    if (line.compare(0, k.size(), k) == 0) return std::stod(line.substr(k.size())) * 1024.0;
  return 0;
}
void reset_peak() { std::ofstream("/proc/self/clear_refs") << "5"; }
}  // namespace

int main(int argc, char** argv) {
  if (argc < 2) {
    std::fprintf(stderr, "usage: %s SIZE [rods|plates] [basic|smooth] [threads] [repeats] [edt|chamfer|chamfer8]\n", argv[0]);
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
  const std::string prio = argc > 6 ? argv[6] : "edt";
  const VolumeU8 mask = synthetic::make_network(no).mask;
  const bool in_place = argc > 7 && std::string(argv[7]) == "inplace";
  if (in_place && repeats != 1) {
    std::fprintf(stderr, "inplace: one run only (repeats = 1)\n");
    return 2;
  }
  VolumeU8 work;  // in place: the buffer that is thinned (a fresh copy per repeat)
  if (in_place) work = mask;
  reset_peak();
  const double base = status_bytes("VmRSS");
  const double t_prio0 = bench::now_seconds();
  DataPtr dt;
  if (prio == "chamfer" || prio == "chamfer8") {
    distance::ChamferOptions co;
    co.threads = threads;
    co.narrow = prio == "chamfer8";
    dt = distance::chamfer(mask, co);
  } else {
    distance::EuclideanOptions eo;
    eo.threads = threads;
    dt = std::make_shared<VolumeF32>(distance::euclidean(mask, eo));
  }
  const double t_prio = bench::now_seconds() - t_prio0;
  const double after_prio = status_bytes("VmHWM");

  ThinningOptions o;
  o.variant = variant;
  o.end_point_length = 2;
  o.threads = threads;
  // SKEL_PROFILE_RSS=1: the resident and peak memory at each progress report of thin_doht (phase ends:
  // 0.04 scan, 0.08 queue filled, 0.08-0.9 removal, 0.9 removal done, 1.0 finished).
  static const std::atomic<bool> never{false};
  // The seconds since thin_doht started are printed too (the phases' times).
  double t_thin0 = 0;
  if (std::getenv("SKEL_PROFILE_RSS"))
    o.interrupter = Interrupter(
        [&](double f) {
          std::printf("  progress %.3f at %.3f s: RSS %.0f MiB, peak %.0f MiB\n", f, bench::now_seconds() - t_thin0,
                      status_bytes("VmRSS") / 1048576.0, status_bytes("VmHWM") / 1048576.0);
        },
        &never);
  ThinningResult r;
  // Process CPU seconds of each run too (all threads; less sensitive to a loaded machine than wall time).
  auto cpu_now = [] {
    timespec ts{};
    clock_gettime(CLOCK_PROCESS_CPUTIME_ID, &ts);
    return static_cast<double>(ts.tv_sec) + 1e-9 * static_cast<double>(ts.tv_nsec);
  };
  double cpu_best = 1e300;
  const double t = bench::best_of(repeats, [&] {
    t_thin0 = bench::now_seconds();
    const double c0 = cpu_now();
    if (in_place) {
      r = thin_doht_in_place(work, *dt, nullptr, o);  // one run (repeats = 1): `work` is the skeleton now
    } else {
      r = thin_doht(mask, *dt, nullptr, o);
    }
    cpu_best = std::min(cpu_best, cpu_now() - c0);
  });
  const double peak = status_bytes("VmHWM");
  if (in_place) r.skeleton = std::move(work);  // for the hash and topology below
  const double nv = static_cast<double>(mask.size());

  uint64_t h = 1469598103934665603ull;  // FNV-1a over the skeleton
  for (int64_t i = 0; i < r.skeleton.size(); ++i) {
    h ^= r.skeleton[i];
    h *= 1099511628211ull;
  }
  const TopologyNumbers tn = topology(r.skeleton);
  const ThinningStatistics& s = r.stats;
  std::printf("%s %lld^3 %s threads %d: %.3f s, CPU %.3f s (best of %d), priority type %s\n", shape.c_str(),
              static_cast<long long>(n), argc > 3 ? argv[3] : "smooth", threads, t, cpu_best, repeats,
              dt->type_id().c_str());
  std::printf("priority %s %.3f s; peak beyond the mask (%.0f MiB at start): priority %.2f B/voxel, priority + "
              "thinning %.2f B/voxel (%.0f MiB), thinning working bytes (stats) %.2f B/voxel\n",
              prio.c_str(), t_prio, base / 1048576.0, (after_prio - base) / nv, (peak - base) / nv,
              (peak - base) / 1048576.0, static_cast<double>(r.stats.bytes) / nv);
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
