#include "geometry/mesh_labels.hpp"

#include <algorithm>
#include <cmath>

#include "skel/error.hpp"
#include "skel/units.hpp"

namespace skel::geometry {

namespace {
// Most frequent non-zero value of vals (ties: the smallest), 0 when none.
int32_t majority(std::vector<int32_t>& vals) {
  std::sort(vals.begin(), vals.end());
  int32_t best = 0;
  size_t best_n = 0;
  for (size_t i = 0; i < vals.size();) {
    size_t j = i;
    while (j < vals.size() && vals[j] == vals[i]) ++j;
    if (vals[i] != 0 && j - i > best_n) {
      best = vals[i];
      best_n = j - i;
    }
    i = j;
  }
  return best;
}
}  // namespace

void label_mesh(Mesh& mesh, const DataObject& labels, const std::string& name) {
  const Grid& g = volume_grid(labels, "labels");
  units::check_same(mesh.unit, "mesh", g.unit, "labels");
  if (mesh.vertex_attributes.count(name) || mesh.triangle_attributes.count(name) || mesh.line_attributes.count(name))
    throw InputError("parameter 'attribute': the mesh already has an attribute '" + name + "'");
  const int64_t nv = mesh.vertex_count();
  std::vector<int32_t> vlabel(static_cast<size_t>(nv), 0);
  std::vector<uint8_t> on_voxel(static_cast<size_t>(nv), 0);
  visit_volume(labels, "labels", [&](const auto& vol) {
    for (int64_t v = 0; v < nv; ++v) {
      int64_t c[3];
      bool centre = true;
      for (int a = 0; a < 3; ++a) {
        const double f = (static_cast<double>(mesh.points[v][a]) - g.origin[a]) / g.spacing[a];
        c[a] = std::llround(f);
        centre = centre && std::abs(f - static_cast<double>(c[a])) <= 0.25;
      }
      if (!centre || !g.contains(c[0], c[1], c[2])) continue;
      on_voxel[v] = 1;
      vlabel[v] = static_cast<int32_t>(vol.at_or(c[0], c[1], c[2], 0));
    }
  });
  std::vector<int32_t> vals, tri(static_cast<size_t>(mesh.triangle_count()), 0);
  std::vector<uint8_t> set(static_cast<size_t>(nv), 0);
  for (int64_t t = 0; t < mesh.triangle_count(); ++t) {
    vals.clear();
    for (int64_t v : mesh.triangles[t])
      if (on_voxel[v]) vals.push_back(vlabel[v]);
    tri[t] = majority(vals);
    for (int64_t v : mesh.triangles[t])
      if (!on_voxel[v] && !set[v]) {
        vlabel[v] = tri[t];
        set[v] = 1;
      }
  }
  std::vector<int32_t> line(static_cast<size_t>(mesh.line_count()), 0);
  for (int64_t l = 0; l < mesh.line_count(); ++l) {
    vals.clear();
    for (int64_t k = mesh.line_offsets[l]; k < mesh.line_offsets[l + 1]; ++k)
      if (const int64_t v = mesh.line_vertices[k]; on_voxel[v]) vals.push_back(vlabel[v]);
    line[l] = majority(vals);
  }
  mesh.vertex_attributes[name] = std::move(vlabel);
  mesh.triangle_attributes[name] = std::move(tri);
  mesh.line_attributes[name] = std::move(line);
}

}  // namespace skel::geometry
