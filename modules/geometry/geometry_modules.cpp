// Modules of the geometry family: skeleton → spatial graph and skeleton → mesh by dual cubes.
#include "geometry/mesh_filters.hpp"
#include "geometry/names.hpp"
#include "geometry/skeleton_to_graph.hpp"
#include "geometry/skeleton_to_mesh.hpp"
#include "skel/distributed.hpp"
#include "skel/module.hpp"

namespace skel::geometry {
namespace {

class SkeletonToGraphModule final : public Module {
public:
  static ModuleSpec spec() {
    return ModuleSpec(names::skeleton_to_graph, "Voxel skeleton to a spatial graph by dual cubes")
        .input<VolumeU8>("skeleton", "voxel skeleton (non-zero = skeleton voxel)")
        .optional_input<AnyVolume>("distance", "distance volume on the same grid; gives the point attribute radius")
        .output<SpatialGraph>("graph", "nodes at junctions/ends, edges with polylines in the skeleton's physical unit, radius per point")
        .output<VolumeU8>("manifold", "manifold type per voxel (only when with_manifold is true)")
        .param("smooth_passes", &SkeletonToGraphOptions::smooth_passes, "Gaussian smoothing passes over edge points (0 = off)")
        .min(0)
        .param("smooth_kernel", &SkeletonToGraphOptions::smooth_kernel, "smoothing window in points (>= 3)")
        .min(3)
        .param("radius_scale", &SkeletonToGraphOptions::radius_scale, "radius = distance value × radius_scale (1 for distances in the spacing unit)")
        .min(0)
        .param("with_manifold", &SkeletonToGraphOptions::want_manifold, "also output the manifold type volume")
        .details(
            "Thesis §3.1. Each object voxel is a 0-cell; 1-cells join 6-adjacent voxels always, 18-adjacent "
            "voxels when the other two voxels of their face are background, 26-adjacent voxels when they are "
            "the only two object voxels of their dual cube (fig. 3.6). In each dual cube, 2-cells fill the "
            "shortest cycles (all independent cycles of one length at once) until the cycle space is spanned; "
            "a 3-cell is added when χ = 2. Voxels are classified by their incident cells (fig. 3.9); codes of "
            "`manifold`: 0 background, 1 0-manifold (isolated voxel), 2 1-manifold, 3 1-boundary, 4 2-manifold, "
            "5 2-boundary, 6 junction, 7 1-x-junction (junction with a bare 1-cell). §3.1.2: a 2^8 table gives "
            "the 1-cells of each reduced dual cube, so every edge is generated once; connected voxels that "
            "are not 1-manifold/1-boundary collapse to one node at their centroid (node label `kind` = highest "
            "manifold code of its voxels); a tunnel inside such a component (a cycle of its 1-cells that does "
            "not bound its 2-cells, e.g. junction voxels around a hole) is kept as a loop edge on its node "
            "drawn along the cycle (the thesis collapses it; components with > 4096 internal 1-cells are "
            "collapsed as in the thesis); chains of 1-manifold voxels become edge polylines that start and end "
            "at their nodes; an isolated ring becomes one loop edge on a node (degree 2) at its first voxel "
            "(x-fastest order). Smoothing: Gaussian weights, sigma = kernel/4, end points fixed. Radius "
            "(§6.1 local thickness): point attribute `radius` = distance × radius_scale at each voxel; at a "
            "node the maximum over its voxels (also node attribute `radius`). Memory: the skeleton (1 B/voxel), "
            "~65 B per skeleton voxel, plus 1 B/voxel for `manifold`. Deterministic for any thread count. "
            "Block-wise under a memory budget (thesis ch. 5): the skeleton (and distance) are read in blocks "
            "with a one-voxel halo and each skeleton voxel is gathered with its 27-neighbourhood, i.e. every "
            "dual cube around it, so 1-cells, junctions, chains and loops crossing block faces, edges and "
            "corners are those of the whole volume; the phases then run on the gathered voxels and the graph, "
            "its radii and statistics are identical to in memory. Memory: one block with halo at 1 B/voxel "
            "(+ the distance's bytes + 1 B/voxel for `manifold`) plus ~65 B per skeleton voxel, resident "
            "(a 1 % skeleton of 1280³ voxels: ~1.4 GB; ~50 B while gathering), independent of the volume's size. "
            "With --resume a killed run keeps the blocks it gathered (20 bytes per skeleton voxel in the "
            "journal) and the finished blocks of `manifold`; the graph is built again from them. skelflow-mpi: "
            "the ranks gather the blocks (each its share, exchanged in block order) and write their blocks "
            "of `manifold`; every rank builds the same graph from the gathered voxels.")
        .blockwise(1, 10);
  }
  void run(RunContext& ctx) override {
    if (const BlockPlan* blocks = ctx.blocks()) {
      const DistributedStage stage;  // blocks gathered by the ranks (skelflow-mpi)
      const DataObject& skel_data = *ctx.input_data("skeleton");
      DataPtr dist = ctx.input_data("distance");
      const auto o = ctx.options<SkeletonToGraphOptions>();
      std::shared_ptr<ChunkedVolume> manifold;
      if (o.want_manifold)
        manifold = ctx.scratch_volume("manifold", type_ids::volume_u8, any_volume_grid(skel_data, "input 'skeleton'"));
      ctx.output("graph", skeleton_to_graph_blocks(skel_data, dist.get(), blocks->block, o, manifold.get()));
      if (manifold) ctx.output("manifold", DataPtr(std::move(manifold)));
      return;
    }
    auto skel_in = ctx.input<VolumeU8>("skeleton");
    DataPtr dist = ctx.input_data("distance");
    const auto o = ctx.options<SkeletonToGraphOptions>();
    auto r = skeleton_to_graph(*skel_in, dist.get(), o);
    ctx.output("graph", std::move(r.graph));
    if (o.want_manifold) ctx.output("manifold", std::move(r.manifold));
  }
};
SKEL_REGISTER_MODULE(SkeletonToGraphModule);

class SkeletonToMeshModule final : public Module {
public:
  static ModuleSpec spec() {
    return ModuleSpec(names::skeleton_to_mesh, "Voxel skeleton to surfaces and lines by dual cubes")
        .input<VolumeU8>("skeleton", "voxel skeleton (non-zero = skeleton voxel), e.g. a plate or mixed skeleton")
        .output<Mesh>("mesh", "triangles (plates) and polylines (rods) in physical units, with manifold classes")
        .param("improved", &SkeletonToMeshOptions::improved,
               "triangulate the dual cube cases 13, 14 and 18 without their enclosed volume (fig. 3.16)")
        .details(
            "Thesis §3.1.3. The cell complex of each dual cube (1-cells of fig. 3.6, 2-cells on the shortest "
            "cycles, as in geometry.skeleton_to_graph) is triangulated: a 2-cell of 3 voxels is a triangle, a "
            "longer one a fan around the centroid of its voxels (fig. 3.14); only the 2-cells of the reduced "
            "dual cube (corner 0, its three edges and faces, the interior) are made, so each triangle is made "
            "once (fig. 3.15). A lookup table over the 3^8 states of a cube's voxels (background; 2-manifold or "
            "2-boundary; other) gives the triangles and their class. With `improved`, case 13 (four voxels "
            "pairwise face-diagonal) becomes a cone from the cube centre over its six diagonals, case 14 (five "
            "voxels) three triangles around the body diagonal of its two degree-3 voxels, case 18 (six voxels) "
            "the full face plus a fin from the face centre to the opposite edge; face centres are shared "
            "between cubes through a 2x2x2 subdivided grid. Case 21 (a 2x2x2 block of voxels) keeps its "
            "volume. 1-cells that bound no 2-cell become polylines (chains broken where more or fewer than 2 "
            "meet). Attributes: vertex `manifold` (codes as in skeleton_to_graph: 2 1-manifold, 3 1-boundary, "
            "4 2-manifold, 5 2-boundary, 6 junction, 7 1-x-junction; face and cell centres 4 or 6), vertex "
            "`fixed` (1 at 1-x-junctions: keep them in place in geometry.mesh_smooth / mesh_decimate), triangle "
            "`manifold` (1 all-manifold: all voxels of its 2-cell are 2-manifold or 2-boundary, else 0), line "
            "`manifold` (1 when all its voxels are 1-manifold or 1-boundary). Isolated voxels give no "
            "geometry. Memory: the skeleton (1 B/voxel), ~450 B per plate voxel of the skeleton while scanning (less for lines), then the "
            "mesh (~30 B per triangle + 8 B per vertex and 4 B per triangle of attributes). Deterministic for "
            "any thread count.");
  }
  void run(RunContext& ctx) override {
    ctx.output("mesh", skeleton_to_mesh(*ctx.input<VolumeU8>("skeleton"), ctx.options<SkeletonToMeshOptions>()));
  }
};
SKEL_REGISTER_MODULE(SkeletonToMeshModule);

class MeshSmoothModule final : public Module {
public:
  static ModuleSpec spec() {
    return ModuleSpec(names::mesh_smooth, "Smooth a mesh (windowed sinc), marked vertices fixed")
        .input<Mesh>("mesh", "triangles and lines, e.g. from geometry.skeleton_to_mesh")
        .output<Mesh>("mesh", "the same triangles, lines and attributes at smoothed positions")
        .param("iterations", &MeshSmoothOptions::iterations, "windowed sinc iterations (0 = copy)")
        .min(0)
        .param("pass_band", &MeshSmoothOptions::pass_band, "pass band of the filter in (0, 2]; smaller smooths more")
        .min(0)
        .param("boundary_smoothing", &MeshSmoothOptions::boundary_smoothing, "also smooth surface boundaries")
        .param("fixed", &MeshSmoothOptions::fixed,
               "int vertex attribute marking vertices that stay in place (skeleton_to_mesh's 1-x-junctions); "
               "an absent attribute fixes nothing")
        .details(
            "Thesis §3.1.3 post-processing: VTK's vtkWindowedSincPolyDataFilter (Taubin's windowed sinc, "
            "coordinates normalised, non-manifold and line vertices smoothed too) over triangles and lines; "
            "the vertices marked in `fixed` get their input positions back, so the lines attached at "
            "1-x-junctions stay attached where the skeleton has them. Topology and attributes are unchanged. "
            "Memory: the mesh twice plus VTK's copy (~100 B per triangle).");
  }
  void run(RunContext& ctx) override {
    ctx.output("mesh", mesh_smooth(*ctx.input<Mesh>("mesh"), ctx.options<MeshSmoothOptions>()));
  }
};
SKEL_REGISTER_MODULE(MeshSmoothModule);

class MeshDecimateModule final : public Module {
public:
  static ModuleSpec spec() {
    return ModuleSpec(names::mesh_decimate, "Decimate a mesh (quadric error), marked vertices fixed")
        .input<Mesh>("mesh", "triangles and lines, e.g. from geometry.skeleton_to_mesh")
        .output<Mesh>("mesh", "fewer triangles; the lines as they were")
        .param("keep", &MeshDecimateOptions::keep, "fraction of the triangles to keep, in (0, 1] (0.02 = 2 %)")
        .min(0)
        .max(1)
        .param("fixed", &MeshDecimateOptions::fixed,
               "int vertex attribute marking vertices that stay in place (skeleton_to_mesh's 1-x-junctions); "
               "an absent attribute fixes nothing")
        .details(
            "Thesis §3.1.3 and §6.2 (bone meshes decimated to 1-2 % still show the plates): VTK's "
            "vtkQuadricDecimation (Garland and Heckbert 1997) of the triangles. Afterwards the output vertex "
            "nearest to each fixed surface vertex is put back at the fixed vertex's exact position and the lines "
            "ending there are attached to it, so rods stay attached to plates where the skeleton has them. Lines are kept unchanged. Vertex and triangle attributes are taken from the "
            "nearest input vertex and triangle (by centroid). Memory: the mesh, VTK's copy and its quadrics "
            "(~300 B per input triangle).");
  }
  void run(RunContext& ctx) override {
    ctx.output("mesh", mesh_decimate(*ctx.input<Mesh>("mesh"), ctx.options<MeshDecimateOptions>()));
  }
};
SKEL_REGISTER_MODULE(MeshDecimateModule);

class IsosurfaceModule final : public Module {
public:
  static ModuleSpec spec() {
    return ModuleSpec(names::isosurface, "Iso-surface of a volume (flying edges), for comparison")
        .input<AnyVolume>("volume", "image or mask (e.g. the voxel skeleton, to compare with skeleton_to_mesh)")
        .output<Mesh>("mesh", "closed triangle surface in physical units")
        .param("value", &IsosurfaceOptions::value, "iso-value (0.5 for a mask)")
        .details(
            "VTK's vtkFlyingEdges3D at `value`. The volume is padded with one voxel of its minimum value, so the "
            "surface is closed where the object touches the border. The surface bounds the voxels from both "
            "sides, so for a one-voxel-thick plate it has about twice the triangles of "
            "geometry.skeleton_to_mesh and encloses a thin volume (thesis §3.1: iso-surfaces are interfaces, "
            "not the skeleton's surface). Memory: 4 B/voxel (a float copy of the padded volume) plus the "
            "surface (~30 B per triangle).");
  }
  void run(RunContext& ctx) override {
    ctx.output("mesh", isosurface(*ctx.input_data("volume"), ctx.options<IsosurfaceOptions>()));
  }
};
SKEL_REGISTER_MODULE(IsosurfaceModule);

}  // namespace
}  // namespace skel::geometry
