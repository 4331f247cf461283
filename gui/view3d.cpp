#include "view3d.hpp"

#include <QCheckBox>
#include <QComboBox>
#include <QDoubleSpinBox>
#include <QFormLayout>
#include <QHBoxLayout>
#include <QLabel>
#include <QListWidget>
#include <QPushButton>
#include <QSlider>
#include <QStackedWidget>
#include <QVBoxLayout>

#include <QVTKOpenGLNativeWidget.h>
#include <vtkActor.h>
#include <vtkCamera.h>
#include <vtkCellData.h>
#include <vtkColorTransferFunction.h>
#include <vtkFloatArray.h>
#include <vtkFlyingEdges3D.h>
#include <vtkGenericOpenGLRenderWindow.h>
#include <vtkGeometryFilter.h>
#include <vtkImageActor.h>
#include <vtkImageMapper3D.h>
#include <vtkImageProperty.h>
#include <vtkLookupTable.h>
#include <vtkOutlineFilter.h>
#include <vtkPiecewiseFunction.h>
#include <vtkPointData.h>
#include <vtkPolyDataMapper.h>
#include <vtkProperty.h>
#include <vtkRenderWindowInteractor.h>
#include <vtkRenderer.h>
#include <vtkScalarBarActor.h>
#include <vtkSmartVolumeMapper.h>
#include <vtkTextProperty.h>
#include <vtkThreshold.h>
#include <vtkTubeFilter.h>
#include <vtkVolume.h>
#include <vtkVolumeProperty.h>
#include <vtkWindowToImageFilter.h>

#include <array>
#include <cmath>

#include "skel/spatial_graph.hpp"
#include "vtk_convert.hpp"

