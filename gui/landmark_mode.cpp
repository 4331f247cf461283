#include "landmark_mode.hpp"

#include <QButtonGroup>
#include <QCheckBox>
#include <QColor>
#include <QComboBox>
#include <QDir>
#include <QDockWidget>
#include <QFileDialog>
#include <QFileInfo>
#include <QHBoxLayout>
#include <QHeaderView>
#include <QKeyEvent>
#include <QLabel>
#include <QMouseEvent>
#include <QPushButton>
#include <QRadioButton>
#include <QSignalBlocker>
#include <QTableView>
#include <QVBoxLayout>

#include <QVTKOpenGLNativeWidget.h>
#include <vtkActor.h>
#include <vtkBillboardTextActor3D.h>
#include <vtkCamera.h>
#include <vtkCellArray.h>
#include <vtkCellPicker.h>
#include <vtkMatrix4x4.h>
#include <vtkPoints.h>
#include <vtkPolyData.h>
#include <vtkPolyDataMapper.h>
#include <vtkProperty.h>
#include <vtkRenderWindow.h>
#include <vtkRenderer.h>
#include <vtkSmartPointer.h>
#include <vtkTextProperty.h>

#include <cmath>

#include "graph_pick.hpp"
#include "main_window.hpp"
#include "pipeline_document.hpp"
#include "view3d.hpp"

