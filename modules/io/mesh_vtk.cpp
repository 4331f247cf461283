#include "io/mesh_vtk.hpp"

#include <algorithm>
#include <cmath>
#include <set>

#include <vtkCellArray.h>
#include <vtkCellArrayIterator.h>
#include <vtkCellData.h>
#include <vtkDataArray.h>
#include <vtkFieldData.h>
#include <vtkFloatArray.h>
#include <vtkIdList.h>
#include <vtkIntArray.h>
#include <vtkPointData.h>
#include <vtkPoints.h>
#include <vtkStringArray.h>
#include <vtkType.h>

#include "skel/error.hpp"

namespace skel::io {
namespace {

constexpr const char* kTriangleNames = "skelflow_triangle_attributes";
constexpr const char* kLineNames = "skelflow_line_attributes";

// A VTK array of `n` values: `lead` zeros, then the attribute's values (or zeros when absent), then
// zeros up to n.
vtkSmartPointer<vtkDataArray> make_array(const std::string& name, const MeshAttribute* first, int64_t n_first,
                                         const MeshAttribute* second, int64_t n_second, bool integer) {
  vtkSmartPointer<vtkDataArray> arr;
  if (integer) arr = vtkSmartPointer<vtkIntArray>::New();
  else arr = vtkSmartPointer<vtkFloatArray>::New();
  arr->SetName(name.c_str());
  arr->SetNumberOfComponents(1);
  arr->SetNumberOfTuples(n_first + n_second);
  auto fill = [&](const MeshAttribute* a, int64_t off, int64_t n) {
    for (int64_t i = 0; i < n; ++i) {
      double v = 0.0;
      if (a) v = std::visit([&](const auto& vec) { return static_cast<double>(vec[i]); }, *a);
      arr->SetComponent(off + i, 0, v);
    }
  };
  fill(first, 0, n_first);
  fill(second, n_first, n_second);
  return arr;
}

bool is_integer(const MeshAttribute& a) { return std::holds_alternative<std::vector<int32_t>>(a); }

void add_name_list(vtkFieldData* fd, const char* key, const MeshAttributes& m) {
  auto s = vtkSmartPointer<vtkStringArray>::New();
  s->SetName(key);
  for (const auto& [n, a] : m) s->InsertNextValue(n);
  fd->AddArray(s);
}

MeshAttribute read_array(vtkDataArray* arr, int64_t begin, const std::vector<int64_t>& cells) {
  if (arr->GetDataType() != VTK_FLOAT && arr->GetDataType() != VTK_DOUBLE) {
    std::vector<int32_t> v(cells.size());
    for (size_t i = 0; i < cells.size(); ++i) v[i] = static_cast<int32_t>(arr->GetComponent(begin + cells[i], 0));
    return v;
  }
  std::vector<float> v(cells.size());
  for (size_t i = 0; i < cells.size(); ++i) v[i] = static_cast<float>(arr->GetComponent(begin + cells[i], 0));
  return v;
}

}  // namespace

vtkSmartPointer<vtkPolyData> mesh_to_vtk(const Mesh& mesh) {
  auto poly = vtkSmartPointer<vtkPolyData>::New();
  auto pts = vtkSmartPointer<vtkPoints>::New();
  pts->SetDataTypeToFloat();
  pts->SetNumberOfPoints(mesh.vertex_count());
  for (int64_t v = 0; v < mesh.vertex_count(); ++v) pts->SetPoint(v, mesh.points[v][0], mesh.points[v][1], mesh.points[v][2]);
  poly->SetPoints(pts);
  if (mesh.line_count() > 0) {
    auto lines = vtkSmartPointer<vtkCellArray>::New();
    for (int64_t l = 0; l < mesh.line_count(); ++l) {
      const int64_t b = mesh.line_offsets[l], e = mesh.line_offsets[l + 1];
      lines->InsertNextCell(static_cast<vtkIdType>(e - b));
      for (int64_t i = b; i < e; ++i) lines->InsertCellPoint(mesh.line_vertices[i]);
    }
    poly->SetLines(lines);
  }
  if (mesh.triangle_count() > 0) {
    auto tris = vtkSmartPointer<vtkCellArray>::New();
    tris->AllocateExact(mesh.triangle_count(), 3 * mesh.triangle_count());
    for (const auto& t : mesh.triangles) {
      const vtkIdType ids[3] = {t[0], t[1], t[2]};
      tris->InsertNextCell(3, ids);
    }
    poly->SetPolys(tris);
  }
  for (const auto& [name, a] : mesh.vertex_attributes)
    poly->GetPointData()->AddArray(make_array(name, &a, mesh.vertex_count(), nullptr, 0, is_integer(a)));
  std::set<std::string, std::less<>> cell_names;
  for (const auto& [n, a] : mesh.triangle_attributes) cell_names.insert(n);
  for (const auto& [n, a] : mesh.line_attributes) cell_names.insert(n);
  for (const auto& name : cell_names) {
    const auto lt = mesh.line_attributes.find(name);
    const auto tt = mesh.triangle_attributes.find(name);
    const MeshAttribute* la = lt == mesh.line_attributes.end() ? nullptr : &lt->second;
    const MeshAttribute* ta = tt == mesh.triangle_attributes.end() ? nullptr : &tt->second;
    const bool integer = (la == nullptr || is_integer(*la)) && (ta == nullptr || is_integer(*ta));
    poly->GetCellData()->AddArray(make_array(name, la, mesh.line_count(), ta, mesh.triangle_count(), integer));
  }
  auto* fd = poly->GetFieldData();
  add_name_list(fd, kTriangleNames, mesh.triangle_attributes);
  add_name_list(fd, kLineNames, mesh.line_attributes);
  auto unit = vtkSmartPointer<vtkStringArray>::New();
  unit->SetName("unit");
  unit->InsertNextValue(mesh.unit);
  fd->AddArray(unit);
  return poly;
}

Mesh mesh_from_vtk(vtkPolyData& poly, const std::string& what) {
  Mesh m;
  const int64_t np = poly.GetNumberOfPoints();
  m.points.resize(np);
  for (int64_t v = 0; v < np; ++v) {
    double p[3];
    poly.GetPoint(v, p);
    for (int a = 0; a < 3; ++a) {
      if (!std::isfinite(p[a])) throw InputError(what + ": point " + std::to_string(v) + " is not finite");
      m.points[v][a] = static_cast<float>(p[a]);
    }
  }
  auto check_id = [&](vtkIdType id) {
    if (id < 0 || id >= np)
      throw InputError(what + ": a cell names point " + std::to_string(id) + " of " + std::to_string(np));
    return static_cast<int64_t>(id);
  };
  const int64_t n_verts = poly.GetNumberOfVerts(), n_lines = poly.GetNumberOfLines(),
                n_polys = poly.GetNumberOfPolys();
  // Cell data rows: verts, lines, polys, strips. Source row of each line and triangle.
  std::vector<int64_t> line_rows, tri_rows;
  {
    auto it = vtk::TakeSmartPointer(poly.GetLines()->NewIterator());
    int64_t row = 0;
    for (it->GoToFirstCell(); !it->IsDoneWithTraversal(); it->GoToNextCell(), ++row) {
      vtkIdType n;
      const vtkIdType* ids;
      it->GetCurrentCell(n, ids);
      if (n < 2) continue;
      std::vector<int64_t> l(static_cast<size_t>(n));
      for (vtkIdType i = 0; i < n; ++i) l[i] = check_id(ids[i]);
      m.add_line(l);
      line_rows.push_back(row);
    }
  }
  {
    auto it = vtk::TakeSmartPointer(poly.GetPolys()->NewIterator());
    int64_t row = 0;
    for (it->GoToFirstCell(); !it->IsDoneWithTraversal(); it->GoToNextCell(), ++row) {
      vtkIdType n;
      const vtkIdType* ids;
      it->GetCurrentCell(n, ids);
      for (vtkIdType i = 2; i < n; ++i) {
        m.add_triangle(check_id(ids[0]), check_id(ids[i - 1]), check_id(ids[i]));
        tri_rows.push_back(row);
      }
    }
  }
  {
    const int64_t strip_base = n_polys;
    auto it = vtk::TakeSmartPointer(poly.GetStrips()->NewIterator());
    int64_t row = 0;
    for (it->GoToFirstCell(); !it->IsDoneWithTraversal(); it->GoToNextCell(), ++row) {
      vtkIdType n;
      const vtkIdType* ids;
      it->GetCurrentCell(n, ids);
      for (vtkIdType i = 2; i < n; ++i) {
        if (i % 2 == 0) m.add_triangle(check_id(ids[i - 2]), check_id(ids[i - 1]), check_id(ids[i]));
        else m.add_triangle(check_id(ids[i - 1]), check_id(ids[i - 2]), check_id(ids[i]));
        tri_rows.push_back(strip_base + row);
      }
    }
  }
  auto* pd = poly.GetPointData();
  std::vector<int64_t> all_points(static_cast<size_t>(np));
  for (int64_t v = 0; v < np; ++v) all_points[v] = v;
  for (int i = 0; i < pd->GetNumberOfArrays(); ++i) {
    vtkDataArray* a = pd->GetArray(i);
    if (!a || !a->GetName() || a->GetNumberOfComponents() != 1) continue;
    m.vertex_attributes[a->GetName()] = read_array(a, 0, all_points);
  }
  auto* fd = poly.GetFieldData();
  auto names_of = [&](const char* key, bool& present) {
    std::set<std::string, std::less<>> out;
    auto* s = vtkStringArray::SafeDownCast(fd->GetAbstractArray(key));
    present = s != nullptr;
    if (s)
      for (vtkIdType i = 0; i < s->GetNumberOfValues(); ++i) out.insert(s->GetValue(i));
    return out;
  };
  bool have_t = false, have_l = false;
  const auto tri_names = names_of(kTriangleNames, have_t);
  const auto line_names = names_of(kLineNames, have_l);
  const bool listed = have_t && have_l;
  auto* cd = poly.GetCellData();
  for (int i = 0; i < cd->GetNumberOfArrays(); ++i) {
    vtkDataArray* a = cd->GetArray(i);
    if (!a || !a->GetName() || a->GetNumberOfComponents() != 1) continue;
    const std::string name = a->GetName();
    if (listed ? line_names.count(name) > 0 : m.line_count() > 0)
      m.line_attributes[name] = read_array(a, n_verts, line_rows);
    if (listed ? tri_names.count(name) > 0 : m.triangle_count() > 0)
      m.triangle_attributes[name] = read_array(a, n_verts + n_lines, tri_rows);
  }
  if (auto* u = vtkStringArray::SafeDownCast(fd->GetAbstractArray("unit")); u && u->GetNumberOfValues() == 1)
    m.unit = u->GetValue(0);
  return m;
}

}  // namespace skel::io
