// Modules of the synthetic family: test objects of thesis ch. 4 and a vessel network with ground truth.
#include "skel/module.hpp"
#include "synthetic/names.hpp"
#include "synthetic/network.hpp"
#include "synthetic/vessel_tree.hpp"

namespace skel::synthetic {
namespace {

class Network final : public Module {
public:
  static ModuleSpec spec() {
    return ModuleSpec(names::network, "Synthetic rods, plates, spheres or mixtures (the test objects of thesis ch. 4)")
        .output<VolumeF32>("image", "smooth scalar image in about [0, 1]; 0.5 is the object boundary")
        .output<VolumeU8>("mask", "image > 0.5 (0/1)")
        .param("shape", &NetworkOptions::shape,
                "rods: jittered lattice of rods along x, y, z; plates: slabs with holes; spheres: balls; mixed: plates joined by rods (bone-like)")
        .param("size", &NetworkOptions::size, "volume size [x, y, z]").range(1, 8192).unit("voxels")
        .param("seed", &NetworkOptions::seed, "random seed: the same seed gives the same volume on any machine and thread count").min(0)
        .param("noise", &NetworkOptions::noise, "amplitude of noise at two frequencies (smooth 16-voxel value noise and per-voxel noise)").range(0, 1)
        .param("spacing", &NetworkOptions::spacing, "voxel size [x, y, z] in `unit`").min(1e-9)
        .param("unit", &NetworkOptions::unit, "physical unit of spacing, stored in the output grids (every later table and file uses it)")
        .param("period", &NetworkOptions::period, "lattice cell size: distance between neighbouring elements").range(8, 4096).unit("voxels")
        .param("radius", &NetworkOptions::radius, "rod radius (each rod varies ±20 %); balls have radii 1.5·radius .. 0.35·period − 1.5").min(0.1).unit("voxels")
        .param("plate_thickness", &NetworkOptions::plate_thickness, "thickness of the plates (plates, mixed)").min(0.1).unit("voxels")
        .param("sigma", &NetworkOptions::sigma, "standard deviation of the Gaussian that smooths the drawn object (0 = none)").min(0).unit("voxels")
        .param("threshold", &NetworkOptions::threshold, "mask = image > threshold").range(0.01, 0.99)
        .details(R"(Thesis ch. 4 (fig. 4.1 test objects). Elements are generated from a jittered lattice
(cell = period voxels) and drawn as 1 into a zero float image: rods are capsules between jittered
lattice nodes along x, y and z (each present with probability 0.8, so the network has free ends);
plates are slabs perpendicular to z every period (tilted up to ±0.15) plus walls perpendicular to x
every 2 periods, with round holes (radius period/3) in 45 % of the lattice cells; spheres are solid
balls, one per cell with probability 0.85, radii 1.5·radius .. 0.35·period − 1.5, always ≥ 3 voxels
apart; mixed is bone-like: plates every 2 periods joined by vertical rods and horizontal struts. The
drawing is smoothed by a separable Gaussian (sigma, clamped borders), noise at two frequencies is
added (smooth value noise on a 16-voxel lattice, ±0.35·noise, and per-voxel noise, ±0.25·noise) and
the image is thresholded. Default object fractions at 256³: rods 4.5 %, plates 15 %, spheres 3.6 %,
mixed 6.5 %. All randomness comes from a counter-based hash of (seed, lattice cell / voxel):
results are identical for any thread count and machine. Memory: 5 bytes per voxel (float image +
mask) plus one (x, y) or (x, z) plane of floats per thread.)");
  }
  void run(RunContext& ctx) override {
    const auto o = ctx.options<NetworkOptions>();
    auto r = synthetic::make_network(o);
    ctx.output("image", std::move(r.image));
    ctx.output("mask", std::move(r.mask));
  }
};
SKEL_REGISTER_MODULE(Network);

class VesselTree final : public Module {
public:
  static ModuleSpec spec() {
    return ModuleSpec(names::vessel_tree, "Synthetic vessel network: arterial and venous trees joined by capillaries, with ground truth")
        .output<VolumeF32>("image", "smooth scalar image in about [0, 1] (vessels bright), plus noise")
        .output<VolumeU8>("mask", "image > 0.5 (0/1)")
        .output<SpatialGraph>("truth", "ground-truth graph (physical units): point attribute radius, edge label tree (0 artery, 1 vein, 2 capillary), node label kind (0 root, 1 branch, 2 end, 3 junction)")
        .output<SpatialGraph>("graph", "the same ground-truth graph as `truth` (the name other families use)")
        .output<Table>("nodes", "ground-truth nodes: id, x, y, z (physical), kind (root | branch | end | junction), degree")
        .output<Table>("edges", "ground-truth edges: id, node0, node1, length and radius (physical), tree (artery | vein | capillary)")
        .param("size", &VesselTreeOptions::size, "volume size [x, y, z]").range(16, 8192).unit("voxels")
        .param("seed", &VesselTreeOptions::seed, "random seed: the same seed gives the same network on any machine and thread count").min(0)
        .param("noise", &VesselTreeOptions::noise, "amplitude of noise at two frequencies (smooth 16-voxel value noise and per-voxel noise)").range(0, 1)
        .param("spacing", &VesselTreeOptions::spacing, "voxel size [x, y, z] in `unit`").min(1e-9)
        .param("unit", &VesselTreeOptions::unit, "physical unit of spacing, stored in the output grids, the truth graph and its tables")
        .param("roots", &VesselTreeOptions::roots, "number of trees (half arterial from the x = 0 face, half venous from the far face)").range(2, 64)
        .param("root_radius", &VesselTreeOptions::root_radius, "radius of the root vessels").min(1).unit("voxels")
        .param("min_radius", &VesselTreeOptions::min_radius, "branching stops below this radius; capillary radius").min(1).unit("voxels")
        .param("capillary_length", &VesselTreeOptions::capillary_length, "longest capillary joining two tree ends, before length_scale (up to 4x longer ones only join otherwise separate trees)").min(1).unit("voxels")
        .param("length_scale", &VesselTreeOptions::length_scale, "vessel and capillary lengths are multiplied by this; 0 = automatic, max(1, smallest size / 128)").min(0)
        .details(R"(Thesis §6.1 (India-ink filled microvessels). Trees grow from root points on the x faces:
each segment is about 5 radii long (× length_scale), then branches into two children at 25–45° whose
radius is 0.79 of the parent's (Murray's law for a symmetric split), until the radius falls below
min_radius. Capillaries (radius min_radius) join arterial ends to the nearest venous ends and to other
arterial ends, closing loops; then remaining separate trees are joined by longer capillaries.
The mask has exactly the topology of the ground-truth graph (one 26-connected component, no cavities,
tunnels = edges − nodes + 1; tested): a vessel is only added if it stays 4 voxels clear of every
vessel it is not connected to (exact segment distances), capillaries leave their end nodes at ≥ 35°
from the vessels already there and only close loops at least 14·(min_radius + 2) voxels long, and the
vessels of each node's star are blended by a smooth minimum (width 4 voxels) that fills the thin
crevices whose digitisation would trap background voxels. Rasterisation: signed distance to the
capsules (cylinders with spherical caps), profile 0.5·(1 − tanh(d / 0.7)), two-frequency noise, >0.5.
Ground truth (graph and tables) in physical units (radius × mean spacing). Memory: 5 bytes per voxel
(float image + mask). Thread count does not change the result.)");
  }
  void run(RunContext& ctx) override {
    const auto o = ctx.options<VesselTreeOptions>();
    auto r = synthetic::make_vessel_tree(o);
    ctx.output("image", std::move(r.image));
    ctx.output("mask", std::move(r.mask));
    DataPtr truth = std::make_shared<SpatialGraph>(std::move(r.truth));
    ctx.output("truth", truth);
    ctx.output("graph", truth);
    ctx.output("nodes", std::move(r.nodes));
    ctx.output("edges", std::move(r.edges));
  }
};
SKEL_REGISTER_MODULE(VesselTree);

}  // namespace
}  // namespace skel::synthetic
