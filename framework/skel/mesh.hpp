#pragma once
// Mesh: triangles and polylines over one vertex array, with named per-vertex, per-triangle and
// per-line attributes (type id "mesh"). The geometry of skeletons (thesis §3.1.3, §3.2): surfaces of
// plate skeletons, lines of rod skeletons, iso-surfaces. VTK-free: converted to vtkPolyData only at
// the file and view boundary (io/mesh_vtk.hpp).
//
// Storage (structure of arrays, plain value semantics like Volume and SpatialGraph):
//   - points[v]: (x, y, z) as float, physical units (`unit`, "µm" by default); 12 B per vertex.
//   - triangles[t]: three vertex ids (64-bit); 24 B per triangle.
//   - lines: polylines in compressed form: line l runs through line_vertices[line_offsets[l] ..
//     line_offsets[l+1]) (>= 2 vertices); 8 B per line vertex + 8 B per line.
//   - attributes: int32 or float arrays, one value per vertex / triangle / line (4 B each per element).
// A closed surface of T triangles has about T/2 vertices, so a triangle costs about 24 + 6 = 30 B plus
// 4 B per triangle attribute and 2 B per vertex attribute (skeleton_to_mesh's `manifold` and `fixed`:
// about 38 B per triangle in all).
#include <array>
#include <cstdint>
#include <map>
#include <string>
#include <string_view>
#include <variant>
#include <vector>

#include "skel/data.hpp"
#include "skel/error.hpp"
#include "skel/volume.hpp"

namespace skel {

// One attribute array: int32 labels (classes, flags) or float values.
using MeshAttribute = std::variant<std::vector<int32_t>, std::vector<float>>;
using MeshAttributes = std::map<std::string, MeshAttribute, std::less<>>;

// Number of values of an attribute array.
inline int64_t attribute_size(const MeshAttribute& a) {
  return std::visit([](const auto& v) { return static_cast<int64_t>(v.size()); }, a);
}

class Mesh final : public DataObject {
public:
  using Point = std::array<float, 3>;
  using Triangle = std::array<int64_t, 3>;

  std::vector<Point> points;
  std::vector<Triangle> triangles;
  std::vector<int64_t> line_offsets{0};  // line_count() + 1 entries, first 0
  std::vector<int64_t> line_vertices;
  MeshAttributes vertex_attributes;    // values[v]
  MeshAttributes triangle_attributes;  // values[t]
  MeshAttributes line_attributes;      // values[l]
  std::string unit = kDefaultUnit;
  // Where the source volume lies: points are in its axis-aligned frame (origin + index·spacing, like
  // its voxels, which the GUI and the algorithms use); mesh files hold world coordinates,
  // world_position(p, frame_origin, frame_direction) (io::write_mesh), so that the mesh overlays the
  // image in Slicer or ParaView. A mesh read from a file is in world coordinates (identity).
  Vec3 frame_origin{0.0, 0.0, 0.0};
  Direction frame_direction{kIdentityDirection};

  [[nodiscard]] int64_t vertex_count() const { return static_cast<int64_t>(points.size()); }
  [[nodiscard]] int64_t triangle_count() const { return static_cast<int64_t>(triangles.size()); }
  [[nodiscard]] int64_t line_count() const { return static_cast<int64_t>(line_offsets.size()) - 1; }

  int64_t add_vertex(const Point& p) {
    points.push_back(p);
    return vertex_count() - 1;
  }
  int64_t add_triangle(int64_t a, int64_t b, int64_t c) {
    triangles.push_back({a, b, c});
    return triangle_count() - 1;
  }
  // Appends a polyline through `ids` (>= 2 vertices); returns its id.
  int64_t add_line(const std::vector<int64_t>& ids);

  // Typed access to an attribute array (throws Error when it is missing or of the other type).
  template <class T>
  [[nodiscard]] static const std::vector<T>& attribute(const MeshAttributes& m, std::string_view name) {
    const auto it = m.find(name);
    if (it == m.end()) throw Error("mesh has no attribute '" + std::string(name) + "'");
    const auto* v = std::get_if<std::vector<T>>(&it->second);
    if (!v) throw Error("mesh attribute '" + std::string(name) + "' has another value type");
    return *v;
  }

  // What is inconsistent (vertex ids out of range, a line of < 2 vertices, offsets not ascending,
  // attribute sizes, non-finite points); empty when the mesh is valid.
  [[nodiscard]] std::vector<std::string> check_invariants() const;

  [[nodiscard]] std::string type_id() const override { return type_ids::mesh; }
  [[nodiscard]] uint64_t bytes() const override;
  [[nodiscard]] std::string describe() const override;
  [[nodiscard]] std::string physical_unit() const override { return unit; }
};

bool operator==(const Mesh& a, const Mesh& b);

}  // namespace skel
