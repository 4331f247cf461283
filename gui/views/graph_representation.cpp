#include "graph_representation.hpp"

#include <QComboBox>
#include <QDoubleSpinBox>
#include <QFormLayout>
#include <QWidget>

#include <vtkActor.h>
#include <vtkFloatArray.h>
#include <vtkLookupTable.h>
#include <vtkPointData.h>
#include <vtkPolyData.h>
#include <vtkPolyDataMapper.h>
#include <vtkProperty.h>
#include <vtkScalarBarActor.h>
#include <vtkTubeFilter.h>

#include <algorithm>

#include "vtk_convert.hpp"

namespace skel::gui {

GraphRepresentation::GraphRepresentation(const QString& name, const std::shared_ptr<const SpatialGraph>& graph,
                                         const Color& color)
    : Representation(name, graph, color), graph_(graph), poly_(graph_to_polydata(*graph)) {
  const auto attrs = graph_attribute_names(*graph);
  const bool has_radius = std::find(attrs.begin(), attrs.end(), "radius") != attrs.end();
  mode_ = has_radius ? GraphMode::Tubes : GraphMode::Lines;
  if (has_radius) color_by_ = "radius";
}

GraphRepresentation::~GraphRepresentation() = default;

void GraphRepresentation::keep_settings(const Representation& old) {
  const auto* g = dynamic_cast<const GraphRepresentation*>(&old);
  if (!g) return;
  mode_ = g->mode_;
  tube_scale_ = g->tube_scale_;
  color_by_ = g->color_by_;
}

std::vector<vtkSmartPointer<vtkProp>> GraphRepresentation::build_props(vtkScalarBarActor* bar) {
  auto mapper = vtkSmartPointer<vtkPolyDataMapper>::New();
  vtkPointData* pd = poly_->GetPointData();
  const bool tubes = mode_ == GraphMode::Tubes && pd->GetArray("radius");
  if (tubes) {
    // Tube radius = radius attribute x scale (clamped away from 0 so tubes never degenerate).
    vtkDataArray* r = pd->GetArray("radius");
    auto scaled = vtkSmartPointer<vtkFloatArray>::New();
    scaled->SetName("tube_radius");
    scaled->SetNumberOfTuples(r->GetNumberOfTuples());
    double range[2];
    r->GetRange(range);
    const double floor_r = std::max(1e-3, 0.05 * range[1]) * tube_scale_;
    for (vtkIdType i = 0; i < r->GetNumberOfTuples(); ++i) {
      scaled->SetValue(i, static_cast<float>(std::max(r->GetTuple1(i) * tube_scale_, floor_r)));
    }
    pd->AddArray(scaled);
    pd->SetActiveScalars("tube_radius");
    auto tube = vtkSmartPointer<vtkTubeFilter>::New();
    tube->SetInputData(poly_);
    tube->SetVaryRadiusToVaryRadiusByAbsoluteScalar();
    tube->SetNumberOfSides(10);
    tube->CappingOn();
    mapper->SetInputConnection(tube->GetOutputPort());
  } else {
    mapper->SetInputData(poly_);
  }
  vtkDataArray* colors = color_by_.isEmpty() ? nullptr : pd->GetArray(color_by_.toUtf8().constData());
  if (colors) {
    double r[2];
    colors->GetRange(r);
    auto lut = vtkSmartPointer<vtkLookupTable>::New();
    lut->SetHueRange(0.667, 0.0);
    lut->SetTableRange(r[0], r[1] > r[0] ? r[1] : r[0] + 1);
    lut->Build();
    mapper->SetLookupTable(lut);
    mapper->SetScalarModeToUsePointFieldData();
    mapper->SelectColorArray(color_by_.toUtf8().constData());
    mapper->SetScalarRange(lut->GetTableRange());
    mapper->ScalarVisibilityOn();
    bar->SetLookupTable(lut);
    bar->SetTitle(color_by_.toUtf8().constData());
    bar->SetVisibility(true);
  } else {
    mapper->ScalarVisibilityOff();
  }
  auto actor = vtkSmartPointer<vtkActor>::New();
  actor->SetMapper(mapper);
  actor->GetProperty()->SetColor(color()[0], color()[1], color()[2]);
  actor->GetProperty()->SetLineWidth(2.0);
  return {actor};
}

QWidget* GraphRepresentation::create_controls() {
  auto* page = new QWidget;
  auto* form = new QFormLayout(page);
  mode_box_ = new QComboBox;
  mode_box_->addItems({"Lines", "Tubes (radius)"});
  form->addRow("Display", mode_box_);
  color_box_ = new QComboBox;
  form->addRow("Colour by", color_box_);
  scale_box_ = new QDoubleSpinBox;
  scale_box_->setRange(0.01, 100);
  scale_box_->setValue(1.0);
  scale_box_->setSingleStep(0.1);
  scale_box_->setKeyboardTracking(false);
  form->addRow("Radius scale", scale_box_);

  QObject::connect(mode_box_, qOverload<int>(&QComboBox::activated), page, [this](int i) {
    mode_ = static_cast<GraphMode>(i);
    changed();
  });
  QObject::connect(color_box_, qOverload<int>(&QComboBox::activated), page, [this](int i) {
    color_by_ = i == 0 ? QString() : color_box_->itemText(i);
    changed();
  });
  QObject::connect(scale_box_, qOverload<double>(&QDoubleSpinBox::valueChanged), page, [this](double v) {
    if (syncing_) return;
    tube_scale_ = v;
    changed();
  });
  return page;
}

void GraphRepresentation::update_controls() {
  if (!mode_box_) return;
  syncing_ = true;
  mode_box_->setCurrentIndex(static_cast<int>(mode_));
  color_box_->clear();
  color_box_->addItem("(plain colour)");
  int index = 0;
  for (const auto& n : graph_attribute_names(*graph_)) {
    color_box_->addItem(QString::fromStdString(n));
    if (QString::fromStdString(n) == color_by_) index = color_box_->count() - 1;
  }
  color_box_->setCurrentIndex(index);
  scale_box_->setValue(tube_scale_);
  syncing_ = false;
}

}  // namespace skel::gui
