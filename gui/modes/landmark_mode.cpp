#include "landmark_mode.hpp"

#include <QButtonGroup>
#include <QCheckBox>
#include <QColor>
#include <QComboBox>
#include <QDir>
#include <QDockWidget>
#include <QFileDialog>
#include <QHBoxLayout>
#include <QHeaderView>
#include <QLabel>
#include <QMouseEvent>
#include <QPushButton>
#include <QRadioButton>
#include <QSignalBlocker>
#include <QTableView>
#include <QVBoxLayout>

#include <vtkActor.h>
#include <vtkBillboardTextActor3D.h>
#include <vtkCellPicker.h>
#include <vtkProperty.h>
#include <vtkRenderer.h>
#include <vtkSmartPointer.h>
#include <vtkTextProperty.h>

#include <cmath>

#include "io/names.hpp"
#include "main_window.hpp"
#include "pipeline_document.hpp"
#include "registration/names.hpp"
#include "views/view3d.hpp"

namespace skel::gui {

struct LandmarkMode::Overlay {
  vtkSmartPointer<vtkActor> sets[2], lines, selection;
  std::vector<vtkSmartPointer<vtkBillboardTextActor3D>> labels;
};

LandmarkMode::LandmarkMode(MainWindow* window) : InteractionMode(window), session_(new LandmarkSession(this)) {
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
  bind_key(Qt::Key_1, [this] { session_->set_active_set(0); });
  bind_key(Qt::Key_2, [this] { session_->set_active_set(1); });
  for (int key : {Qt::Key_Delete, Qt::Key_Backspace}) {
    bind_key(key, [this] {
      if (selected_ >= 0) session_->delete_pair(selected_);
    });
  }
  bind_key(Qt::Key_Escape, [this] { select_pair(-1); });
}

LandmarkMode::~LandmarkMode() { stop(); }

QUndoStack* LandmarkMode::undo_stack() const { return session_->undo_stack(); }

QString LandmarkMode::default_path() const { return QDir(default_dir()).filePath("landmarks.landmarkAscii"); }

void LandmarkMode::start() {
  if (active_) return;
  active_ = true;
  overlay_ = std::make_unique<Overlay>();
  vtkRenderer* overlay = open_overlay();
  overlay_->lines = make_overlay_actor({0.85, 0.85, 0.85}, 1, 1.5);
  // The selected pair: flat white squares behind the (sphere-shaded, hence nearer) points.
  overlay_->selection = make_overlay_actor({1.0, 1.0, 1.0}, 19, 1);
  overlay_->selection->GetProperty()->RenderPointsAsSpheresOff();
  for (int s = 0; s < 2; ++s) overlay_->sets[s] = make_overlay_actor(LandmarkSession::set_color(s), 13, 1);
  for (auto* a : {overlay_->lines.Get(), overlay_->selection.Get(), overlay_->sets[0].Get(), overlay_->sets[1].Get()})
    overlay->AddActor(a);
  take_input();
  build_dock();
  refresh();
  log("Landmark mode: click on a slice or surface to place set " + QString::number(session_->active_set() + 1) +
      " points, drag a landmark to move it");
  emit started();
}

void LandmarkMode::stop() {
  if (!active_) return;
  active_ = false;
  release();  // event filter, overlay layer, dock
  overlay_.reset();
  dock_ = nullptr;
  table_ = nullptr;
  status_ = nullptr;
  model_ = nullptr;
  set_button_[0] = set_button_[1] = nullptr;
  drag_pair_ = drag_set_ = -1;
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
  model_->setToolTip(QString("registration model of the residual fit (%1)").arg(registration::names::landmarks));
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
  const QString save_tip = QString("write the landmarks and add %1 + %2 to the pipeline")
                               .arg(io::names::read_landmarks, registration::names::landmarks);
  button("Save…", save_tip, [this] {
    const QString path = QFileDialog::getSaveFileName(
        window_, "Save landmarks", default_path(),
        "Amira landmarks (*.landmarkAscii);;Slicer markups, set 1 only (*.fcsv);;CSV (*.csv)");
    if (!path.isEmpty()) save(path);
  });
  button("Leave", "leave landmark mode (the landmarks are kept)", [this] { stop(); });
  v->addLayout(files);

  dock_ = add_dock("Landmarks", "landmarks", panel);
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
  for (auto& l : overlay_->labels) overlay()->RemoveActor(l);
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
      overlay()->AddActor(label);
      overlay_->labels.push_back(label);
    }
    if (p[0] && p[1]) lines.emplace_back(*p[0], *p[1]);
  }
  for (int s = 0; s < 2; ++s) {
    OverlayShape shape;
    for (const Vec3& p : pts[s]) shape.vertex(p);
    shape.set(overlay_->sets[s]);
  }
  OverlayShape pair_lines, selection;
  for (const auto& [p, q] : lines) pair_lines.line({p, q});
  for (const Vec3& p : sel) selection.vertex(p);
  pair_lines.set(overlay_->lines);
  selection.set(overlay_->selection);
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

std::optional<std::pair<int, int>> LandmarkMode::pick_landmark(QPoint pos) const {
  const ScreenProjection proj = projection();
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

// ---------------------------------------------------------------- mouse
bool LandmarkMode::mouse_press(QMouseEvent* m) {
  const auto hit = pick_landmark(m->pos());
  if (!hit) return false;
  drag_pair_ = hit->first;
  drag_set_ = hit->second;
  drag_to_.reset();
  select_pair(drag_pair_);
  return true;  // no camera rotation while dragging a landmark
}

bool LandmarkMode::mouse_move(QMouseEvent* m) {
  if (drag_pair_ < 0) return false;
  if (!is_click(m->pos())) {
    if (const auto p = pick_surface(m->pos())) {
      drag_to_ = p;
      refresh();
    }
  }
  return true;
}

bool LandmarkMode::mouse_release(QMouseEvent* m, bool click) {
  if (drag_pair_ >= 0) {
    const int pair = drag_pair_, set = drag_set_;
    std::optional<Vec3> to;
    if (!click) {
      to = pick_surface(m->pos());
      if (!to) to = drag_to_;  // released off the surfaces: the last position on them
    }
    drag_pair_ = drag_set_ = -1;
    drag_to_.reset();
    if (to) session_->move_point(pair, set, *to);
    else refresh();
    return true;
  }
  if (click) {
    if (const auto p = pick_surface(m->pos())) {
      const int pair = session_->add_point(*p);
      if (pair >= 0) select_pair(pair);
    } else {
      log("Landmarks: nothing under the cursor (show a volume as slices or iso-surface)", true);
    }
  }
  return false;  // the interactor ends its (empty) rotation
}

}  // namespace skel::gui
