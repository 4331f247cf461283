// Skeleton meshes (thesis §3.1.3): triangles of geometry.skeleton_to_mesh against the closed
// iso-surface (VTK flying edges) of the same skeleton voxels, on the mixed skeleton of the
// bone_plates pipeline's phantom at several sizes; time, bytes per triangle, and what decimation to
// 2 % leaves. The thesis's claim: the skeleton's surface needs fewer triangles than an iso-surface of
// the same voxels, which bounds each one-voxel-thick plate from both sides.
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <string>

#include "common/bench_util.hpp"
#include "geometry/mesh_filters.hpp"
#include "geometry/skeleton_to_mesh.hpp"
#include "skel/executor.hpp"
#include "skel/pipeline.hpp"

using namespace skel;

int main(int argc, char** argv) {
  const int threads = argc > 1 ? std::atoi(argv[1]) : 2;
  const bool big = argc > 2 && std::string(argv[2]) == "big";
  std::printf("## Skeleton meshes vs iso-surfaces\n\n");
  std::printf("Mixed skeleton of `pipelines/bone_plates.yaml` (plates and rods phantom, geodesic threshold 24, "
              "plates locked during thinning), %d threads. skeleton mesh = `geometry.skeleton_to_mesh` (improved cases); "
              "iso-surface = `geometry.isosurface` of the same skeleton voxels at 0.5 (closed); 2 %% = "
              "`geometry.mesh_decimate` keep 0.02. bytes/tri = Mesh::bytes() / triangles.\n\n", threads);
  std::printf("| size | skeleton voxels | skeleton mesh triangles | lines | time (s) | bytes/tri | iso-surface triangles | time (s) | iso / skeleton | 2 %% triangles | decimate (s) |\n");
  std::printf("|---|---|---|---|---|---|---|---|---|---|---|\n");
  std::vector<int64_t> sizes = {128, 192};
  if (big) sizes.push_back(256);
  for (int64_t n : sizes) {
    Pipeline p = Pipeline::load_file(std::filesystem::path(SKEL_SOURCE_DIR) / "pipelines" / "bone_plates.yaml");
    p.set_param("phantom", "size", std::vector<int64_t>{n, n, n});
    Executor ex;
    ExecOptions o;
    o.threads = threads;
    o.keep_outputs = true;
    o.targets = {"mixed"};
    ex.run(p, o);
    auto sk = std::dynamic_pointer_cast<const VolumeU8>(ex.output(p, "mixed", "skeleton"));
    if (!sk) {
      std::fprintf(stderr, "bench_mesh: no skeleton\n");
      return 1;
    }
    int64_t k = 0;
    for (auto v : *sk) k += v != 0;
    geometry::SkeletonToMeshOptions so;
    so.threads = threads;
    Mesh m, iso, dec;
    const double ts = bench::best_of(1, [&] { m = geometry::skeleton_to_mesh(*sk, so); });
    const double ti = bench::best_of(1, [&] { iso = geometry::isosurface(*sk); });
    geometry::MeshDecimateOptions d;
    d.keep = 0.02;
    const double td = bench::best_of(1, [&] { dec = geometry::mesh_decimate(m, d); });
    std::printf("| %lld³ | %lld | %lld | %lld | %.2f | %.1f | %lld | %.2f | %.2f | %lld | %.2f |\n", static_cast<long long>(n),
                static_cast<long long>(k), static_cast<long long>(m.triangle_count()), static_cast<long long>(m.line_count()), ts,
                static_cast<double>(m.bytes()) / static_cast<double>(std::max<int64_t>(1, m.triangle_count())),
                static_cast<long long>(iso.triangle_count()), ti,
                static_cast<double>(iso.triangle_count()) / static_cast<double>(std::max<int64_t>(1, m.triangle_count())),
                static_cast<long long>(dec.triangle_count()), td);
    std::fflush(stdout);
  }
  std::printf("\nPeak RSS %.0f MiB.\n", bench::peak_rss_mib());
  return 0;
}