namespace skel::gui {

namespace {
// Colours given to objects in the order they are shown.
const std::array<std::array<double, 3>, 6> kPalette = {{{0.90, 0.75, 0.55},
                                                        {0.55, 0.80, 0.95},
                                                        {0.95, 0.55, 0.55},
                                                        {0.65, 0.90, 0.60},
                                                        {0.85, 0.65, 0.95},
                                                        {0.95, 0.90, 0.50}}};
}  // namespace

struct View3D::Vtk {
  vtkSmartPointer<vtkGenericOpenGLRenderWindow> window;
  vtkSmartPointer<vtkRenderer> renderer;
  vtkSmartPointer<vtkScalarBarActor> bar;
};

struct View3D::Object {
  QString name;
  DataPtr data;
  bool is_graph = false;
  bool binary = false;
  bool visible = true;
  std::array<double, 3> color{};
  std::vector<vtkSmartPointer<vtkProp>> props;  // in the renderer now
  // volumes
  vtkSmartPointer<vtkImageData> image;
  double range[2] = {0, 1};
  int extent[6] = {0, 0, 0, 0, 0, 0};
  VolumeMode mode = VolumeMode::Slices;
  double window = 1, level = 0.5, iso = 0.5;
  int slice[3] = {0, 0, 0};
  vtkSmartPointer<vtkActor> outline;
  vtkSmartPointer<vtkActor> surface;
  double surface_iso = std::nan("");
  vtkSmartPointer<vtkActor> voxels;
  vtkSmartPointer<vtkVolume> volume;
  // graphs
  vtkSmartPointer<vtkPolyData> poly;
  GraphMode graph_mode = GraphMode::Lines;
  QString color_by;
  double tube_scale = 1.0;
  vtkSmartPointer<vtkActor> graph_actor;
};

View3D::View3D(QWidget* parent) : QWidget(parent), vtk_state_(std::make_unique<Vtk>()) {
  vtk_ = new QVTKOpenGLNativeWidget(this);
  vtk_state_->window = vtkSmartPointer<vtkGenericOpenGLRenderWindow>::New();
  vtk_->setRenderWindow(vtk_state_->window);
  vtk_state_->renderer = vtkSmartPointer<vtkRenderer>::New();
  vtk_state_->renderer->SetBackground(0.10, 0.11, 0.13);
  vtk_state_->renderer->SetBackground2(0.25, 0.27, 0.32);
  vtk_state_->renderer->GradientBackgroundOn();
  vtk_state_->window->AddRenderer(vtk_state_->renderer);
  vtk_state_->bar = vtkSmartPointer<vtkScalarBarActor>::New();
  vtk_state_->bar->SetNumberOfLabels(5);
  vtk_state_->bar->SetWidth(0.08);
  vtk_state_->bar->SetHeight(0.5);
  vtk_state_->bar->SetPosition(0.9, 0.25);
  vtk_state_->bar->GetTitleTextProperty()->SetFontSize(12);
  vtk_state_->bar->SetVisibility(false);
  vtk_state_->renderer->AddActor2D(vtk_state_->bar);

  // Side panel: objects with visibility check boxes and the controls of the selected object.
  auto* side = new QWidget(this);
  auto* sv = new QVBoxLayout(side);
  sv->setContentsMargins(2, 2, 2, 2);
  sv->addWidget(new QLabel("<b>Objects</b> (click an output port)"));
  list_ = new QListWidget(side);
  list_->setMaximumHeight(130);
  sv->addWidget(list_);
  auto* buttons = new QHBoxLayout;
  auto* remove = new QPushButton("Remove", side);
  auto* reset = new QPushButton("Reset camera", side);
  buttons->addWidget(remove);
  buttons->addWidget(reset);
  sv->addLayout(buttons);

  controls_ = new QStackedWidget(side);
  controls_->addWidget(new QWidget);  // nothing selected
  auto* vol = new QWidget;
  auto* vf = new QFormLayout(vol);
  volume_mode_ = new QComboBox;
  volume_mode_->addItems({"Slices", "MIP", "Iso-surface", "Volume rendering", "Voxel surface"});
  vf->addRow("Display", volume_mode_);
  window_ = new QDoubleSpinBox;
  level_ = new QDoubleSpinBox;
  for (QDoubleSpinBox* b : {window_, level_}) {
    b->setRange(-1e12, 1e12);
    b->setDecimals(4);
    b->setKeyboardTracking(false);
  }
  vf->addRow("Window", window_);
  vf->addRow("Level", level_);
  const char* axes[3] = {"Slice x", "Slice y", "Slice z"};
  for (int k = 0; k < 3; ++k) {
    slice_[k] = new QSlider(Qt::Horizontal);
    vf->addRow(axes[k], slice_[k]);
  }
  iso_ = new QDoubleSpinBox;
  iso_->setRange(-1e12, 1e12);
  iso_->setDecimals(4);
  iso_->setKeyboardTracking(false);
  vf->addRow("Iso value", iso_);
  controls_->addWidget(vol);
  auto* gr = new QWidget;
  auto* gf = new QFormLayout(gr);
  graph_mode_ = new QComboBox;
  graph_mode_->addItems({"Lines", "Tubes (radius)"});
  gf->addRow("Display", graph_mode_);
  color_by_ = new QComboBox;
  gf->addRow("Colour by", color_by_);
  tube_scale_ = new QDoubleSpinBox;
  tube_scale_->setRange(0.01, 100);
  tube_scale_->setValue(1.0);
  tube_scale_->setSingleStep(0.1);
  tube_scale_->setKeyboardTracking(false);
  gf->addRow("Radius scale", tube_scale_);
  controls_->addWidget(gr);
  sv->addWidget(controls_);
  sv->addStretch(1);

  vtk_->setMinimumSize(320, 240);
  side->setSizePolicy(QSizePolicy::Fixed, QSizePolicy::Preferred);
  side->setFixedWidth(260);
  auto* layout = new QHBoxLayout(this);
  layout->setContentsMargins(0, 0, 0, 0);
  layout->addWidget(vtk_, 1);
  layout->addWidget(side, 0);

  connect(list_, &QListWidget::currentTextChanged, this, &View3D::select_object);
  connect(list_, &QListWidget::itemChanged, this, [this](QListWidgetItem* item) {
    if (!updating_controls_) set_object_visible(item->text(), item->checkState() == Qt::Checked);
  });
  connect(remove, &QPushButton::clicked, this, [this] {
    if (!current_.isEmpty()) remove_object(current_);
  });
  connect(reset, &QPushButton::clicked, this, &View3D::reset_camera);
  connect(volume_mode_, qOverload<int>(&QComboBox::activated), this, [this](int i) {
    if (!current_.isEmpty()) set_volume_mode(current_, static_cast<VolumeMode>(i));
  });
  auto wl = [this] {
    if (!updating_controls_ && !current_.isEmpty()) set_window_level(current_, window_->value(), level_->value());
  };
  connect(window_, qOverload<double>(&QDoubleSpinBox::valueChanged), this, wl);
  connect(level_, qOverload<double>(&QDoubleSpinBox::valueChanged), this, wl);
  for (int k = 0; k < 3; ++k) {
    connect(slice_[k], &QSlider::valueChanged, this, [this, k](int v) {
      Object* o = current();
      if (updating_controls_ || !o || o->is_graph) return;
      o->slice[k] = v;
      if (o->mode == VolumeMode::Slices) apply(*o);
    });
  }
  connect(iso_, qOverload<double>(&QDoubleSpinBox::valueChanged), this, [this](double v) {
    if (!updating_controls_ && !current_.isEmpty()) set_iso_value(current_, v);
  });
  connect(graph_mode_, qOverload<int>(&QComboBox::activated), this, [this](int i) {
    if (!current_.isEmpty()) set_graph_mode(current_, static_cast<GraphMode>(i));
  });
  connect(color_by_, qOverload<int>(&QComboBox::activated), this, [this](int i) {
    if (!current_.isEmpty()) set_graph_color_by(current_, i == 0 ? QString() : color_by_->itemText(i));
  });
  connect(tube_scale_, qOverload<double>(&QDoubleSpinBox::valueChanged), this, [this](double v) {
    Object* o = current();
    if (updating_controls_ || !o || !o->is_graph) return;
    o->tube_scale = v;
    apply(*o);
  });
  update_controls();
}

View3D::~View3D() = default;

vtkRenderer* View3D::renderer() const { return vtk_state_->renderer; }

View3D::Object* View3D::current() {
  auto it = objects_.find(current_);
  return it == objects_.end() ? nullptr : it->get();
}

bool View3D::show_data(const QString& name, const DataPtr& data, QString* error) {
  if (!data) {
    if (error) *error = name + ": no data (run the pipeline first)";
    return false;
  }
  auto o = std::make_shared<Object>();
  o->name = name;
  o->data = data;
  o->color = kPalette[static_cast<size_t>(objects_.size()) % kPalette.size()];
  if (auto g = std::dynamic_pointer_cast<const SpatialGraph>(data)) {
    o->is_graph = true;
    o->poly = graph_to_polydata(*g);
    const auto attrs = graph_attribute_names(*g);
    const bool has_radius = std::find(attrs.begin(), attrs.end(), "radius") != attrs.end();
    o->graph_mode = has_radius ? GraphMode::Tubes : GraphMode::Lines;
    if (has_radius) o->color_by = "radius";
  } else {
    try {
      o->image = volume_to_image(*data);
    } catch (const std::exception&) {
      if (error) *error = name + ": the 3D view shows volumes and graphs, not " + QString::fromStdString(data->type_id());
      return false;
    }
    o->binary = is_binary_volume(*data);
    o->image->GetScalarRange(o->range);
    o->image->GetExtent(o->extent);
    for (int k = 0; k < 3; ++k) o->slice[k] = (o->extent[2 * k] + o->extent[2 * k + 1]) / 2;
    o->window = std::max(o->range[1] - o->range[0], 1e-9);
    o->level = 0.5 * (o->range[0] + o->range[1]);
    o->iso = o->binary ? 0.5 : o->range[0] + 0.5 * (o->range[1] - o->range[0]);
    o->mode = o->binary ? VolumeMode::VoxelSurface : VolumeMode::Slices;
    // A thin outline of the grid so slices and surfaces have context.
    auto outline = vtkSmartPointer<vtkOutlineFilter>::New();
    outline->SetInputData(o->image);
    auto om = vtkSmartPointer<vtkPolyDataMapper>::New();
    om->SetInputConnection(outline->GetOutputPort());
    o->outline = vtkSmartPointer<vtkActor>::New();
    o->outline->SetMapper(om);
    o->outline->GetProperty()->SetColor(0.6, 0.6, 0.65);
  }
  const bool first = objects_.isEmpty();
  if (objects_.contains(name)) {
    // New data for a shown object (e.g. after a re-run): keep how it is displayed.
    const Object& old = *objects_.value(name);
    o->color = old.color;
    o->visible = old.visible;
    if (old.is_graph == o->is_graph && old.binary == o->binary) {
      o->mode = old.mode;
      o->graph_mode = old.graph_mode;
      o->tube_scale = old.tube_scale;
      if (o->is_graph) o->color_by = old.color_by;
      if (!o->is_graph && old.data->type_id() == data->type_id()) {
        o->window = old.window;
        o->level = old.level;
        o->iso = old.iso;
        for (int k = 0; k < 3; ++k) o->slice[k] = std::clamp(old.slice[k], o->extent[2 * k], o->extent[2 * k + 1]);
      }
    }
    remove_object(name);
  }
  objects_.insert(name, o);
  updating_controls_ = true;
  auto* item = new QListWidgetItem(name, list_);
  item->setFlags(item->flags() | Qt::ItemIsUserCheckable);
  item->setCheckState(o->visible ? Qt::Checked : Qt::Unchecked);
  item->setToolTip(QString::fromStdString(data->describe()));
  updating_controls_ = false;
  apply(*o);
  list_->setCurrentItem(item);
  if (first) reset_camera();
  emit message("Showing " + name + ": " + QString::fromStdString(data->describe()));
  return true;
}

void View3D::remove_object(const QString& name) {
  auto it = objects_.find(name);
  if (it == objects_.end()) return;
  for (auto& p : (*it)->props) vtk_state_->renderer->RemoveViewProp(p);
  objects_.erase(it);
  for (int i = 0; i < list_->count(); ++i) {
    if (list_->item(i)->text() == name) delete list_->takeItem(i);
  }
  if (current_ == name) current_.clear();
  // The scalar bar belongs to the graph shown last with a colour attribute.
  bool bar = false;
  for (auto& o : objects_) bar |= o->is_graph && o->visible && !o->color_by.isEmpty();
  vtk_state_->bar->SetVisibility(bar);
  update_controls();
  render();
}

void View3D::clear() {
  for (const QString& n : objects_.keys()) remove_object(n);
}

QStringList View3D::object_names() const { return objects_.keys(); }

DataPtr View3D::object_data(const QString& name) const {
  auto it = objects_.find(name);
  return it == objects_.end() ? nullptr : (*it)->data;
}
bool View3D::has_object(const QString& name) const { return objects_.contains(name); }

void View3D::set_object_visible(const QString& name, bool visible) {
  auto it = objects_.find(name);
  if (it == objects_.end()) return;
  (*it)->visible = visible;
  updating_controls_ = true;
  for (int i = 0; i < list_->count(); ++i) {
    if (list_->item(i)->text() == name) list_->item(i)->setCheckState(visible ? Qt::Checked : Qt::Unchecked);
  }
  updating_controls_ = false;
  apply(**it);
}

bool View3D::object_visible(const QString& name) const {
  auto it = objects_.find(name);
  return it != objects_.end() && (*it)->visible;
}

void View3D::set_volume_mode(const QString& name, VolumeMode mode) {
  auto it = objects_.find(name);
  if (it == objects_.end() || (*it)->is_graph) return;
  (*it)->mode = mode;
  apply(**it);
  if (name == current_) update_controls();
}

VolumeMode View3D::volume_mode(const QString& name) const {
  auto it = objects_.find(name);
  return it == objects_.end() ? VolumeMode::Slices : (*it)->mode;
}

void View3D::set_window_level(const QString& name, double window, double level) {
  auto it = objects_.find(name);
  if (it == objects_.end() || (*it)->is_graph) return;
  (*it)->window = std::max(window, 1e-12);
  (*it)->level = level;
  apply(**it);
}

void View3D::set_iso_value(const QString& name, double value) {
  auto it = objects_.find(name);
  if (it == objects_.end() || (*it)->is_graph) return;
  (*it)->iso = value;
  apply(**it);
}

void View3D::set_graph_mode(const QString& name, GraphMode mode) {
  auto it = objects_.find(name);
  if (it == objects_.end() || !(*it)->is_graph) return;
  (*it)->graph_mode = mode;
  apply(**it);
}

void View3D::set_graph_color_by(const QString& name, const QString& attribute) {
  auto it = objects_.find(name);
  if (it == objects_.end() || !(*it)->is_graph) return;
  (*it)->color_by = attribute;
  apply(**it);
}

void View3D::apply(Object& o) {
  vtkRenderer* ren = vtk_state_->renderer;
  for (auto& p : o.props) ren->RemoveViewProp(p);
  o.props.clear();
  if (o.visible && o.is_graph) {
    auto mapper = vtkSmartPointer<vtkPolyDataMapper>::New();
    vtkPointData* pd = o.poly->GetPointData();
    const bool tubes = o.graph_mode == GraphMode::Tubes && pd->GetArray("radius");
    if (tubes) {
      // Tube radius = radius attribute x scale (clamped away from 0 so tubes never degenerate).
      vtkDataArray* r = pd->GetArray("radius");
      auto scaled = vtkSmartPointer<vtkFloatArray>::New();
      scaled->SetName("tube_radius");
      scaled->SetNumberOfTuples(r->GetNumberOfTuples());
      double range[2];
      r->GetRange(range);
      const double floor_r = std::max(1e-3, 0.05 * range[1]) * o.tube_scale;
      for (vtkIdType i = 0; i < r->GetNumberOfTuples(); ++i) {
        scaled->SetValue(i, static_cast<float>(std::max(r->GetTuple1(i) * o.tube_scale, floor_r)));
      }
      pd->AddArray(scaled);
      pd->SetActiveScalars("tube_radius");
      auto tube = vtkSmartPointer<vtkTubeFilter>::New();
      tube->SetInputData(o.poly);
      tube->SetVaryRadiusToVaryRadiusByAbsoluteScalar();
      tube->SetNumberOfSides(10);
      tube->CappingOn();
      mapper->SetInputConnection(tube->GetOutputPort());
    } else {
      mapper->SetInputData(o.poly);
    }
    vtkDataArray* colors = o.color_by.isEmpty() ? nullptr : pd->GetArray(o.color_by.toUtf8().constData());
    if (colors) {
      double r[2];
      colors->GetRange(r);
      auto lut = vtkSmartPointer<vtkLookupTable>::New();
      lut->SetHueRange(0.667, 0.0);
      lut->SetTableRange(r[0], r[1] > r[0] ? r[1] : r[0] + 1);
      lut->Build();
      mapper->SetLookupTable(lut);
      mapper->SetScalarModeToUsePointFieldData();
      mapper->SelectColorArray(o.color_by.toUtf8().constData());
      mapper->SetScalarRange(lut->GetTableRange());
      mapper->ScalarVisibilityOn();
      vtk_state_->bar->SetLookupTable(lut);
      vtk_state_->bar->SetTitle(o.color_by.toUtf8().constData());
      vtk_state_->bar->SetVisibility(true);
    } else {
      mapper->ScalarVisibilityOff();
    }
    o.graph_actor = vtkSmartPointer<vtkActor>::New();
    o.graph_actor->SetMapper(mapper);
    o.graph_actor->GetProperty()->SetColor(o.color.data());
    o.graph_actor->GetProperty()->SetLineWidth(2.0);
    o.props.push_back(o.graph_actor);
  } else if (o.visible) {
    o.props.push_back(o.outline);
    switch (o.mode) {
      case VolumeMode::Slices: {
        for (int k = 0; k < 3; ++k) {
          auto actor = vtkSmartPointer<vtkImageActor>::New();
          actor->GetMapper()->SetInputData(o.image);
          int e[6];
          std::copy(std::begin(o.extent), std::end(o.extent), e);
          e[2 * k] = e[2 * k + 1] = std::clamp(o.slice[k], o.extent[2 * k], o.extent[2 * k + 1]);
          actor->SetDisplayExtent(e);
          actor->GetProperty()->SetColorWindow(o.window);
          actor->GetProperty()->SetColorLevel(o.level);
          actor->GetProperty()->SetInterpolationTypeToNearest();
          o.props.push_back(actor);
        }
        break;
      }
      case VolumeMode::Mip:
      case VolumeMode::VolumeRendering: {
        auto mapper = vtkSmartPointer<vtkSmartVolumeMapper>::New();
        mapper->SetInputData(o.image);
        const bool mip = o.mode == VolumeMode::Mip;
        if (mip) mapper->SetBlendModeToMaximumIntensity();
        else mapper->SetBlendModeToComposite();
        const double lo = o.level - 0.5 * o.window, hi = o.level + 0.5 * o.window;
        auto color = vtkSmartPointer<vtkColorTransferFunction>::New();
        auto opacity = vtkSmartPointer<vtkPiecewiseFunction>::New();
        if (mip) {
          color->AddRGBPoint(lo, 0, 0, 0);
          color->AddRGBPoint(hi, 1, 1, 1);
          opacity->AddPoint(lo, 0.0);
          opacity->AddPoint(hi, 1.0);
        } else {
          color->AddRGBPoint(lo, 0.2, 0.1, 0.05);
          color->AddRGBPoint(lo + 0.5 * (hi - lo), 0.9, 0.5, 0.2);
          color->AddRGBPoint(hi, 1.0, 1.0, 0.9);
          opacity->AddPoint(lo, 0.0);
          opacity->AddPoint(hi, 0.6);
        }
        auto prop = vtkSmartPointer<vtkVolumeProperty>::New();
        prop->SetColor(color);
        prop->SetScalarOpacity(opacity);
        prop->SetInterpolationTypeToLinear();
        if (!mip) prop->ShadeOn();
        o.volume = vtkSmartPointer<vtkVolume>::New();
        o.volume->SetMapper(mapper);
        o.volume->SetProperty(prop);
        o.props.push_back(o.volume);
        break;
      }
      case VolumeMode::IsoSurface: {
        if (!o.surface || o.surface_iso != o.iso) {
          auto fe = vtkSmartPointer<vtkFlyingEdges3D>::New();
          fe->SetInputData(o.image);
          fe->SetValue(0, o.iso);
          fe->ComputeNormalsOn();
          fe->ComputeScalarsOff();
          auto m = vtkSmartPointer<vtkPolyDataMapper>::New();
          m->SetInputConnection(fe->GetOutputPort());
          m->ScalarVisibilityOff();
          o.surface = vtkSmartPointer<vtkActor>::New();
          o.surface->SetMapper(m);
          o.surface->GetProperty()->SetColor(o.color.data());
          o.surface_iso = o.iso;
        }
        o.props.push_back(o.surface);
        break;
      }
      case VolumeMode::VoxelSurface: {
        if (!o.voxels) {
          // Each voxel >= iso is a cube; the outer faces of the kept cubes are the voxel surface.
          auto cells = volume_to_cell_image(*o.data);
          auto th = vtkSmartPointer<vtkThreshold>::New();
          th->SetInputData(cells);
          th->SetInputArrayToProcess(0, 0, 0, vtkDataObject::FIELD_ASSOCIATION_CELLS, "voxels");
          th->SetLowerThreshold(o.binary ? 0.5 : o.iso);
          th->SetUpperThreshold(VTK_DOUBLE_MAX);
          th->SetThresholdFunction(vtkThreshold::THRESHOLD_BETWEEN);
          auto geom = vtkSmartPointer<vtkGeometryFilter>::New();
          geom->SetInputConnection(th->GetOutputPort());
          auto m = vtkSmartPointer<vtkPolyDataMapper>::New();
          m->SetInputConnection(geom->GetOutputPort());
          m->ScalarVisibilityOff();
          o.voxels = vtkSmartPointer<vtkActor>::New();
          o.voxels->SetMapper(m);
          o.voxels->GetProperty()->SetColor(o.color.data());
        }
        o.props.push_back(o.voxels);
        break;
      }
    }
  }
  for (auto& p : o.props) ren->AddViewProp(p);
  bool bar = false;
  for (auto& x : objects_) bar |= x->is_graph && x->visible && !x->color_by.isEmpty();
  vtk_state_->bar->SetVisibility(bar);
  render();
}

void View3D::select_object(const QString& name) {
  current_ = name;
  update_controls();
}

void View3D::update_controls() {
  updating_controls_ = true;
  Object* o = current();
  if (!o) {
    controls_->setCurrentIndex(0);
  } else if (o->is_graph) {
    controls_->setCurrentIndex(2);
    graph_mode_->setCurrentIndex(static_cast<int>(o->graph_mode));
    color_by_->clear();
    color_by_->addItem("(plain colour)");
    int index = 0;
    if (auto g = std::dynamic_pointer_cast<const SpatialGraph>(o->data)) {
      for (const auto& n : graph_attribute_names(*g)) {
        color_by_->addItem(QString::fromStdString(n));
        if (QString::fromStdString(n) == o->color_by) index = color_by_->count() - 1;
      }
    }
    color_by_->setCurrentIndex(index);
    tube_scale_->setValue(o->tube_scale);
  } else {
    controls_->setCurrentIndex(1);
    volume_mode_->setCurrentIndex(static_cast<int>(o->mode));
    window_->setValue(o->window);
    level_->setValue(o->level);
    window_->setSingleStep(std::max(o->window / 50, 1e-4));
    level_->setSingleStep(std::max(o->window / 50, 1e-4));
    for (int k = 0; k < 3; ++k) {
      slice_[k]->setRange(o->extent[2 * k], o->extent[2 * k + 1]);
      slice_[k]->setValue(o->slice[k]);
    }
    iso_->setValue(o->iso);
    iso_->setSingleStep(std::max((o->range[1] - o->range[0]) / 50, 1e-4));
  }
  updating_controls_ = false;
}

void View3D::reset_camera() {
  vtkRenderer* ren = vtk_state_->renderer;
  ren->ResetCamera();
  vtkCamera* cam = ren->GetActiveCamera();
  // A three-quarter view shows all three slice planes.
  cam->Azimuth(35);
  cam->Elevation(25);
  cam->OrthogonalizeViewUp();
  ren->ResetCamera();
  ren->ResetCameraClippingRange();
  render();
}

void View3D::render() {
  vtk_state_->window->Render();
  vtk_->update();
}

QImage View3D::grab_image() {
  render();
  // Read back what VTK rendered (works on every platform where VTK renders, Xvfb + Mesa included).
  auto w2i = vtkSmartPointer<vtkWindowToImageFilter>::New();
  w2i->SetInput(vtk_state_->window);
  w2i->SetInputBufferTypeToRGB();
  w2i->ReadFrontBufferOff();
  w2i->Update();
  vtkImageData* img = w2i->GetOutput();
  int dims[3];
  img->GetDimensions(dims);
  if (dims[0] <= 0 || dims[1] <= 0 || img->GetNumberOfScalarComponents() < 3) return {};
  QImage out(dims[0], dims[1], QImage::Format_RGB888);
  const auto* src = static_cast<const unsigned char*>(img->GetScalarPointer());
  const int comps = img->GetNumberOfScalarComponents();
  for (int y = 0; y < dims[1]; ++y) {
    uchar* dst = out.scanLine(dims[1] - 1 - y);  // VTK rows go bottom-up
    const unsigned char* row = src + static_cast<size_t>(y) * dims[0] * comps;
    for (int x = 0; x < dims[0]; ++x) {
      dst[3 * x + 0] = row[comps * x + 0];
      dst[3 * x + 1] = row[comps * x + 1];
      dst[3 * x + 2] = row[comps * x + 2];
    }
  }
  return out;
}

bool View3D::save_screenshot(const QString& path) {
  const QImage img = grab_image();
  return !img.isNull() && img.save(path, "PNG");
}

}  // namespace skel::gui
