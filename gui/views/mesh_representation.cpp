#include "mesh_representation.hpp"

#include <QComboBox>
#include <QDoubleSpinBox>
#include <QFormLayout>
#include <QWidget>

#include <vtkActor.h>
#include <vtkCellData.h>
#include <vtkDataArray.h>
#include <vtkLookupTable.h>
#include <vtkPointData.h>
#include <vtkPolyData.h>
#include <vtkPolyDataMapper.h>
#include <vtkProperty.h>
#include <vtkScalarBarActor.h>
#include <vtkTubeFilter.h>

#include <algorithm>
#include <cmath>

#include "io/mesh_vtk.hpp"

namespace skel::gui {
namespace {

// The mesh's triangles or lines alone, with the vertex attributes and their own attributes.
vtkSmartPointer<vtkPolyData> part(const Mesh& m, bool triangles) {
  Mesh p;
  p.points = m.points;
  p.vertex_attributes = m.vertex_attributes;
  p.unit = m.unit;
  if (triangles) {
    p.triangles = m.triangles;
    p.triangle_attributes = m.triangle_attributes;
  } else {
    p.line_offsets = m.line_offsets;
    p.line_vertices = m.line_vertices;
    p.line_attributes = m.line_attributes;
  }
  return io::mesh_to_vtk(p);
}

}  // namespace

MeshRepresentation::MeshRepresentation(const QString& name, const std::shared_ptr<const Mesh>& mesh, const Color& color)
    : Representation(name, mesh, color), mesh_(mesh), surface_(part(*mesh, true)), lines_(part(*mesh, false)) {
  if (mesh->triangle_attributes.count("manifold")) color_by_ = "triangle:manifold";
  else if (mesh->line_attributes.count("manifold")) color_by_ = "line:manifold";
  double b[6];
  surface_->GetBounds(b);
  const double diag = std::sqrt((b[1] - b[0]) * (b[1] - b[0]) + (b[3] - b[2]) * (b[3] - b[2]) + (b[5] - b[4]) * (b[5] - b[4]));
  tube_radius_ = diag > 0 ? 0.004 * diag : 0.5;
}

MeshRepresentation::~MeshRepresentation() = default;

QStringList MeshRepresentation::color_choices() const {
  QStringList out;
  for (const auto& [n, a] : mesh_->vertex_attributes) out << "vertex:" + QString::fromStdString(n);
  for (const auto& [n, a] : mesh_->triangle_attributes) out << "triangle:" + QString::fromStdString(n);
  for (const auto& [n, a] : mesh_->line_attributes) out << "line:" + QString::fromStdString(n);
  return out;
}

void MeshRepresentation::keep_settings(const Representation& old) {
  const auto* m = dynamic_cast<const MeshRepresentation*>(&old);
  if (!m) return;
  if (m->color_by_.isEmpty() || color_choices().contains(m->color_by_)) color_by_ = m->color_by_;
  tubes_ = m->tubes_;
  tube_radius_ = m->tube_radius_;
}

std::vector<vtkSmartPointer<vtkProp>> MeshRepresentation::build_props(vtkScalarBarActor* bar) {
  const QString kind = color_by_.section(':', 0, 0);
  const QByteArray attr = color_by_.section(':', 1).toUtf8();
  vtkSmartPointer<vtkLookupTable> lut;
  auto colour = [&](vtkPolyDataMapper* mapper, vtkPolyData* poly, bool is_surface) {
    vtkDataArray* a = nullptr;
    if (kind == "vertex") {
      a = poly->GetPointData()->GetArray(attr.constData());
      mapper->SetScalarModeToUsePointFieldData();
    } else if ((kind == "triangle" && is_surface) || (kind == "line" && !is_surface)) {
      a = poly->GetCellData()->GetArray(attr.constData());
      mapper->SetScalarModeToUseCellFieldData();
    }
    if (!a) {
      mapper->ScalarVisibilityOff();
      return;
    }
    if (!lut) {
      double r[2];
      a->GetRange(r);
      lut = vtkSmartPointer<vtkLookupTable>::New();
      lut->SetHueRange(0.667, 0.0);
      lut->SetTableRange(r[0], r[1] > r[0] ? r[1] : r[0] + 1);
      lut->Build();
    }
    mapper->SetLookupTable(lut);
    mapper->SelectColorArray(attr.constData());
    mapper->SetScalarRange(lut->GetTableRange());
    mapper->ScalarVisibilityOn();
  };
  std::vector<vtkSmartPointer<vtkProp>> props;
  if (mesh_->triangle_count() > 0) {
    auto mapper = vtkSmartPointer<vtkPolyDataMapper>::New();
    mapper->SetInputData(surface_);
    colour(mapper, surface_, true);
    auto actor = vtkSmartPointer<vtkActor>::New();
    actor->SetMapper(mapper);
    actor->GetProperty()->SetColor(color()[0], color()[1], color()[2]);
    actor->GetProperty()->SetInterpolationToGouraud();
    actor->GetProperty()->BackfaceCullingOff();
    props.push_back(actor);
  }
  if (mesh_->line_count() > 0) {
    auto mapper = vtkSmartPointer<vtkPolyDataMapper>::New();
    if (tubes_) {
      auto tube = vtkSmartPointer<vtkTubeFilter>::New();
      tube->SetInputData(lines_);
      tube->SetRadius(tube_radius_);
      tube->SetNumberOfSides(8);
      tube->CappingOn();
      mapper->SetInputConnection(tube->GetOutputPort());
    } else {
      mapper->SetInputData(lines_);
    }
    colour(mapper, lines_, false);
    auto actor = vtkSmartPointer<vtkActor>::New();
    actor->SetMapper(mapper);
    actor->GetProperty()->SetColor(color()[0], color()[1], color()[2]);
    actor->GetProperty()->SetLineWidth(2.0);
    props.push_back(actor);
  }
  if (lut) {
    bar->SetLookupTable(lut);
    bar->SetTitle(color_by_.toUtf8().constData());
    bar->SetVisibility(true);
  }
  return props;
}

QWidget* MeshRepresentation::create_controls() {
  auto* page = new QWidget;
  auto* form = new QFormLayout(page);
  color_box_ = new QComboBox;
  form->addRow("Colour by", color_box_);
  lines_box_ = new QComboBox;
  lines_box_->addItems({"Lines", "Tubes"});
  form->addRow("Lines as", lines_box_);
  radius_box_ = new QDoubleSpinBox;
  radius_box_->setRange(1e-4, 1e6);
  radius_box_->setDecimals(4);
  radius_box_->setKeyboardTracking(false);
  form->addRow("Tube radius", radius_box_);
  QObject::connect(color_box_, qOverload<int>(&QComboBox::activated), page, [this](int i) {
    color_by_ = i == 0 ? QString() : color_box_->itemText(i);
    changed();
  });
  QObject::connect(lines_box_, qOverload<int>(&QComboBox::activated), page, [this](int i) {
    tubes_ = i == 1;
    changed();
  });
  QObject::connect(radius_box_, qOverload<double>(&QDoubleSpinBox::valueChanged), page, [this](double v) {
    if (syncing_) return;
    tube_radius_ = v;
    changed();
  });
  return page;
}

void MeshRepresentation::update_controls() {
  if (!color_box_) return;
  syncing_ = true;
  color_box_->clear();
  color_box_->addItem("(plain colour)");
  int index = 0;
  for (const QString& c : color_choices()) {
    color_box_->addItem(c);
    if (c == color_by_) index = color_box_->count() - 1;
  }
  color_box_->setCurrentIndex(index);
  lines_box_->setCurrentIndex(tubes_ ? 1 : 0);
  radius_box_->setValue(tube_radius_);
  syncing_ = false;
}

}  // namespace skel::gui
