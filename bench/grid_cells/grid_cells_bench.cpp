// Grid cell thinning (thinning.grid_cell, thesis Algorithm 3) against voxel thinning (thinning.doht,
// Algorithm 2) on the rods and plates phantoms of synthetic.network: time, working memory in bytes per
// voxel, size of the results. Prints a markdown section for bench/RESULTS.md.
#include <cstdio>
#include <cstdlib>
#include <string>
#include <vector>

#include "common/bench_util.hpp"
#include "distance/distance.hpp"
#include "synthetic/network.hpp"
#include "thinning/grid_cell.hpp"
#include "thinning/thinning.hpp"

using namespace skel;

int main(int argc, char** argv) {
  const int threads = argc > 1 ? std::atoi(argv[1]) : 2;
  std::vector<int64_t> sizes;
  for (int i = 2; i < argc; ++i) sizes.push_back(std::atoll(argv[i]));
  if (sizes.empty()) sizes = {128, 256};
  std::printf("## Grid cell thinning vs voxel thinning\n\n");
  std::printf("`synthetic.network` rods (radius 2) and plates (thickness 3), noise 0.15, seed 1; priority = "
              "`distance.euclidean`; %d threads. voxel = `thinning.doht` (smooth, end_point_length 2); cells = "
              "`thinning.grid_cell` (end_point_length 4; the thesis needs a larger length in the grid cell model). B/voxel = working memory (Statistics::bytes) plus "
              "the output (voxel skeleton: 1 B/voxel; grid cells: (X+1)(Y+1)(Z+1) B) per voxel; inputs (mask 1 B, "
              "priority 4 B) excluded.\n\n", threads);
  std::printf("| phantom | size | object voxels | method | time (s) | B/voxel | result |\n|---|---|---|---|---|---|---|\n");
  for (int64_t n : sizes)
    for (auto shape : {synthetic::Shape::rods, synthetic::Shape::plates}) {
      synthetic::NetworkOptions no;
      no.shape = shape;
      no.size = {n, n, n};
      no.noise = 0.15;
      no.threads = threads;
      const VolumeU8 mask = synthetic::make_network(no).mask;
      distance::EuclideanOptions eo;
      eo.threads = threads;
      const VolumeF32 d = distance::euclidean(mask, eo);
      int64_t obj = 0;
      for (auto v : mask) obj += v != 0;
      const char* name = shape == synthetic::Shape::rods ? "rods" : "plates";
      const double voxels = static_cast<double>(mask.size());
      thinning::ThinningOptions vo;
      vo.threads = threads;
      thinning::ThinningResult vr;
      const double tv = bench::best_of(1, [&] { vr = thinning::thin_doht(mask, d, nullptr, vo); });
      std::printf("| %s | %lld³ | %lld | voxel | %.2f | %.2f | %lld voxels, %lld stuck |\n", name, static_cast<long long>(n),
                  static_cast<long long>(obj), tv, (static_cast<double>(vr.stats.bytes) + voxels) / voxels,
                  static_cast<long long>(vr.stats.skeleton_voxels), static_cast<long long>(vr.stats.stuck_voxels));
      {
        thinning::GridCellThinningOptions go;
        go.threads = threads;
        go.end_point_length = 4;
        thinning::GridCellThinningResult gr;
        const double tg = bench::best_of(1, [&] { gr = thinning::thin_grid_cells(mask, d, nullptr, go); });
        const auto& c = gr.stats.cells_after;
        std::printf("| %s | %lld³ | %lld | cells | %.2f | %.2f | %lld/%lld/%lld/%lld cells (0/1/2/3), %lld pairs |\n", name,
                    static_cast<long long>(n), static_cast<long long>(obj),
                    tg, (static_cast<double>(gr.stats.bytes) + static_cast<double>(gr.skeleton.bytes())) / voxels,
                    static_cast<long long>(c[0]), static_cast<long long>(c[1]), static_cast<long long>(c[2]),
                    static_cast<long long>(c[3]), static_cast<long long>(gr.stats.removed_pairs));
      }
      std::fflush(stdout);
    }
  std::printf("\nPeak RSS of the process: %.0f MiB.\n", bench::peak_rss_mib());
  return 0;
}
