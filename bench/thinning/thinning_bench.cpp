// Thinning benchmark: thinning.doht (smooth, l = 2, Euclidean distance priority) and thinning.lee94 vs
// scikit-image skeletonize_3d on the same rods and plates phantoms, with the skeletons' topology numbers
// and a voxel-for-voxel comparison of thinning.lee94 with scikit-image.
// Usage: bench_thinning SCRIPT_DIR WORK_DIR [sizes...]   (prints a markdown section)
#include <algorithm>
#include <cstdio>
#include <ctime>
#include <filesystem>
#include <string>
#include <vector>

#include "common/bench_util.hpp"
#include "distance/distance.hpp"
#include "npy_read.hpp"
#include "skel/parallel.hpp"
#include "synthetic/network.hpp"
#include "thinning/lee94.hpp"
#include "thinning/thinning.hpp"
#include "analysis/topology.hpp"
#include "thinning/local_topology.hpp"

using namespace skel::thinning;
using namespace skel::analysis;

using namespace skel;

namespace {

struct Peer {
  double seconds = -1, rss = -1, cpu = -1;  // cpu: the peer's process CPU seconds for the call
  bool ok = false;
};

Peer run_peer(const std::string& script, const std::string& in, const std::string& out) {
  Peer p;
  const std::string cmd = "/usr/bin/python3 " + script + " " + in + " " + out + " 2>/dev/null";
  FILE* f = popen(cmd.c_str(), "r");
  if (!f) return p;
  char buf[256] = {};
  if (std::fgets(buf, sizeof buf, f) && std::sscanf(buf, "%lf %lf %lf", &p.seconds, &p.rss, &p.cpu) >= 2) p.ok = true;
  if (pclose(f) != 0) p.ok = false;
  return p;
}

std::string topo_text(const TopologyNumbers& t) {
  char b[160];
  std::snprintf(b, sizeof b, "%lld | %lld | %lld | %lld | %lld", static_cast<long long>(t.object_voxels),
                static_cast<long long>(t.components), static_cast<long long>(t.cavities),
                static_cast<long long>(t.euler), static_cast<long long>(t.tunnels));
  return b;
}

}  // namespace

