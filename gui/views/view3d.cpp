#include "view3d.hpp"

#include <QHBoxLayout>
#include <QLabel>
#include <QListWidget>
#include <QPushButton>
#include <QStackedWidget>
#include <QVBoxLayout>

#include <QVTKOpenGLNativeWidget.h>
#include <vtkGenericOpenGLRenderWindow.h>
#include <vtkImageData.h>
#include <vtkProp.h>
#include <vtkRenderer.h>
#include <vtkScalarBarActor.h>
#include <vtkWindowToImageFilter.h>


namespace skel::gui {

struct View3D::Vtk {
  vtkSmartPointer<vtkGenericOpenGLRenderWindow> window;
  vtkSmartPointer<vtkRenderer> renderer;
  vtkSmartPointer<vtkScalarBarActor> bar;  // shared: shows the colours of the graphs coloured by an attribute
};

View3D::View3D(QWidget* parent) : QWidget(parent), vtk_state_(std::make_unique<Vtk>()) {
  vtk_ = new QVTKOpenGLNativeWidget(this);
  vtk_state_->window = vtkSmartPointer<vtkGenericOpenGLRenderWindow>::New();
  vtk_->setRenderWindow(vtk_state_->window);
  vtk_state_->renderer = vtkSmartPointer<vtkRenderer>::New();
  render::setup_renderer(vtk_state_->renderer);  // the look `skelflow render` shares
  vtk_state_->window->AddRenderer(vtk_state_->renderer);
  vtk_state_->bar = render::make_scalar_bar(vtk_state_->renderer);

  // Side panel: objects with visibility check boxes and the controls of the selected object (a
  // page per object, made by its representation).
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
  update_controls();
}

View3D::~View3D() {
  // The pages call into their representations: they go first.
  for (auto& o : objects_) delete o->controls;
}

vtkRenderer* View3D::renderer() const { return vtk_state_->renderer; }
QWidget* View3D::vtk_widget() const { return vtk_; }

template <class R>
R* View3D::find(const QString& name) const {
  auto it = objects_.find(name);
  return it == objects_.end() ? nullptr : dynamic_cast<R*>((*it)->rep.get());
}

bool View3D::show_data(const QString& name, const DataPtr& data, QString* error) {
  if (!data) {
    if (error) *error = name + ": no data (run the pipeline first)";
    return false;
  }
  auto o = std::make_shared<Object>();
  o->rep = make_representation(name, data, render::palette_color(static_cast<size_t>(objects_.size())), error);
  if (!o->rep) return false;
  const bool first = objects_.isEmpty();
  if (objects_.contains(name)) {
    // New data for a shown object (e.g. after a re-run): keep how it is displayed.
    o->rep->keep_display_of(*objects_.value(name)->rep);
    remove_object(name);
  }
  Object* raw = o.get();
  o->rep->on_changed([this, raw] { apply(*raw); });
  objects_.insert(name, o);
  updating_controls_ = true;
  auto* item = new QListWidgetItem(name, list_);
  item->setFlags(item->flags() | Qt::ItemIsUserCheckable);
  item->setCheckState(o->rep->visible() ? Qt::Checked : Qt::Unchecked);
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
  if (QWidget* page = (*it)->controls) {
    controls_->removeWidget(page);
    delete page;
  }
  objects_.erase(it);
  for (int i = 0; i < list_->count(); ++i) {
    if (list_->item(i)->text() == name) delete list_->takeItem(i);
  }
  if (current_ == name) current_.clear();
  update_scalar_bar();
  update_controls();
  render();
}

void View3D::clear() {
  for (const QString& n : objects_.keys()) remove_object(n);
}

QStringList View3D::object_names() const { return objects_.keys(); }

DataPtr View3D::object_data(const QString& name) const {
  auto it = objects_.find(name);
  return it == objects_.end() ? nullptr : (*it)->rep->data();
}
bool View3D::has_object(const QString& name) const { return objects_.contains(name); }

void View3D::set_object_visible(const QString& name, bool visible) {
  auto it = objects_.find(name);
  if (it == objects_.end()) return;
  (*it)->rep->set_visible(visible);
  updating_controls_ = true;
  for (int i = 0; i < list_->count(); ++i) {
    if (list_->item(i)->text() == name) list_->item(i)->setCheckState(visible ? Qt::Checked : Qt::Unchecked);
  }
  updating_controls_ = false;
  apply(**it);
}

bool View3D::object_visible(const QString& name) const {
  auto it = objects_.find(name);
  return it != objects_.end() && (*it)->rep->visible();
}

void View3D::set_volume_mode(const QString& name, VolumeMode mode) {
  auto* v = find<VolumeRepresentation>(name);
  if (!v) return;
  v->set_mode(mode);
  apply(*objects_.value(name));
  if (name == current_) update_controls();
}

VolumeMode View3D::volume_mode(const QString& name) const {
  auto* v = find<VolumeRepresentation>(name);
  return v ? v->mode() : VolumeMode::Slices;
}

void View3D::set_window_level(const QString& name, double window, double level) {
  auto* v = find<VolumeRepresentation>(name);
  if (!v) return;
  v->set_window_level(window, level);
  apply(*objects_.value(name));
}

void View3D::set_iso_value(const QString& name, double value) {
  auto* v = find<VolumeRepresentation>(name);
  if (!v) return;
  v->set_iso_value(value);
  apply(*objects_.value(name));
}

void View3D::set_graph_mode(const QString& name, GraphMode mode) {
  auto* g = find<GraphRepresentation>(name);
  if (!g) return;
  g->set_mode(mode);
  apply(*objects_.value(name));
}

void View3D::set_graph_color_by(const QString& name, const QString& attribute) {
  auto* g = find<GraphRepresentation>(name);
  if (!g) return;
  g->set_color_by(attribute);
  apply(*objects_.value(name));
}

void View3D::apply(Object& o) {
  vtkRenderer* ren = vtk_state_->renderer;
  for (auto& p : o.props) ren->RemoveViewProp(p);
  o.props.clear();
  if (o.rep->visible()) o.props = o.rep->build_props(vtk_state_->bar);
  for (auto& p : o.props) ren->AddViewProp(p);
  update_scalar_bar();
  render();
}

void View3D::update_scalar_bar() {
  // The bar shows the colours of the object that set it last; it stays while any visible object
  // colours by an attribute.
  bool bar = false;
  for (auto& o : objects_) bar |= o->rep->visible() && o->rep->uses_scalar_bar();
  vtk_state_->bar->SetVisibility(bar);
}

void View3D::select_object(const QString& name) {
  current_ = name;
  update_controls();
}

void View3D::update_controls() {
  updating_controls_ = true;
  auto it = objects_.find(current_);
  if (it == objects_.end()) {
    controls_->setCurrentIndex(0);
  } else {
    Object& o = **it;
    if (!o.controls) {
      o.controls = o.rep->create_controls();
      controls_->addWidget(o.controls);
    }
    controls_->setCurrentWidget(o.controls);
    o.rep->update_controls();
  }
  updating_controls_ = false;
}

void View3D::reset_camera() {
  render::set_camera(vtk_state_->renderer, render::CameraPreset::Iso);
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
