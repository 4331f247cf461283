#include "geometry/mesh_filters.hpp"

#include <algorithm>
#include <cmath>
#include <limits>

#include <vtkCellArray.h>
#include <vtkCellArrayIterator.h>
#include <vtkFloatArray.h>
#include <vtkFlyingEdges3D.h>
#include <vtkImageData.h>
#include <vtkPointData.h>
#include <vtkPoints.h>
#include <vtkPolyData.h>
#include <vtkQuadricDecimation.h>
#include <vtkSmartPointer.h>
#include <vtkStaticPointLocator.h>
#include <vtkWindowedSincPolyDataFilter.h>

#include "io/mesh_vtk.hpp"
#include "skel/error.hpp"
#include "skel/volume.hpp"

namespace skel::geometry {
namespace {

// Flags of the fixed vertices (all 0 when the attribute is absent).
std::vector<uint8_t> fixed_flags(const Mesh& m, const std::string& name) {
  std::vector<uint8_t> f(m.vertex_count(), 0);
  const auto it = m.vertex_attributes.find(name);
  if (name.empty() || it == m.vertex_attributes.end()) return f;
  const auto* v = std::get_if<std::vector<int32_t>>(&it->second);
  if (!v) throw InputError("parameter 'fixed': vertex attribute '" + name + "' is not an int attribute");
  for (int64_t i = 0; i < m.vertex_count(); ++i) f[i] = (*v)[i] != 0;
  return f;
}

void check_mesh(const Mesh& m) {
  const auto problems = m.check_invariants();
  if (!problems.empty()) throw InputError("input 'mesh': inconsistent mesh: " + problems.front());
}

// A locator over `pts`.
vtkSmartPointer<vtkStaticPointLocator> locator(const std::vector<Mesh::Point>& pts) {
  auto p = vtkSmartPointer<vtkPoints>::New();
  p->SetDataTypeToFloat();
  p->SetNumberOfPoints(static_cast<vtkIdType>(pts.size()));
  for (size_t i = 0; i < pts.size(); ++i) p->SetPoint(static_cast<vtkIdType>(i), pts[i][0], pts[i][1], pts[i][2]);
  auto poly = vtkSmartPointer<vtkPolyData>::New();
  poly->SetPoints(p);
  auto loc = vtkSmartPointer<vtkStaticPointLocator>::New();
  loc->SetDataSet(poly);
  loc->BuildLocator();
  return loc;
}

// Copies element `from` of every attribute array of `src` to the end of the arrays of `dst`.
void append_values(MeshAttributes& dst, const MeshAttributes& src, int64_t from) {
  for (const auto& entry : src)
    std::visit([&](const auto& v) {
      using V = std::decay_t<decltype(v)>;
      const std::string& name = entry.first;  // no structured binding: clang 14 cannot capture one
      auto it = dst.find(name);
      if (it == dst.end()) it = dst.emplace(name, V{}).first;
      std::get<V>(it->second).push_back(v[from]);
    }, entry.second);
}

}  // namespace

Mesh mesh_smooth(const Mesh& mesh, const MeshSmoothOptions& o) {
  check_mesh(mesh);
  if (o.iterations < 0) throw InputError("parameter 'iterations': must be >= 0");
  if (!(o.pass_band > 0.0 && o.pass_band <= 2.0)) throw InputError("parameter 'pass_band': must be in (0, 2]");
  const auto fixed = fixed_flags(mesh, o.fixed);
  Mesh out = mesh;
  if (o.iterations == 0 || mesh.vertex_count() == 0) return out;
  auto poly = io::mesh_to_vtk(mesh);
  auto f = vtkSmartPointer<vtkWindowedSincPolyDataFilter>::New();
  f->SetInputData(poly);
  f->SetNumberOfIterations(o.iterations);
  f->SetPassBand(o.pass_band);
  f->NormalizeCoordinatesOn();
  f->SetBoundarySmoothing(o.boundary_smoothing);
  f->NonManifoldSmoothingOn();
  f->FeatureEdgeSmoothingOff();
  f->Update();
  vtkPolyData* r = f->GetOutput();
  if (r->GetNumberOfPoints() != mesh.vertex_count()) throw Error("mesh_smooth: VTK's filter changed the vertex count");
  for (int64_t v = 0; v < mesh.vertex_count(); ++v) {
    if (fixed[v]) continue;
    double p[3];
    r->GetPoint(v, p);
    out.points[v] = {static_cast<float>(p[0]), static_cast<float>(p[1]), static_cast<float>(p[2])};
  }
  return out;
}

Mesh mesh_decimate(const Mesh& mesh, const MeshDecimateOptions& o) {
  check_mesh(mesh);
  if (!(o.keep > 0.0 && o.keep <= 1.0)) throw InputError("parameter 'keep': must be in (0, 1]");
  const auto fixed = fixed_flags(mesh, o.fixed);
  // Triangles only. (VTK 9.1's attribute error metric, which could weight the fixed flag into the
  // quadrics, stops decimating planar regions, "Unable to factor linear system": fixed vertices are
  // put back after the decimation instead.)
  Mesh tri = mesh;
  tri.line_offsets = {0};
  tri.line_vertices.clear();
  tri.vertex_attributes.clear();
  tri.triangle_attributes.clear();
  tri.line_attributes.clear();
  auto poly = io::mesh_to_vtk(tri);
  Mesh out;
  out.unit = mesh.unit;
  out.frame_origin = mesh.frame_origin;
  out.frame_direction = mesh.frame_direction;
  if (mesh.triangle_count() > 0) {
    auto d = vtkSmartPointer<vtkQuadricDecimation>::New();
    d->SetInputData(poly);
    d->SetTargetReduction(1.0 - o.keep);
    d->AttributeErrorMetricOff();
    d->VolumePreservationOff();
    d->Update();
    vtkPolyData* r = d->GetOutput();
    out.points.resize(r->GetNumberOfPoints());
    for (vtkIdType v = 0; v < r->GetNumberOfPoints(); ++v) {
      double p[3];
      r->GetPoint(v, p);
      out.points[v] = {static_cast<float>(p[0]), static_cast<float>(p[1]), static_cast<float>(p[2])};
    }
    auto it = vtk::TakeSmartPointer(r->GetPolys()->NewIterator());
    for (it->GoToFirstCell(); !it->IsDoneWithTraversal(); it->GoToNextCell()) {
      vtkIdType n;
      const vtkIdType* ids;
      it->GetCurrentCell(n, ids);
      for (vtkIdType i = 2; i < n; ++i) out.add_triangle(ids[0], ids[i - 1], ids[i]);
    }
  }
  // Attributes from the nearest input vertex; fixed vertices back at their exact place.
  std::vector<int64_t> source(out.vertex_count(), -1);
  std::vector<int64_t> fixed_to(mesh.vertex_count(), -1);
  if (out.vertex_count() > 0) {
    auto in_loc = locator(mesh.points);
    for (int64_t v = 0; v < out.vertex_count(); ++v) {
      const double p[3] = {out.points[v][0], out.points[v][1], out.points[v][2]};
      source[v] = in_loc->FindClosestPoint(p);
    }
    auto out_loc = locator(out.points);
    std::vector<uint8_t> surf(mesh.vertex_count(), 0);
    for (const auto& t : mesh.triangles) surf[t[0]] = surf[t[1]] = surf[t[2]] = 1;
    for (int64_t v = 0; v < mesh.vertex_count(); ++v) {
      if (!fixed[v] || !surf[v]) continue;
      const double p[3] = {mesh.points[v][0], mesh.points[v][1], mesh.points[v][2]};
      const int64_t w = out_loc->FindClosestPoint(p);
      out.points[w] = mesh.points[v];
      source[w] = v;
      fixed_to[v] = w;
    }
  }
  for (int64_t v = 0; v < out.vertex_count(); ++v) append_values(out.vertex_attributes, mesh.vertex_attributes, source[v]);
  if (out.triangle_count() > 0 && !mesh.triangle_attributes.empty()) {
    std::vector<Mesh::Point> centres(mesh.triangles.size());
    for (size_t t = 0; t < mesh.triangles.size(); ++t)
      for (int a = 0; a < 3; ++a)
        centres[t][a] = (mesh.points[mesh.triangles[t][0]][a] + mesh.points[mesh.triangles[t][1]][a] +
                         mesh.points[mesh.triangles[t][2]][a]) / 3.0f;
    auto tloc = locator(centres);
    for (const auto& t : out.triangles) {
      double c[3];
      for (int a = 0; a < 3; ++a) c[a] = (double(out.points[t[0]][a]) + out.points[t[1]][a] + out.points[t[2]][a]) / 3.0;
      append_values(out.triangle_attributes, mesh.triangle_attributes, tloc->FindClosestPoint(c));
    }
  }
  // Lines as they were; their vertices appended, a fixed one mapped onto its surface vertex.
  std::vector<int64_t> line_vertex(mesh.vertex_count(), -1);
  for (int64_t l = 0; l < mesh.line_count(); ++l) {
    std::vector<int64_t> ids;
    for (int64_t i = mesh.line_offsets[l]; i < mesh.line_offsets[l + 1]; ++i) {
      const int64_t v = mesh.line_vertices[i];
      if (fixed_to[v] >= 0) {
        ids.push_back(fixed_to[v]);
        continue;
      }
      if (line_vertex[v] < 0) {
        line_vertex[v] = out.add_vertex(mesh.points[v]);
        append_values(out.vertex_attributes, mesh.vertex_attributes, v);
      }
      ids.push_back(line_vertex[v]);
    }
    out.add_line(ids);
    append_values(out.line_attributes, mesh.line_attributes, l);
  }
  // Attributes that had no element to take a value from are still present (empty, the right size).
  auto keep_names = [](MeshAttributes& dst, const MeshAttributes& src) {
    for (const auto& [name, a] : src)
      if (!dst.count(name)) dst.emplace(name, std::visit([](const auto& v) { return MeshAttribute(std::decay_t<decltype(v)>{}); }, a));
  };
  keep_names(out.vertex_attributes, mesh.vertex_attributes);
  keep_names(out.triangle_attributes, mesh.triangle_attributes);
  keep_names(out.line_attributes, mesh.line_attributes);
  return out;
}

Mesh isosurface(const DataObject& volume, const IsosurfaceOptions& o) {
  return visit_volume(volume, "volume", [&](const auto& v) {
    const int64_t nx = v.nx() + 2, ny = v.ny() + 2, nz = v.nz() + 2;
    if (nx > std::numeric_limits<int>::max() || ny > std::numeric_limits<int>::max() || nz > std::numeric_limits<int>::max())
      throw InputError("input 'volume': too large for VTK's image data");
    double lo = 0.0;
    if (v.size() > 0) lo = static_cast<double>(*std::min_element(v.data(), v.data() + v.size()));
    auto img = vtkSmartPointer<vtkImageData>::New();
    img->SetDimensions(static_cast<int>(nx), static_cast<int>(ny), static_cast<int>(nz));
    img->SetSpacing(v.spacing()[0], v.spacing()[1], v.spacing()[2]);
    img->SetOrigin(v.origin()[0] - v.spacing()[0], v.origin()[1] - v.spacing()[1], v.origin()[2] - v.spacing()[2]);
    auto s = vtkSmartPointer<vtkFloatArray>::New();
    s->SetName("value");
    s->SetNumberOfTuples(nx * ny * nz);
    float* d = s->GetPointer(0);
    std::fill(d, d + nx * ny * nz, static_cast<float>(lo));
    for (int64_t z = 0; z < v.nz(); ++z)
      for (int64_t y = 0; y < v.ny(); ++y)
        for (int64_t x = 0; x < v.nx(); ++x)
          d[(x + 1) + nx * ((y + 1) + ny * (z + 1))] = static_cast<float>(v(x, y, z));
    img->GetPointData()->SetScalars(s);
    auto fe = vtkSmartPointer<vtkFlyingEdges3D>::New();
    fe->SetInputData(img);
    fe->SetValue(0, o.value);
    fe->ComputeNormalsOff();
    fe->ComputeGradientsOff();
    fe->ComputeScalarsOff();
    fe->Update();
    Mesh m = io::mesh_from_vtk(*fe->GetOutput(), "isosurface");
    m.unit = v.unit();
    m.frame_origin = v.origin();
    m.frame_direction = v.grid().direction;
    m.vertex_attributes.clear();
    m.triangle_attributes.clear();
    return m;
  });
}

}  // namespace skel::geometry
