// Small modules registered only in the GUI test binaries, so the GUI tests run even while the
// real source/segmentation families are absent: a smooth field (three crossing Gaussian rods), a
// threshold, and a table of voxel counts.
#include <algorithm>
#include <chrono>
#include <cmath>
#include <thread>

#include "geometry/skeleton_to_mesh.hpp"
#include "skel/module.hpp"
#include "skel/spatial_graph.hpp"
#include "skel/table.hpp"

namespace skel {
namespace {

class FieldModule final : public Module {
public:
  static ModuleSpec spec() {
    return ModuleSpec("gui_test.field", "Test source: three crossing Gaussian rods in [0, 1]")
        .output<VolumeF32>("image", "float32 field, 1 on the rod axes")
        .param<std::vector<int64_t>>("size", {64, 64, 64}, "volume size (x, y, z)")
        .range(4, 512)
        .length(3)
        .param<double>("radius", 6.0, "Gaussian radius of the rods")
        .range(0.5, 100)
        .unit("voxels")
        .details("Test-only module of the GUI tests. Memory: 4 bytes per voxel.");
  }
  void run(RunContext& ctx) override {
    const auto size = ctx.param<std::vector<int64_t>>("size");
    const double r = ctx.param<double>("radius");
    VolumeF32 v(Dims{size[0], size[1], size[2]});
    const double cx = (size[0] - 1) / 2.0, cy = (size[1] - 1) / 2.0, cz = (size[2] - 1) / 2.0;
    for (int64_t z = 0; z < v.nz(); ++z) {
      ctx.progress().check(static_cast<double>(z) / static_cast<double>(v.nz()));
      for (int64_t y = 0; y < v.ny(); ++y) {
        for (int64_t x = 0; x < v.nx(); ++x) {
          const double dx = x - cx, dy = y - cy, dz = z - cz;
          const double d2 = std::min({dy * dy + dz * dz, dx * dx + dz * dz, dx * dx + dy * dy});
          v(x, y, z) = static_cast<float>(std::exp(-d2 / (r * r)));
        }
      }
    }
    ctx.output("image", std::move(v));
  }
};
SKEL_REGISTER_MODULE(FieldModule);

class ThresholdModule final : public Module {
public:
  static ModuleSpec spec() {
    return ModuleSpec("gui_test.threshold", "Test threshold: voxel >= level becomes 1")
        .input<VolumeF32>("image", "float32 image")
        .output<VolumeU8>("mask", "binary mask (0/1)")
        .param<double>("level", 0.5, "threshold level")
        .range(0, 1)
        .details("Test-only module of the GUI tests. Memory: 5 bytes per voxel.");
  }
  void run(RunContext& ctx) override {
    auto in = ctx.input<VolumeF32>("image");
    const float level = static_cast<float>(ctx.param<double>("level"));
    VolumeU8 out(in->grid(), 0);
    for (int64_t i = 0; i < in->size(); ++i) out.data()[i] = in->data()[i] >= level ? 1 : 0;
    ctx.output("mask", std::move(out));
  }
};
SKEL_REGISTER_MODULE(ThresholdModule);

class CountModule final : public Module {
public:
  static ModuleSpec spec() {
    return ModuleSpec("gui_test.count", "Test statistics: number of object voxels")
        .input<VolumeU8>("mask", "binary mask")
        .output<Table>("table", "one row: voxels")
        .details("Test-only module of the GUI tests. Memory: none.");
  }
  void run(RunContext& ctx) override {
    auto in = ctx.input<VolumeU8>("mask");
    int64_t n = 0;
    for (int64_t i = 0; i < in->size(); ++i) n += in->data()[i] != 0;
    Table t;
    t.add("voxels", std::vector<int64_t>{n});
    ctx.output("table", std::move(t));
  }
};
SKEL_REGISTER_MODULE(CountModule);

}  // namespace
}  // namespace skel