namespace skel::gui {

namespace {
constexpr double kPickRadius = 8.0;  // pixels
constexpr int kClickSlack = 3;       // pixels a click may move and still be a click

vtkSmartPointer<vtkActor> make_actor(const std::array<double, 3>& color, double point_size, double line_width) {
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

void set_points(vtkActor* a, const std::vector<Vec3>& verts, const std::vector<std::pair<Vec3, Vec3>>& lines = {}) {
  auto pts = vtkSmartPointer<vtkPoints>::New();
  auto vc = vtkSmartPointer<vtkCellArray>::New();
  auto lc = vtkSmartPointer<vtkCellArray>::New();
  for (const Vec3& p : verts) {
    const vtkIdType id = pts->InsertNextPoint(p[0], p[1], p[2]);
    vc->InsertNextCell(1, &id);
  }
  for (const auto& [p, q] : lines) {
    const vtkIdType ids[2] = {pts->InsertNextPoint(p[0], p[1], p[2]), pts->InsertNextPoint(q[0], q[1], q[2])};
    lc->InsertNextCell(2, ids);
  }
  auto pd = vtkSmartPointer<vtkPolyData>::New();
  pd->SetPoints(pts);
  pd->SetVerts(vc);
  pd->SetLines(lc);
  static_cast<vtkPolyDataMapper*>(a->GetMapper())->SetInputData(pd);
}
}  // namespace

struct LandmarkMode::Overlay {
  vtkSmartPointer<vtkRenderer> renderer;
  vtkSmartPointer<vtkActor> sets[2], lines, selection;
  std::vector<vtkSmartPointer<vtkBillboardTextActor3D>> labels;
};

LandmarkMode::LandmarkMode(MainWindow* window)
    : QObject(window), window_(window), view_(window->view3d()),
      vtk_widget_(window->view3d()->findChild<QVTKOpenGLNativeWidget*>()), session_(new LandmarkSession(this)) {
  connect(session_, &LandmarkSession::landmarks_changed, this, &LandmarkMode::refresh);
  connect(session_, &LandmarkSession::active_set_changed, this, [this](int set) {
    if (set_button_[set]) set_button_[set]->setChecked(true);
    refresh();
  });
  connect(session_, &LandmarkSession::message, this, [this](const QString& m, bool error) { log(m, error); });
  connect(window_->document(), &PipelineDocument::document_reset, this, [this] {
    stop();
    session_->undo_stack()->clear();
    session_->apply_state({});
    selected_ = -1;
  });
}

LandmarkMode::~LandmarkMode() { stop(); }

void LandmarkMode::log(const QString& text, bool error) { window_->log(text, error); }

QString LandmarkMode::default_path() const {
  QString dir = QString::fromLocal8Bit(qgetenv("SKELFLOW_EDIT_DIR"));
  if (dir.isEmpty() && !window_->document()->file_path().isEmpty())
    dir = QFileInfo(window_->document()->file_path()).absolutePath();
  if (dir.isEmpty()) dir = QDir::currentPath();
  return QDir(dir).filePath("landmarks.landmarkAscii");
}

void LandmarkMode::start() {
  if (active_) return;
  active_ = true;
  overlay_ = std::make_unique<Overlay>();
  vtkRenderer* main = view_->renderer();
  vtkRenderWindow* rw = main->GetRenderWindow();
  if (rw->GetNumberOfLayers() < 2) rw->SetNumberOfLayers(2);
  overlay_->renderer = vtkSmartPointer<vtkRenderer>::New();
  overlay_->renderer->SetLayer(1);
  overlay_->renderer->InteractiveOff();
  overlay_->renderer->SetActiveCamera(main->GetActiveCamera());
  overlay_->lines = make_actor({0.85, 0.85, 0.85}, 1, 1.5);
  // The selected pair: flat white squares behind the (sphere-shaded, hence nearer) points.
  overlay_->selection = make_actor({1.0, 1.0, 1.0}, 19, 1);
  overlay_->selection->GetProperty()->RenderPointsAsSpheresOff();
  for (int s = 0; s < 2; ++s) overlay_->sets[s] = make_actor(LandmarkSession::set_color(s), 13, 1);
  for (auto* a : {overlay_->lines.Get(), overlay_->selection.Get(), overlay_->sets[0].Get(), overlay_->sets[1].Get()})
    overlay_->renderer->AddActor(a);
  rw->AddRenderer(overlay_->renderer);
  if (vtk_widget_) {
    vtk_widget_->installEventFilter(this);
    vtk_widget_->setFocus();
  }
  build_dock();
  refresh();
  log("Landmark mode: click on a slice or surface to place set " + QString::number(session_->active_set() + 1) +
      " points, drag a landmark to move it");
  emit started();
}

void LandmarkMode::stop() {
  if (!active_) return;
  active_ = false;
  if (vtk_widget_) vtk_widget_->removeEventFilter(this);
  if (overlay_) {
    view_->renderer()->GetRenderWindow()->RemoveRenderer(overlay_->renderer);
    overlay_.reset();
  }
  if (dock_) {
    window_->removeDockWidget(dock_);
    dock_->deleteLater();
  }
  dock_ = nullptr;
  table_ = nullptr;
  status_ = nullptr;
  model_ = nullptr;
  set_button_[0] = set_button_[1] = nullptr;
  drag_pair_ = drag_set_ = -1;
  pressed_ = false;
  view_->render();
  log("Left landmark mode");
  emit stopped();
}

void LandmarkMode::build_dock() {
  auto* panel = new QWidget;
  auto* v = new QVBoxLayout(panel);
  status_ = new QLabel(panel);
  status_->setWordWrap(true);
  status_->setTextInteractionFlags(Qt::TextSelectableByMouse);
  v->addWidget(status_);

  auto* sets = new QHBoxLayout;
  auto* group = new QButtonGroup(panel);
  const char* names[2] = {"Set 1 (fixed) [1]", "Set 2 (moving) [2]"};
  for (int s = 0; s < 2; ++s) {
    set_button_[s] = new QRadioButton(names[s], panel);
    set_button_[s]->setFocusPolicy(Qt::NoFocus);
    const auto c = LandmarkSession::set_color(s);
    set_button_[s]->setStyleSheet(QString("QRadioButton { color: %1; font-weight: bold; }")
                                      .arg(QColor::fromRgbF(c[0], c[1], c[2]).darker(130).name()));
    group->addButton(set_button_[s], s);
    sets->addWidget(set_button_[s]);
  }
  set_button_[session_->active_set()]->setChecked(true);
  connect(group, qOverload<int>(&QButtonGroup::idClicked), this, [this](int s) { session_->set_active_set(s); });
  v->addLayout(sets);

  auto* opts = new QHBoxLayout;
  auto* alternate = new QCheckBox("Alternate sets", panel);
  alternate->setFocusPolicy(Qt::NoFocus);
  alternate->setChecked(session_->alternate());
  alternate->setToolTip("after each placed point, switch to the other set (1, 2, 1, 2, ...)");
  connect(alternate, &QCheckBox::toggled, this, [this](bool on) { session_->set_alternate(on); });
  opts->addWidget(alternate);
  opts->addStretch(1);
  opts->addWidget(new QLabel("Model", panel));
  model_ = new QComboBox(panel);
  model_->setFocusPolicy(Qt::NoFocus);
  model_->addItems({"rigid", "similarity", "affine"});
  model_->setCurrentText(QString::fromStdString(to_string(session_->model())));
  model_->setToolTip("registration model of the residual fit (registration.landmarks)");
  connect(model_, &QComboBox::currentTextChanged, this,
          [this](const QString& m) { session_->set_model(parse_transform_kind(m.toStdString(), "model")); });
  opts->addWidget(model_);
  v->addLayout(opts);

  table_ = new QTableView(panel);
  table_->setModel(session_);
  table_->setSelectionBehavior(QAbstractItemView::SelectRows);
  table_->setSelectionMode(QAbstractItemView::SingleSelection);
  table_->setFocusPolicy(Qt::ClickFocus);
  table_->verticalHeader()->hide();
  table_->horizontalHeader()->setSectionResizeMode(QHeaderView::Stretch);
  table_->horizontalHeader()->setSectionResizeMode(LandmarkSession::ColPair, QHeaderView::ResizeToContents);
  table_->horizontalHeader()->setSectionResizeMode(LandmarkSession::ColResidual, QHeaderView::ResizeToContents);
  connect(table_->selectionModel(), &QItemSelectionModel::currentRowChanged, this, [this](const QModelIndex& i) {
    if (i.isValid() && i.row() < session_->pair_count() && i.row() != selected_) select_pair(i.row());
  });
  v->addWidget(table_, 1);

  auto* grid = new QHBoxLayout;
  auto button = [&](const QString& text, const QString& tip, auto slot) {
    auto* b = new QPushButton(text, panel);
    b->setFocusPolicy(Qt::NoFocus);
    b->setToolTip(tip);
    connect(b, &QPushButton::clicked, this, slot);
    grid->addWidget(b);
    return b;
  };
  button("Delete pair", "delete the selected pair (Delete)", [this] {
    if (selected_ >= 0) session_->delete_pair(selected_);
  });
  button("Undo", "Ctrl+Z in the 3D view", [this] { session_->undo_stack()->undo(); });
  button("Redo", "Ctrl+Shift+Z in the 3D view", [this] { session_->undo_stack()->redo(); });
  v->addLayout(grid);
  auto* files = new QHBoxLayout;
  grid = files;
  button("Load…", "read an Amira .landmarkAscii, Slicer .fcsv or CSV landmark file", [this] {
    const QString path = QFileDialog::getOpenFileName(window_, "Load landmarks", default_path(),
                                                      "Landmarks (*.landmarkAscii *.am *.fcsv *.csv)");
    if (!path.isEmpty()) load(path);
  });
  button("Save…", "write the landmarks and add io.read_landmarks + registration.landmarks to the pipeline", [this] {
    const QString path = QFileDialog::getSaveFileName(
        window_, "Save landmarks", default_path(),
        "Amira landmarks (*.landmarkAscii);;Slicer markups, set 1 only (*.fcsv);;CSV (*.csv)");
    if (!path.isEmpty()) save(path);
  });
  button("Leave", "leave landmark mode (the landmarks are kept)", [this] { stop(); });
  v->addLayout(files);

  dock_ = new QDockWidget("Landmarks", window_);
  dock_->setObjectName("landmarks");
  dock_->setWidget(panel);
  window_->addDockWidget(Qt::RightDockWidgetArea, dock_);
  window_->resizeDocks({dock_}, {450}, Qt::Horizontal);  // room for both points and the residual
}

void LandmarkMode::select_pair(int pair) {
  selected_ = pair >= 0 && pair < session_->pair_count() ? pair : -1;
  refresh();
}

void LandmarkMode::refresh() {
  if (selected_ >= session_->pair_count()) selected_ = -1;
  if (table_) {
    QSignalBlocker block(table_->selectionModel());
    if (selected_ >= 0) table_->selectRow(selected_);
    else table_->clearSelection();
  }
  if (status_) {
    const double rms = session_->rms();
    status_->setText(
        QString("<b>%1 pair(s)</b>, %2 complete; next click places a point of <b>set %3</b><br>%4<br>%5 step(s) in "
                "the history")
            .arg(session_->pair_count())
            .arg(session_->complete_count())
            .arg(session_->active_set() + 1)
            .arg(session_->has_fit() ? QString("%1 fit: RMS residual %2").arg(QString::fromStdString(to_string(session_->model()))).arg(rms, 0, 'g', 4)
                                     : "No fit: " + session_->fit_error().toHtmlEscaped())
            .arg(session_->undo_stack()->index()));
  }
  if (!overlay_) return;
  std::vector<Vec3> pts[2], sel;
  std::vector<std::pair<Vec3, Vec3>> lines;
  for (auto& l : overlay_->labels) overlay_->renderer->RemoveActor(l);
  overlay_->labels.clear();
  for (int i = 0; i < session_->pair_count(); ++i) {
    std::optional<Vec3> p[2];
    for (int s = 0; s < 2; ++s) {
      p[s] = session_->point(i, s);
      if (i == drag_pair_ && s == drag_set_ && drag_to_) p[s] = drag_to_;
      if (!p[s]) continue;
      pts[s].push_back(*p[s]);
      if (i == selected_) sel.push_back(*p[s]);
      auto label = vtkSmartPointer<vtkBillboardTextActor3D>::New();
      label->SetInput(QString::number(i + 1).toUtf8().constData());
      label->SetPosition((*p[s])[0], (*p[s])[1], (*p[s])[2]);
      label->SetDisplayOffset(7, 7);
      const auto c = LandmarkSession::set_color(s);
      label->GetTextProperty()->SetColor(c[0], c[1], c[2]);
      label->GetTextProperty()->SetFontSize(16);
      label->GetTextProperty()->BoldOn();
      label->GetTextProperty()->ShadowOn();
      overlay_->renderer->AddActor(label);
      overlay_->labels.push_back(label);
    }
    if (p[0] && p[1]) lines.emplace_back(*p[0], *p[1]);
  }
  for (int s = 0; s < 2; ++s) set_points(overlay_->sets[s], pts[s]);
  set_points(overlay_->lines, {}, lines);
  set_points(overlay_->selection, sel);
  view_->render();
}

bool LandmarkMode::save(const QString& path_in) {
  const QString path = path_in.isEmpty() ? default_path() : path_in;
  try {
    session_->save(path);
    const QString id = session_->add_pipeline_nodes(window_->document(), path);
    log(QString("Saved %1 landmark pair(s) to %2; pipeline node %3 reads them").arg(session_->pair_count()).arg(path).arg(id));
  } catch (const std::exception& e) {
    log("Saving the landmarks failed: " + QString::fromUtf8(e.what()), true);
    return false;
  }
  refresh();
  return true;
}

bool LandmarkMode::load(const QString& path) {
  try {
    session_->load(path);
  } catch (const std::exception& e) {
    log("Loading landmarks failed: " + QString::fromUtf8(e.what()), true);
    return false;
  }
  selected_ = -1;
  log(QString("Loaded %1 landmark pair(s) from %2").arg(session_->pair_count()).arg(path));
  refresh();
  return true;
}

// ---------------------------------------------------------------- picking
namespace {
ScreenProjection projection_of(vtkRenderer* ren, const QWidget* w) {
  ScreenProjection s;
  s.width = std::max(1, w->width());
  s.height = std::max(1, w->height());
  ren->ResetCameraClippingRange();
  vtkMatrix4x4* m = ren->GetActiveCamera()->GetCompositeProjectionTransformMatrix(s.width / s.height, -1, 1);
  for (int i = 0; i < 4; ++i) {
    for (int j = 0; j < 4; ++j) s.m[static_cast<size_t>(4 * i + j)] = m->GetElement(i, j);
  }
  return s;
}
}  // namespace

std::optional<Vec3> LandmarkMode::pick_surface(QPoint pos) const {
  const QWidget* w = vtk_widget_ ? vtk_widget_ : static_cast<QWidget*>(view_);
  const double dpr = w->devicePixelRatioF();
  auto picker = vtkSmartPointer<vtkCellPicker>::New();
  picker->SetTolerance(0.0005);
  vtkRenderer* ren = view_->renderer();
  ren->ResetCameraClippingRange();
  // VTK display coordinates: physical pixels, y upwards; the cursor is at the pixel's centre.
  if (!picker->Pick((pos.x() + 0.5) * dpr, (w->height() - pos.y() - 0.5) * dpr, 0, ren)) return std::nullopt;
  double p[3];
  picker->GetPickPosition(p);
  if (!std::isfinite(p[0]) || !std::isfinite(p[1]) || !std::isfinite(p[2])) return std::nullopt;
  return Vec3{p[0], p[1], p[2]};
}

std::optional<std::pair<double, double>> LandmarkMode::screen_position_f(const Vec3& p) const {
  const QWidget* w = vtk_widget_ ? vtk_widget_ : static_cast<QWidget*>(view_);
  double x, y, d;
  if (!projection_of(view_->renderer(), w).project(p, x, y, d)) return std::nullopt;
  return std::make_pair(x, y);
}

std::optional<QPoint> LandmarkMode::screen_position(const Vec3& p) const {
  const auto f = screen_position_f(p);
  if (!f) return std::nullopt;
  return QPoint(static_cast<int>(std::floor(f->first)), static_cast<int>(std::floor(f->second)));
}

std::optional<std::pair<int, int>> LandmarkMode::pick_landmark(QPoint pos) const {
  const QWidget* w = vtk_widget_ ? vtk_widget_ : static_cast<QWidget*>(view_);
  const ScreenProjection proj = projection_of(view_->renderer(), w);
  const double cx = pos.x() + 0.5, cy = pos.y() + 0.5;
  double best = kPickRadius, best_depth = 2;
  std::optional<std::pair<int, int>> hit;
  for (int i = 0; i < session_->pair_count(); ++i) {
    for (int s = 0; s < 2; ++s) {
      const auto p = session_->point(i, s);
      double x, y, d;
      if (!p || !proj.project(*p, x, y, d)) continue;
      const double dist = std::hypot(x - cx, y - cy);
      // Nearest on screen; among (nearly) coinciding ones the one nearer to the camera.
      if (dist < best - 1e-9 || (std::abs(dist - best) <= 1e-9 && d < best_depth)) {
        best = dist;
        best_depth = d;
        hit = std::make_pair(i, s);
      }
    }
  }
  return hit;
}

// ---------------------------------------------------------------- events
bool LandmarkMode::handle_key(int key, Qt::KeyboardModifiers mods) {
  if (!active_) return false;
  const bool ctrl = mods & Qt::ControlModifier, shift = mods & Qt::ShiftModifier;
  if (ctrl) {
    if (key == Qt::Key_Z && !shift) session_->undo_stack()->undo();
    else if ((key == Qt::Key_Z && shift) || key == Qt::Key_Y) session_->undo_stack()->redo();
    else return false;
    return true;
  }
  switch (key) {
    case Qt::Key_1: session_->set_active_set(0); return true;
    case Qt::Key_2: session_->set_active_set(1); return true;
    case Qt::Key_Delete:
    case Qt::Key_Backspace:
      if (selected_ >= 0) session_->delete_pair(selected_);
      return true;
    case Qt::Key_Escape: select_pair(-1); return true;
    default: return false;
  }
}

bool LandmarkMode::eventFilter(QObject* watched, QEvent* event) {
  if (watched != vtk_widget_ || !active_) return QObject::eventFilter(watched, event);
  switch (event->type()) {
    case QEvent::ShortcutOverride:
    case QEvent::KeyPress: {
      auto* k = static_cast<QKeyEvent*>(event);
      const int key = k->key();
      const auto mods = k->modifiers() & (Qt::ControlModifier | Qt::ShiftModifier);
      const bool bound = (mods & Qt::ControlModifier) ? (key == Qt::Key_Z || key == Qt::Key_Y)
                                                      : (key == Qt::Key_1 || key == Qt::Key_2 || key == Qt::Key_Delete ||
                                                         key == Qt::Key_Backspace || key == Qt::Key_Escape);
      if (!bound) return false;
      // Accepting the override keeps the window's shortcuts (pipeline Undo/Delete, Esc) from firing.
      event->accept();
      if (event->type() == QEvent::KeyPress) handle_key(key, mods);
      return true;
    }
    case QEvent::MouseButtonPress: {
      auto* m = static_cast<QMouseEvent*>(event);
      if (m->button() != Qt::LeftButton) return false;
      pressed_ = true;
      press_pos_ = m->pos();
      if (const auto hit = pick_landmark(m->pos())) {
        drag_pair_ = hit->first;
        drag_set_ = hit->second;
        drag_to_.reset();
        select_pair(drag_pair_);
        return true;  // no camera rotation while dragging a landmark
      }
      return false;
    }
    case QEvent::MouseMove: {
      if (drag_pair_ < 0) return false;
      auto* m = static_cast<QMouseEvent*>(event);
      if ((m->pos() - press_pos_).manhattanLength() > kClickSlack) {
        if (const auto p = pick_surface(m->pos())) {
          drag_to_ = p;
          refresh();
        }
      }
      return true;
    }
    case QEvent::MouseButtonRelease: {
      auto* m = static_cast<QMouseEvent*>(event);
      if (m->button() != Qt::LeftButton || !pressed_) return false;
      pressed_ = false;
      if (drag_pair_ >= 0) {
        const int pair = drag_pair_, set = drag_set_;
        std::optional<Vec3> to;
        if ((m->pos() - press_pos_).manhattanLength() > kClickSlack) {
          to = pick_surface(m->pos());
          if (!to) to = drag_to_;  // released off the surfaces: the last position on them
        }
        drag_pair_ = drag_set_ = -1;
        drag_to_.reset();
        if (to) session_->move_point(pair, set, *to);
        else refresh();
        return true;
      }
      if ((m->pos() - press_pos_).manhattanLength() <= kClickSlack) {
        if (const auto p = pick_surface(m->pos())) {
          const int pair = session_->add_point(*p);
          if (pair >= 0) select_pair(pair);
        } else {
          log("Landmarks: nothing under the cursor (show a volume as slices or iso-surface)", true);
        }
      }
      return false;  // the interactor ends its (empty) rotation
    }
    default:
      return false;
  }
}

}  // namespace skel::gui
