#include "vtk_convert.hpp"

#include <vtkCellArray.h>
#include <vtkCellData.h>
#include <vtkDataArray.h>
#include <vtkFloatArray.h>
#include <vtkPointData.h>
#include <vtkPoints.h>
#include <vtkType.h>

#include <set>
#include <type_traits>

#include "skel/volume.hpp"

namespace skel::render {

namespace {

template <class T>
constexpr int vtk_type() {
  if constexpr (std::is_same_v<T, uint8_t>) return VTK_UNSIGNED_CHAR;
  else if constexpr (std::is_same_v<T, uint16_t>) return VTK_UNSIGNED_SHORT;
  else if constexpr (std::is_same_v<T, uint32_t>) return VTK_UNSIGNED_INT;
  else if constexpr (std::is_same_v<T, uint64_t>) return VTK_UNSIGNED_LONG_LONG;
  else if constexpr (std::is_same_v<T, int32_t>) return VTK_INT;
  else if constexpr (std::is_same_v<T, float>) return VTK_FLOAT;
  else return VTK_DOUBLE;
}

// A VTK array over the volume's voxels, sharing the memory (save = 1: VTK never frees it).
template <class T>
vtkSmartPointer<vtkDataArray> wrap(const Volume<T>& v) {
  vtkSmartPointer<vtkDataArray> a = vtkSmartPointer<vtkDataArray>::Take(vtkDataArray::CreateDataArray(vtk_type<T>()));
  a->SetNumberOfComponents(1);
  a->SetVoidArray(const_cast<T*>(v.data()), static_cast<vtkIdType>(v.size()), 1);
  a->SetName("voxels");
  return a;
}

}  // namespace

vtkSmartPointer<vtkImageData> volume_to_image(const DataObject& data) {
  return visit_volume(data, "3D view", [](const auto& v) {
    auto image = vtkSmartPointer<vtkImageData>::New();
    image->SetDimensions(static_cast<int>(v.nx()), static_cast<int>(v.ny()), static_cast<int>(v.nz()));
    image->SetSpacing(v.spacing()[0], v.spacing()[1], v.spacing()[2]);
    image->SetOrigin(v.origin()[0], v.origin()[1], v.origin()[2]);
    image->GetPointData()->SetScalars(wrap(v));
    return image;
  });
}

vtkSmartPointer<vtkImageData> volume_to_cell_image(const DataObject& data) {
  return visit_volume(data, "3D view", [](const auto& v) {
    auto image = vtkSmartPointer<vtkImageData>::New();
    image->SetDimensions(static_cast<int>(v.nx() + 1), static_cast<int>(v.ny() + 1), static_cast<int>(v.nz() + 1));
    const auto& s = v.spacing();
    const auto& o = v.origin();
    image->SetSpacing(s[0], s[1], s[2]);
    image->SetOrigin(o[0] - 0.5 * s[0], o[1] - 0.5 * s[1], o[2] - 0.5 * s[2]);
    image->GetCellData()->SetScalars(wrap(v));
    return image;
  });
}

bool is_binary_volume(const DataObject& data) {
  const auto* v = dynamic_cast<const VolumeU8*>(&data);
  if (!v) return false;
  for (uint8_t x : *v) {
    if (x > 1) return false;
  }
  return true;
}

std::vector<std::string> graph_attribute_names(const SpatialGraph& g) {
  std::set<std::string> names;
  for (const auto& [name, values] : g.point_attributes) names.insert(name);
  for (const auto& [name, values] : g.edge_attributes) names.insert(name);
  for (const auto& [name, values] : g.edge_labels) names.insert(name);
  return {names.begin(), names.end()};
}

vtkSmartPointer<vtkPolyData> graph_to_polydata(const SpatialGraph& g) {
  auto points = vtkSmartPointer<vtkPoints>::New();
  points->SetDataTypeToDouble();
  points->SetNumberOfPoints(static_cast<vtkIdType>(g.point_count()));
  auto lines = vtkSmartPointer<vtkCellArray>::New();
  vtkIdType next = 0;
  for (const auto& e : g.edges) {
    lines->InsertNextCell(static_cast<int>(e.points.size()));
    for (const auto& p : e.points) {
      points->SetPoint(next, p[0], p[1], p[2]);
      lines->InsertCellPoint(next++);
    }
  }
  auto poly = vtkSmartPointer<vtkPolyData>::New();
  poly->SetPoints(points);
  poly->SetLines(lines);

  auto point_array = [&](const std::string& name) {
    auto a = vtkSmartPointer<vtkFloatArray>::New();
    a->SetName(name.c_str());
    a->SetNumberOfTuples(next);
    poly->GetPointData()->AddArray(a);
    return a;
  };
  auto cell_array = [&](const std::string& name) {
    auto a = vtkSmartPointer<vtkFloatArray>::New();
    a->SetName(name.c_str());
    a->SetNumberOfTuples(static_cast<vtkIdType>(g.edges.size()));
    poly->GetCellData()->AddArray(a);
    return a;
  };
  for (const auto& [name, values] : g.point_attributes) {
    auto a = point_array(name);
    vtkIdType i = 0;
    for (size_t e = 0; e < g.edges.size(); ++e) {
      for (size_t k = 0; k < g.edges[e].points.size(); ++k) {
        a->SetValue(i++, e < values.size() && k < values[e].size() ? values[e][k] : 0.0f);
      }
    }
  }
  auto per_edge = [&](const std::string& name, auto const& values) {
    if (g.point_attributes.count(name)) return;  // the point attribute is finer
    auto a = point_array(name);
    auto c = cell_array(name);
    vtkIdType i = 0;
    for (size_t e = 0; e < g.edges.size(); ++e) {
      const float v = e < values.size() ? static_cast<float>(values[e]) : 0.0f;
      c->SetValue(static_cast<vtkIdType>(e), v);
      for (size_t k = 0; k < g.edges[e].points.size(); ++k) a->SetValue(i++, v);
    }
  };
  for (const auto& [name, values] : g.edge_attributes) per_edge(name, values);
  for (const auto& [name, values] : g.edge_labels) per_edge(name, values);
  return poly;
}

}  // namespace skel::render