namespace skel {
namespace {

// A small spatial graph: a centre node joined to the six faces of a cube by curved polylines whose
// radius shrinks along each edge (point attribute "radius", edge attribute "length").
class GraphModule final : public Module {
public:
  static ModuleSpec spec() {
    return ModuleSpec("gui_test.graph", "Test source: a star-shaped spatial graph with radii")
        .output<SpatialGraph>("graph", "7 nodes, 6 curved edges; point attribute radius, edge attribute length")
        .param<double>("extent", 30.0, "distance of the outer nodes from the centre")
        .range(1, 1000)
        .unit("µm")
        .details("Test-only module of the GUI tests. Memory: a few KiB.");
  }
  void run(RunContext& ctx) override {
    const double r = ctx.param<double>("extent");
    SpatialGraph g;
    const int64_t c = g.add_node({0, 0, 0});
    const Vec3 dirs[6] = {{1, 0, 0}, {-1, 0, 0}, {0, 1, 0}, {0, -1, 0}, {0, 0, 1}, {0, 0, -1}};
    for (const Vec3& d : dirs) {
      const int64_t n = g.add_node({d[0] * r, d[1] * r, d[2] * r});
      std::vector<Vec3> pts;
      for (int i = 0; i <= 10; ++i) {
        const double t = i / 10.0, bend = 0.2 * r * std::sin(t * 3.14159265358979);
        pts.push_back({d[0] * r * t + bend * d[1], d[1] * r * t + bend * d[2], d[2] * r * t + bend * d[0]});
      }
      const int64_t e = g.add_edge(c, n, std::move(pts));
      auto& radius = g.ensure_point_attribute("radius");
      for (size_t i = 0; i < radius[e].size(); ++i) radius[e][i] = static_cast<float>(0.08 * r * (1.0 - 0.06 * i));
    }
    auto& length = g.ensure_edge_attribute("length");
    for (int64_t e = 0; e < g.edge_count(); ++e) length[e] = static_cast<float>(g.edge_length(e));
    ctx.output("graph", std::move(g));
  }
};
SKEL_REGISTER_MODULE(GraphModule);

}  // namespace
}  // namespace skel

namespace skel {
namespace {

// A small skeleton mesh: a bent plate with a rod standing on it (geometry.skeleton_to_mesh), so the
// triangles have both manifold classes and there is a line.
class MeshModule final : public Module {
public:
  static ModuleSpec spec() {
    return ModuleSpec("gui_test.mesh", "Test source: the mesh of a bent plate with a rod on it")
        .output<Mesh>("mesh", "triangles (manifold class per triangle) and one line")
        .details("Test-only module of the GUI tests. Memory: a few hundred KiB.");
  }
  void run(RunContext& ctx) override {
    VolumeU8 v({32, 32, 32}, 0);
    for (int64_t y = 2; y < 30; ++y)
      for (int64_t x = 2; x < 30; ++x) v(x, y, 6 + std::abs(x - 16) / 3) = 1;
    for (int64_t z = 7; z < 28; ++z) v(16, 16, z) = 1;
    ctx.output("mesh", geometry::skeleton_to_mesh(v));
  }
};
SKEL_REGISTER_MODULE(MeshModule);

}  // namespace
}  // namespace skel

namespace skel {
namespace {

// Runs for `seconds`, reporting progress and honouring cancellation every 10 ms: lets the GUI tests
// watch a node in the Running state and cancel it.
class SlowModule final : public Module {
public:
  static ModuleSpec spec() {
    return ModuleSpec("gui_test.slow", "Test source: takes `seconds`, reporting progress; cancellable")
        .output<VolumeU8>("mask", "8x8x8 mask, all 1")
        .param<double>("seconds", 5.0, "how long the run takes")
        .range(0, 600)
        .unit("s")
        .details("Test-only module of the GUI tests. Memory: 512 bytes.");
  }
  void run(RunContext& ctx) override {
    const double seconds = ctx.param<double>("seconds");
    const auto t0 = std::chrono::steady_clock::now();
    for (;;) {
      const double t = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
      if (t >= seconds) break;
      ctx.progress().check(t / seconds);
      std::this_thread::sleep_for(std::chrono::milliseconds(10));
    }
    ctx.output("mask", VolumeU8(Dims{8, 8, 8}, 1));
  }
};
SKEL_REGISTER_MODULE(SlowModule);

}  // namespace
}  // namespace skel
