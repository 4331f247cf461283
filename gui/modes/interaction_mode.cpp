#include "interaction_mode.hpp"

#include <QDir>
#include <QDockWidget>
#include <QFileInfo>
#include <QKeyEvent>
#include <QMouseEvent>
#include <QUndoStack>

#include <vtkActor.h>
#include <vtkCamera.h>
#include <vtkMatrix4x4.h>
#include <vtkPolyData.h>
#include <vtkPolyDataMapper.h>
#include <vtkProperty.h>
#include <vtkRenderWindow.h>
#include <vtkRenderer.h>

#include <cmath>

#include "main_window.hpp"
#include "views/view3d.hpp"

namespace skel::gui {

InteractionMode::InteractionMode(MainWindow* window)
    : QObject(window), window_(window), view_(window->view3d()), vtk_widget_(window->view3d()->vtk_widget()) {}

InteractionMode::~InteractionMode() = default;

void InteractionMode::log(const QString& text, bool error) { window_->log(text, error); }

QString InteractionMode::default_dir() const {
  const QByteArray env = qgetenv("SKELFLOW_EDIT_DIR");
  if (!env.isEmpty()) return QString::fromLocal8Bit(env);
  if (!window_->document()->file_path().isEmpty()) return QFileInfo(window_->document()->file_path()).absolutePath();
  return QDir::currentPath();
}

// ---------------------------------------------------------------- entering and leaving
vtkRenderer* InteractionMode::open_overlay() {
  vtkRenderer* main = view_->renderer();
  vtkRenderWindow* rw = main->GetRenderWindow();
  if (rw->GetNumberOfLayers() < 2) rw->SetNumberOfLayers(2);
  overlay_ = vtkSmartPointer<vtkRenderer>::New();
  overlay_->SetLayer(1);
  overlay_->InteractiveOff();
  overlay_->SetActiveCamera(main->GetActiveCamera());
  rw->AddRenderer(overlay_);
  return overlay_;
}

vtkRenderer* InteractionMode::overlay() const { return overlay_; }

void InteractionMode::take_input() {
  if (!vtk_widget_) return;
  vtk_widget_->installEventFilter(this);
  vtk_widget_->setFocus();
}

void InteractionMode::release() {
  if (vtk_widget_) vtk_widget_->removeEventFilter(this);
  if (overlay_) {
    view_->renderer()->GetRenderWindow()->RemoveRenderer(overlay_);
    overlay_ = nullptr;
  }
  for (QDockWidget* d : docks_) {
    window_->removeDockWidget(d);
    d->deleteLater();
  }
  docks_.clear();
  pressed_ = false;
}

QDockWidget* InteractionMode::add_dock(const QString& title, const QString& object_name, QWidget* content) {
  auto* dock = new QDockWidget(title, window_);
  dock->setObjectName(object_name);
  dock->setWidget(content);
  window_->addDockWidget(Qt::RightDockWidgetArea, dock);
  docks_.push_back(dock);
  return dock;
}

// ---------------------------------------------------------------- overlay
vtkSmartPointer<vtkActor> InteractionMode::make_overlay_actor(const std::array<double, 3>& color, double point_size,
                                                             double line_width) {
  auto mapper = vtkSmartPointer<vtkPolyDataMapper>::New();
  mapper->SetInputData(vtkSmartPointer<vtkPolyData>::New());
  mapper->ScalarVisibilityOff();
  auto a = vtkSmartPointer<vtkActor>::New();
  a->SetMapper(mapper);
  a->GetProperty()->SetColor(color[0], color[1], color[2]);
  a->GetProperty()->SetPointSize(static_cast<float>(point_size));
  a->GetProperty()->SetLineWidth(static_cast<float>(line_width));
  a->GetProperty()->RenderPointsAsSpheresOn();
  a->GetProperty()->SetLighting(false);
  return a;
}

void InteractionMode::OverlayShape::vertex(const Vec3& p) {
  const vtkIdType id = points->InsertNextPoint(p[0], p[1], p[2]);
  verts->InsertNextCell(1, &id);
}

void InteractionMode::OverlayShape::line(const std::vector<Vec3>& pts) {
  lines->InsertNextCell(static_cast<vtkIdType>(pts.size()));
  for (const auto& p : pts) lines->InsertCellPoint(points->InsertNextPoint(p[0], p[1], p[2]));
}

void InteractionMode::OverlayShape::set(vtkActor* actor) const {
  auto pd = vtkSmartPointer<vtkPolyData>::New();
  pd->SetPoints(points);
  pd->SetVerts(verts);
  pd->SetLines(lines);
  static_cast<vtkPolyDataMapper*>(actor->GetMapper())->SetInputData(pd);
}

// ---------------------------------------------------------------- screen positions
ScreenProjection InteractionMode::projection() const {
  ScreenProjection s;
  const QWidget* w = vtk_widget_ ? vtk_widget_ : static_cast<QWidget*>(view_);
  s.width = std::max(1, w->width());
  s.height = std::max(1, w->height());
  vtkRenderer* ren = view_->renderer();
  ren->ResetCameraClippingRange();
  vtkMatrix4x4* m = ren->GetActiveCamera()->GetCompositeProjectionTransformMatrix(s.width / s.height, -1, 1);
  for (int i = 0; i < 4; ++i) {
    for (int j = 0; j < 4; ++j) s.m[static_cast<size_t>(4 * i + j)] = m->GetElement(i, j);
  }
  return s;
}

std::optional<std::pair<double, double>> InteractionMode::screen_position_f(const Vec3& p) const {
  double x, y, d;
  if (!projection().project(p, x, y, d)) return std::nullopt;
  return std::make_pair(x, y);
}

std::optional<QPoint> InteractionMode::screen_position(const Vec3& p) const {
  const auto f = screen_position_f(p);
  if (!f) return std::nullopt;
  return QPoint(static_cast<int>(std::floor(f->first)), static_cast<int>(std::floor(f->second)));
}

// ---------------------------------------------------------------- events
void InteractionMode::bind_key(int key, std::function<void()> action) { keys_[key] = std::move(action); }

bool InteractionMode::is_bound(int key, Qt::KeyboardModifiers mods) const {
  if (mods & Qt::ControlModifier) return key == Qt::Key_Z || key == Qt::Key_Y;
  return keys_.count(key) > 0;
}

bool InteractionMode::handle_key(int key, Qt::KeyboardModifiers mods) {
  if (!active()) return false;
  const bool ctrl = mods & Qt::ControlModifier, shift = mods & Qt::ShiftModifier;
  if (ctrl) {
    if (key == Qt::Key_Z && !shift) undo_stack()->undo();
    else if ((key == Qt::Key_Z && shift) || key == Qt::Key_Y) undo_stack()->redo();
    else return false;
    return true;
  }
  const auto it = keys_.find(key);
  if (it == keys_.end()) return false;
  it->second();
  return true;
}

bool InteractionMode::eventFilter(QObject* watched, QEvent* event) {
  if (watched != vtk_widget_ || !active()) return QObject::eventFilter(watched, event);
  switch (event->type()) {
    case QEvent::ShortcutOverride:
    case QEvent::KeyPress: {
      auto* k = static_cast<QKeyEvent*>(event);
      const int key = k->key();
      const auto mods = k->modifiers() & (Qt::ControlModifier | Qt::ShiftModifier);
      if (!is_bound(key, mods)) return false;
      // Accepting the override keeps the window's shortcuts (pipeline Delete/Undo, Esc = cancel run)
      // from firing; the key press then comes here.
      event->accept();
      if (event->type() == QEvent::KeyPress) handle_key(key, mods);
      return true;
    }
    case QEvent::MouseButtonPress: {
      auto* m = static_cast<QMouseEvent*>(event);
      if (m->button() != Qt::LeftButton) return false;
      pressed_ = true;
      press_pos_ = m->pos();
      return mouse_press(m);
    }
    case QEvent::MouseMove: return mouse_move(static_cast<QMouseEvent*>(event));
    case QEvent::MouseButtonRelease: {
      auto* m = static_cast<QMouseEvent*>(event);
      if (m->button() != Qt::LeftButton || !pressed_) return false;
      pressed_ = false;
      return mouse_release(m, is_click(m->pos()));
    }
    default:
      return false;
  }
}

}  // namespace skel::gui