int main(int argc, char** argv) {
  if (argc < 3) {
    std::fprintf(stderr, "usage: %s SCRIPT_DIR WORK_DIR [sizes...]\n", argv[0]);
    return 2;
  }
  const std::string script = std::string(argv[1]) + "/skimage_peer.py";
  const std::filesystem::path work = argv[2];
  std::filesystem::create_directories(work);
  std::vector<int64_t> sizes;
  for (int i = 3; i < argc; ++i) sizes.push_back(std::stoll(argv[i]));
  if (sizes.empty()) sizes = {256, 512};
  const int threads = hardware_threads();

  std::printf("## Thinning: thinning.doht vs scikit-image skeletonize_3d\n\n");
  std::printf("Phantoms: synthetic::make_network (shape rods | plates, default period 24, rod radius 2, plate "
              "thickness 3, no noise, seed 1). Ours: smooth "
              "DOHT, end_point_length 2, priority = exact Euclidean distance (distance::euclidean), %d threads; "
              "peer: skimage.morphology.skeletonize_3d on the identical mask (.npy), one run each. "
              "ratio = peer time / our time.\n\n", threads);
  std::printf("| phantom | size | object voxels | EDT s | thinning s | thinning Mvox/s | skimage s | ratio (thinning) | ratio (EDT + thinning) | our peak RSS MiB | skimage peak RSS MiB |\n");
  std::printf("|---|---|---|---|---|---|---|---|---|---|---|\n");
  std::vector<std::string> topo_rows, lee_rows, chamfer_rows;
  auto cpu_now = [] {
    timespec ts{};
    clock_gettime(CLOCK_PROCESS_CPUTIME_ID, &ts);
    return static_cast<double>(ts.tv_sec) + 1e-9 * static_cast<double>(ts.tv_nsec);
  };
  for (int64_t n : sizes) {
    for (int kind = 0; kind < 2; ++kind) {
      const std::string name = kind == 0 ? "rods" : "plates";
      synthetic::NetworkOptions no;
      no.shape = parse_enum<synthetic::Shape>(name, "shape");
      no.size = {n, n, n};
      no.seed = 1;
      no.threads = threads;
      const VolumeU8 mask = synthetic::make_network(no).mask;
      const std::string in = (work / (name + std::to_string(n) + ".npy")).string();
      const std::string out = (work / (name + std::to_string(n) + "_skimage.npy")).string();
      bench::write_npy(in, mask);

      distance::EuclideanOptions eo;
      eo.threads = threads;
      VolumeF32 dt;
      const double t_dt = bench::best_of(1, [&] { dt = distance::euclidean(mask, eo); });
      ThinningOptions o;
      o.variant = ThinningVariant::Smooth;
      o.end_point_length = 2;
      o.threads = threads;
      ThinningResult r;
      const double t_thin = bench::best_of(n <= 256 ? 2 : 1, [&] { r = thin_doht(mask, dt, nullptr, o); });
      const double rss = bench::peak_rss_mib();
      // The thesis pipeline's priority: chamfer (3, 4, 5) with `narrow` (uint8 where every distance
      // fits) + smooth DOHT, wall and process CPU seconds of the best repeat.
      double t_ch = 1e30, t_cth = 1e30, cpu_cth = 1e30;
      std::string ch_type;
      ThinningResult rc;
      for (int rep = 0; rep < (n <= 256 ? 2 : 1); ++rep) {
        const double w0 = bench::now_seconds(), c0 = cpu_now();
        distance::ChamferOptions co;
        co.threads = threads;
        co.narrow = true;
        const DataPtr cd = distance::chamfer(mask, co);
        const double w1 = bench::now_seconds();
        rc = thin_doht(mask, *cd, nullptr, o);
        t_ch = std::min(t_ch, w1 - w0);
        t_cth = std::min(t_cth, bench::now_seconds() - w0);
        cpu_cth = std::min(cpu_cth, cpu_now() - c0);
        ch_type = cd->type_id();
      }
      const TopologyNumbers t_cham = topology(rc.skeleton);
      const Peer p = run_peer(script, in, out);
      const TopologyNumbers t_obj = topology(mask), t_ours = topology(r.skeleton);
      std::string peer_topo = "peer failed | | | |";
      VolumeU8 peer_skel;
      if (p.ok) {
        peer_skel = bench::read_npy_u8(out);
        peer_topo = topo_text(topology(peer_skel));
      }
      Lee94Options lo;
      lo.threads = threads;
      Lee94Result lee;
      double cpu_lee = 1e30;  // process CPU seconds (all threads) of the best repeat
      const double t_lee = bench::best_of(n <= 256 ? 2 : 1, [&] {
        const std::clock_t c0 = std::clock();
        lee = thin_lee94(mask, lo);
        cpu_lee = std::min(cpu_lee, static_cast<double>(std::clock() - c0) / CLOCKS_PER_SEC);
      });
      const bool same = p.ok && peer_skel.dims() == lee.skeleton.dims() &&
                        std::equal(peer_skel.begin(), peer_skel.end(), lee.skeleton.begin());
      {
        char row[512];
        const bool cpu_ok = p.ok && p.cpu > 0;
        std::snprintf(row, sizeof row, "| %s | %lld³ | %lld | %.3f | %.3f | %.1f | %lld | %s | %s | %s | %s | %s | %s |\n",
                      name.c_str(), static_cast<long long>(n), static_cast<long long>(lee.stats.object_voxels), t_lee,
                      cpu_lee, static_cast<double>(lee.stats.object_voxels) / t_lee / 1e6,
                      static_cast<long long>(lee.stats.skeleton_voxels),
                      p.ok ? std::to_string(p.seconds).substr(0, 6).c_str() : "n/a",
                      cpu_ok ? std::to_string(p.cpu).substr(0, 6).c_str() : "n/a",
                      p.ok ? (std::to_string(p.seconds / t_lee).substr(0, 5) + "×").c_str() : "n/a",
                      cpu_ok ? (std::to_string(p.cpu / cpu_lee).substr(0, 5) + "×").c_str() : "n/a",
                      p.ok ? (same ? "yes" : "**no**") : "n/a",
                      (std::to_string(static_cast<double>(lee.stats.bytes) / static_cast<double>(mask.size())).substr(0, 4)).c_str());
        lee_rows.emplace_back(row);
      }
      std::printf("| %s | %lld³ | %lld | %.3f | %.3f | %.1f | %s | %s | %s | %.0f | %s |\n", name.c_str(),
                  static_cast<long long>(n), static_cast<long long>(r.stats.object_voxels), t_dt, t_thin,
                  static_cast<double>(r.stats.object_voxels) / t_thin / 1e6,
                  p.ok ? std::to_string(p.seconds).substr(0, 6).c_str() : "n/a",
                  p.ok ? (std::to_string(p.seconds / t_thin).substr(0, 5) + "×").c_str() : "n/a",
                  p.ok ? (std::to_string(p.seconds / (t_thin + t_dt)).substr(0, 5) + "×").c_str() : "n/a", rss,
                  p.ok ? std::to_string(p.rss).substr(0, 7).c_str() : "n/a");
      std::fflush(stdout);
      {
        char crow[512];
        const bool cpu_ok = p.ok && p.cpu > 0;
        std::snprintf(crow, sizeof crow, "| %s | %lld³ | %s | %.3f | %.3f | %.3f | %s | %s | %s | %s | %s |\n",
                      name.c_str(), static_cast<long long>(n), ch_type.c_str(), t_ch, t_cth, cpu_cth,
                      p.ok ? std::to_string(p.seconds).substr(0, 6).c_str() : "n/a",
                      cpu_ok ? std::to_string(p.cpu).substr(0, 6).c_str() : "n/a",
                      p.ok ? (std::to_string(p.seconds / t_cth).substr(0, 5) + "×").c_str() : "n/a",
                      cpu_ok ? (std::to_string(p.cpu / cpu_cth).substr(0, 5) + "×").c_str() : "n/a",
                      topo_text(t_cham).c_str());
        chamfer_rows.emplace_back(crow);
      }
      char row[512];
      std::snprintf(row, sizeof row,
                    "| %s %lld³ | object | %s |\n| | ours (l=2) | %s |\n| | thinning.lee94 | %s |\n| | skimage | %s |\n",
                    name.c_str(), static_cast<long long>(n), topo_text(t_obj).c_str(), topo_text(t_ours).c_str(),
                    topo_text(topology(lee.skeleton)).c_str(), peer_topo.c_str());
      topo_rows.emplace_back(row);
      std::filesystem::remove(in);
      std::filesystem::remove(out);
    }
  }
  std::printf("\n### Chamfer (narrow) + smooth DOHT vs scikit-image skeletonize_3d\n\n"
              "Same masks and the same scikit-image run as above; priority distance::chamfer (3, 4, 5) with "
              "`narrow` (uint8 where every distance is below 255), smooth DOHT, l = 2, %d threads; chamfer + "
              "thinning wall and process CPU seconds (best of 2 at 256³, one run at 512³); ratio = "
              "scikit-image / ours; the skeleton's voxels, components, cavities, Euler number and tunnels.\n\n",
              threads);
  std::printf("| phantom | size | priority type | chamfer s | chamfer + thinning s | CPU s | skimage s | skimage CPU s | "
              "ratio (wall) | ratio (CPU) | skeleton voxels | components | cavities | euler | tunnels |\n");
  std::printf("|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|\n");
  for (const auto& c : chamfer_rows) std::printf("%s", c.c_str());
  std::printf("\n## thinning.lee94 (Lee94 as scikit-image/Fiji) vs scikit-image skeletonize_3d\n\n"
              "Same masks and the same scikit-image run as above; %d threads; wall and process CPU seconds (CPU "
              "time is less sensitive than wall time to a machine loaded by other work; ours sums all threads); "
              "identical = the two skeletons agree voxel for voxel; working bytes per voxel beyond the mask and "
              "the 1-byte output.\n\n", threads);
  std::printf("| phantom | size | object voxels | lee94 s | lee94 CPU s | Mvox/s | skeleton voxels | skimage s | skimage CPU s | ratio (wall) | ratio (CPU) | identical | working B/voxel |\n");
  std::printf("|---|---|---|---|---|---|---|---|---|---|---|---|---|\n");
  for (const auto& s : lee_rows) std::printf("%s", s.c_str());
  std::printf("\nTopology numbers ((26, 6) adjacency, analysis.topology): a homotopic skeleton has the object's "
              "components, cavities, Euler characteristic and tunnels.\n\n");
  std::printf("| volume | skeleton | voxels | components | cavities | euler | tunnels |\n|---|---|---|---|---|---|---|\n");
  for (const auto& s : topo_rows) std::printf("%s", s.c_str());
  std::printf("\n");
  return 0;
}
