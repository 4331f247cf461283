// Module of the geometry family that colours a skeleton mesh by a label volume (kept apart from
// geometry_modules.cpp).
#include "geometry/mesh_labels.hpp"
#include "geometry/names.hpp"
#include "skel/module.hpp"

namespace skel::geometry {
namespace {

struct MeshLabelsOptions {
  std::string attribute = "element";
};

class MeshLabelsModule final : public Module {
public:
  static ModuleSpec spec() {
    return ModuleSpec(names::mesh_labels, "Labels of a voxel volume onto the triangles, lines and vertices of a skeleton mesh")
        .input<Mesh>("mesh", "mesh of a voxel skeleton (geometry.skeleton_to_mesh), vertices still on voxel centres")
        .add_input("labels", all_volume_types(), "label volume on the skeleton's grid, e.g. analysis.rods_plates_elements elements or classes", true)
        .output<Mesh>("mesh", "the mesh with the int attribute `attribute` on vertices, triangles and lines")
        .param("attribute", &MeshLabelsOptions::attribute, "name of the new attribute (e.g. element or class)")
        .details(R"(Thesis fig. 6.14: rods and plates coloured per element on the skeleton's geometry. A mesh
vertex on a voxel centre (within a quarter voxel per axis) takes the label of that voxel (values
converted to int32); a triangle or line takes the most frequent non-zero label of its voxel vertices
(ties: the smallest; 0 when none is labelled); face-centre and centroid vertices take the label of their
first triangle. Run it before geometry.mesh_smooth and geometry.mesh_decimate, which move the vertices
off the voxel centres but carry the attributes along. The mesh and the labels must share their unit.
Memory: 4 bytes per vertex, triangle and line for the attribute plus 5 bytes per vertex while working.)");
  }
  void run(RunContext& ctx) override {
    Mesh mesh = *ctx.input<Mesh>("mesh");
    label_mesh(mesh, *ctx.input_data("labels"), ctx.options<MeshLabelsOptions>().attribute);
    ctx.output("mesh", std::move(mesh));
  }
};
SKEL_REGISTER_MODULE(MeshLabelsModule);

}  // namespace
}  // namespace skel::geometry
