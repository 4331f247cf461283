#include "main_window.hpp"

#include <QAction>
#include <QApplication>
#include <QClipboard>
#include <QCloseEvent>
#include <QDockWidget>
#include <QFileDialog>
#include <QFileInfo>
#include <QHeaderView>
#include <QKeySequence>
#include <QLabel>
#include <QMenu>
#include <QMenuBar>
#include <QMessageBox>
#include <QMimeData>
#include <QPlainTextEdit>
#include <QProgressBar>
#include <QSettings>
#include <QSplitter>
#include <QStatusBar>
#include <QScrollBar>
#include <QTableWidget>
#include <QTimer>
#include <QTime>
#include <QToolBar>

#include <algorithm>
#include <cmath>

#include "final_outputs.hpp"
#include "modes/graph_edit_mode.hpp"
#include "modes/landmark_mode.hpp"
#include "node_editor.hpp"
#include "palette.hpp"
#include "properties_panel.hpp"
#include "geometry/cells_to_mesh.hpp"
#include "skel/error.hpp"
#include "skel/grid_cells.hpp"
#include "skel/mesh.hpp"
#include "skel/spatial_graph.hpp"
#include "skel/table.hpp"
#include "views/view3d.hpp"

namespace skel::gui {

namespace {
constexpr int kMaxRecent = 8;
constexpr const char* kClipboardMime = "application/x-skelflow-nodes";
}  // namespace

MainWindow::MainWindow(QWidget* parent) : QMainWindow(parent) {
  doc_ = new PipelineDocument(this);
  run_ = new RunController(doc_, this);
  scene_ = new NodeScene(doc_, run_, this);
  view_ = new NodeView(scene_, this);
  view3d_ = new View3D(this);

  split_ = new QSplitter(Qt::Horizontal, this);
  split_->addWidget(view_);
  split_->addWidget(view3d_);
  split_->setStretchFactor(0, 2);
  split_->setStretchFactor(1, 3);
  split_->setChildrenCollapsible(false);
  split_->setSizes({520, 700});
  setCentralWidget(split_);

  palette_ = new Palette(doc_->registry(), this);
  auto* palette_dock = new QDockWidget("Modules", this);
  palette_dock->setObjectName("modules");
  palette_dock->setWidget(palette_);
  palette_->setMinimumWidth(180);
  addDockWidget(Qt::LeftDockWidgetArea, palette_dock);

  props_ = new PropertiesPanel(doc_, this);
  props_->set_input_unit_source([this](const QString& id) -> std::string {
    const PipelineNode* n = doc_->pipeline().find(id.toStdString());
    if (!n) return {};
    for (const auto& [port, ref] : n->inputs)
      if (DataPtr d = run_->output(QString::fromStdString(ref.node), QString::fromStdString(ref.port)))
        if (auto u = d->physical_unit(); !u.empty()) return u;
    return {};
  });
  auto* props_dock = new QDockWidget("Properties", this);
  props_dock->setObjectName("properties");
  props_dock->setWidget(props_);
  addDockWidget(Qt::LeftDockWidgetArea, props_dock);

  log_ = new QPlainTextEdit(this);
  log_->setReadOnly(true);
  log_->setMaximumBlockCount(2000);
  auto* log_dock = new QDockWidget("Log", this);
  log_dock->setObjectName("log");
  log_dock->setWidget(log_);
  addDockWidget(Qt::BottomDockWidgetArea, log_dock);

  table_ = new QTableWidget(this);
  table_->setEditTriggers(QAbstractItemView::NoEditTriggers);
  auto* table_dock = new QDockWidget("Table", this);
  table_dock->setObjectName("table");
  table_dock->setWidget(table_);
  addDockWidget(Qt::BottomDockWidgetArea, table_dock);
  tabifyDockWidget(log_dock, table_dock);
  log_dock->raise();
  resizeDocks({log_dock}, {150}, Qt::Vertical);
  resizeDocks({palette_dock}, {300}, Qt::Horizontal);
  resizeDocks({palette_dock, props_dock}, {330, 420}, Qt::Vertical);

  progress_ = new QProgressBar(this);
  progress_->setRange(0, 1000);
  progress_->setValue(0);
  progress_->setMaximumWidth(260);
  progress_->setFormat("%p%");
  status_label_ = new QLabel(this);
  statusBar()->addWidget(status_label_, 1);
  statusBar()->addPermanentWidget(progress_);

  edit_ = new GraphEditMode(this);
  landmarks_ = new LandmarkMode(this);
  build_actions();

  connect(palette_, &Palette::module_activated, this, [this](const QString& module) {
    QString error;
    const QString id = doc_->add_node(module, view_->visible_center(), &error);
    if (id.isEmpty()) log(error, true);
    else scene_->select_nodes({id});
  });
  connect(scene_, &NodeScene::node_selection_changed, this, [this](const QStringList& ids) {
    props_->show_node(ids.size() == 1 ? ids.front() : QString());
    update_run_actions();
  });
  connect(scene_, &NodeScene::message, this, [this](const QString& m) { log(m, true); });
  connect(scene_, &NodeScene::output_port_clicked, this,
          [this](const QString& node, const QString& port) { show_output(node, port); });
  connect(props_, &PropertiesPanel::message, this, [this](const QString& m) { log(m, true); });
  connect(view3d_, &View3D::message, this, [this](const QString& m) { log(m); });
  connect(doc_, &PipelineDocument::modified_changed, this, &MainWindow::update_title);
  connect(doc_, &PipelineDocument::file_path_changed, this, &MainWindow::update_title);
  connect(doc_, &PipelineDocument::document_reset, this, [this] {
    view3d_->clear();
    view_chosen_ = false;
    view_->fit_all();
    QTimer::singleShot(0, view_, [this] { view_->fit_all(); });  // again once the splitter has settled
  });

  connect(run_, &RunController::started, this, [this] {
    status_label_->setText("Running…");
    update_run_actions();
  });
  connect(run_, &RunController::progress_changed, this,
          [this](double p) { progress_->setValue(static_cast<int>(std::lround(p * 1000))); });
  connect(run_, &RunController::node_status_changed, this, [this](const QString& node) {
    const NodeStatus s = run_->status(node);
    if (s.state == NodeState::Error) log(node + ": " + QString::fromStdString(s.message), true);
  });
  connect(run_, &RunController::warning, this,
          [this](const QString& node, const QString& m) { log("warning: " + node + ": " + m); });
  connect(run_, &RunController::finished, this, [this](bool ok, const QString& message) {
    status_label_->setText(ok ? "Done: " + message : "Failed: " + message);
    log(ok ? "Run finished: " + message : "Run failed: " + message, !ok);
    update_run_actions();
    props_->refresh();  // parameter units follow the data's
    // Objects in the 3D view follow their node's new results.
    for (const QString& name : view3d_->object_names()) {
      const int dot = name.lastIndexOf('.');
      DataPtr data = run_->output(name.left(dot), name.mid(dot + 1));
      if (data && data != view3d_->object_data(name)) view3d_->show_data(name, data);
    }
    if (ok && !pending_node_.isEmpty()) {
      const QString n = pending_node_, p = pending_port_;
      pending_node_.clear();
      show_output(n, p);
    } else if (ok && !view_chosen_ && view3d_->object_names().isEmpty()) {
      show_final_geometry();
    }
    pending_node_.clear();
  });

  resize(1500, 900);
  update_title();
  update_run_actions();
  rebuild_recent_menu();
}

MainWindow::~MainWindow() {
  run_->cancel();
  run_->wait();
  delete edit_;  // leaves edit mode while the 3D view still exists
  edit_ = nullptr;
  delete landmarks_;
  landmarks_ = nullptr;
  // Views first: they refer to the document while they are torn down.
  delete view_;
  delete scene_;
}

void MainWindow::build_actions() {
  QMenu* file = menuBar()->addMenu("&File");
  QMenu* edit = menuBar()->addMenu("&Edit");
  QMenu* view = menuBar()->addMenu("&View");
  QMenu* run = menuBar()->addMenu("&Run");
  QToolBar* bar = addToolBar("Main");
  bar->setObjectName("main_toolbar");

  auto add = [this](QMenu* menu, const QString& text, QKeySequence key, auto slot) {
    auto* a = new QAction(text, this);
    if (!key.isEmpty()) a->setShortcut(key);
    connect(a, &QAction::triggered, this, slot);
    menu->addAction(a);
    return a;
  };

  QAction* new_a = add(file, "&New", QKeySequence::New, [this] {
    if (maybe_save()) doc_->clear();
  });
  QAction* open_a = add(file, "&Open…", QKeySequence::Open, [this] {
    if (!maybe_save()) return;
    const QString path = QFileDialog::getOpenFileName(this, "Open pipeline", {}, "Pipelines (*.yaml *.yml)");
    if (!path.isEmpty()) open_file(path);
  });
  recent_menu_ = file->addMenu("Open &Recent");
  QAction* save_a = add(file, "&Save", QKeySequence::Save, [this] {
    if (doc_->file_path().isEmpty()) {
      const QString path = QFileDialog::getSaveFileName(this, "Save pipeline", "pipeline.yaml", "Pipelines (*.yaml)");
      if (!path.isEmpty()) save_file(path);
    } else {
      save_file(doc_->file_path());
    }
  });
  add(file, "Save &As…", QKeySequence::SaveAs, [this] {
    const QString path = QFileDialog::getSaveFileName(this, "Save pipeline as", doc_->file_path(), "Pipelines (*.yaml)");
    if (!path.isEmpty()) save_file(path);
  });
  file->addSeparator();
  add(file, "Save 3D &Screenshot…", QKeySequence(), [this] {
    const QString path = QFileDialog::getSaveFileName(this, "Save screenshot", "view.png", "PNG images (*.png)");
    if (path.isEmpty()) return;
    if (view3d_->save_screenshot(path)) log("Saved screenshot " + path);
    else log("Could not save screenshot " + path, true);
  });
  file->addSeparator();
  add(file, "&Quit", QKeySequence::Quit, [this] { close(); });

  QAction* undo = doc_->undo_stack()->createUndoAction(this, "&Undo");
  undo->setShortcut(QKeySequence::Undo);
  QAction* redo = doc_->undo_stack()->createRedoAction(this, "&Redo");
  redo->setShortcuts({QKeySequence("Ctrl+Shift+Z"), QKeySequence::Redo});
  edit->addAction(undo);
  edit->addAction(redo);
  edit->addSeparator();
  add(edit, "Cu&t", QKeySequence::Cut, [this] {
    copy_selection();
    scene_->delete_selection();
  });
  add(edit, "&Copy", QKeySequence::Copy, [this] { copy_selection(); });
  add(edit, "&Paste", QKeySequence::Paste, [this] { paste_clipboard(); });
  QAction* del = add(edit, "&Delete", QKeySequence::Delete, [this] { scene_->delete_selection(); });
  del->setShortcuts({QKeySequence::Delete, QKeySequence(Qt::Key_Backspace)});
  add(edit, "Select &All", QKeySequence::SelectAll, [this] { scene_->select_nodes(doc_->node_ids()); });
  edit->addSeparator();
  // Graph edit mode on the selected node's graph output, else on the graph shown last in 3D.
  add(edit, "Edit &Graph in 3D View", QKeySequence("Ctrl+E"), [this] {
    QString node, port;
    for (const QString& id : scene_->selected_node_ids()) {
      const ModuleSpec* spec = doc_->spec(id);
      for (const auto& out : spec ? spec->outputs() : std::vector<PortSpec>{}) {
        if (node.isEmpty() && std::find(out.types.begin(), out.types.end(), type_ids::graph) != out.types.end()) {
          node = id;
          port = QString::fromStdString(out.name);
        }
      }
    }
    for (const QString& name : view3d_->object_names()) {
      const int dot = name.lastIndexOf('.');
      if (node.isEmpty() && std::dynamic_pointer_cast<const SpatialGraph>(view3d_->object_data(name)) &&
          run_->output(name.left(dot), name.mid(dot + 1))) {
        node = name.left(dot);
        port = name.mid(dot + 1);
      }
    }
    if (node.isEmpty()) log("Edit graph: select a node with a graph output (run it first) or show a graph in 3D", true);
    else edit_graph(node, port);
  });
  add(edit, "&Leave Graph Edit Mode", QKeySequence(), [this] { edit_->stop(); });
  add(edit, "Place &Landmarks in 3D View", QKeySequence("Ctrl+L"), [this] { edit_landmarks(); });
  add(edit, "Leave Landmar&k Mode", QKeySequence(), [this] { landmarks_->stop(); });

  QAction* fit = add(view, "&Fit Pipeline", QKeySequence("F"), [this] { view_->fit_all(); });
  add(view, "Zoom &In", QKeySequence::ZoomIn, [this] { view_->zoom(1.25); });
  add(view, "Zoom &Out", QKeySequence::ZoomOut, [this] { view_->zoom(0.8); });
  QAction* camera = add(view, "&Reset 3D Camera", QKeySequence("R"), [this] { view3d_->reset_camera(); });

  run_all_ = add(run, "Run &All", QKeySequence("Ctrl+R"), [this] { run_all(); });
  run_selected_ = add(run, "Run to &Selected", QKeySequence("Ctrl+Shift+R"), [this] { run_selected(); });
  cancel_ = add(run, "&Cancel", QKeySequence("Esc"), [this] { cancel_run(); });

  for (QAction* a : {new_a, open_a, save_a}) bar->addAction(a);
  bar->addSeparator();
  for (QAction* a : {undo, redo}) bar->addAction(a);
  bar->addSeparator();
  for (QAction* a : {run_all_, run_selected_, cancel_}) bar->addAction(a);
  bar->addSeparator();
  for (QAction* a : {fit, camera}) bar->addAction(a);
}

void MainWindow::update_title() {
  const QString name = doc_->file_path().isEmpty() ? "untitled" : QFileInfo(doc_->file_path()).fileName();
  setWindowTitle(name + "[*] — Skelflow");
  setWindowModified(doc_->is_modified());
}

void MainWindow::update_run_actions() {
  const bool running = run_->is_running();
  run_all_->setEnabled(!running);
  run_selected_->setEnabled(!running && !scene_->selected_node_ids().isEmpty());
  cancel_->setEnabled(running);
}

void MainWindow::log(const QString& text, bool error) {
  const QString line = QTime::currentTime().toString("HH:mm:ss ") + text;
  if (error) log_->appendHtml("<span style='color:#e05050'>" + line.toHtmlEscaped() + "</span>");
  else log_->appendPlainText(line);
  statusBar()->showMessage(text, 6000);
}

QString MainWindow::log_text() const { return log_->toPlainText(); }

bool MainWindow::open_file(const QString& path) {
  // While the 3D view shows nothing, the node editor gets the larger part of the window, and a
  // pipeline without stored positions is laid out in rows as wide as the editor at a legible zoom.
  if (view3d_->object_names().isEmpty()) {
    const int total = split_->width();
    split_->setSizes({total * 3 / 5, total - total * 3 / 5});
  }
  doc_->set_layout_columns(NodeView::legible_columns(split_->sizes().value(0) - view_->verticalScrollBar()->sizeHint().width() -
                                                     2 * view_->frameWidth()));
  try {
    doc_->load(path);
  } catch (const std::exception& e) {
    log("Cannot open " + path + ": " + QString::fromStdString(e.what()), true);
    return false;
  }
  for (const auto& d : validate(doc_->pipeline())) log(QString::fromStdString(d.format()), true);
  add_recent(doc_->file_path());
  log("Opened " + doc_->file_path());
  return true;
}

bool MainWindow::save_file(const QString& path) {
  try {
    doc_->save(path);
  } catch (const std::exception& e) {
    log("Cannot save " + path + ": " + QString::fromStdString(e.what()), true);
    return false;
  }
  add_recent(doc_->file_path());
  log("Saved " + doc_->file_path());
  return true;
}

bool MainWindow::maybe_save() {
  if (!doc_->is_modified()) return true;
  const auto answer = QMessageBox::warning(this, "Unsaved changes", "The pipeline has unsaved changes. Save them?",
                                           QMessageBox::Save | QMessageBox::Discard | QMessageBox::Cancel);
  if (answer == QMessageBox::Cancel) return false;
  if (answer == QMessageBox::Discard) return true;
  QString path = doc_->file_path();
  if (path.isEmpty()) path = QFileDialog::getSaveFileName(this, "Save pipeline", "pipeline.yaml", "Pipelines (*.yaml)");
  return !path.isEmpty() && save_file(path);
}

void MainWindow::closeEvent(QCloseEvent* e) {
  if (!maybe_save()) {
    e->ignore();
    return;
  }
  run_->cancel();
  run_->wait();
  e->accept();
}

QStringList MainWindow::recent_files() const { return QSettings().value("recent_files").toStringList(); }

void MainWindow::add_recent(const QString& path) {
  QStringList files = recent_files();
  files.removeAll(path);
  files.prepend(path);
  while (files.size() > kMaxRecent) files.removeLast();
  QSettings().setValue("recent_files", files);
  rebuild_recent_menu();
}

void MainWindow::rebuild_recent_menu() {
  recent_menu_->clear();
  const QStringList files = recent_files();
  for (const QString& f : files) {
    QAction* a = recent_menu_->addAction(QFileInfo(f).fileName());
    a->setToolTip(f);
    connect(a, &QAction::triggered, this, [this, f] {
      if (maybe_save()) open_file(f);
    });
  }
  recent_menu_->setEnabled(!files.isEmpty());
}

void MainWindow::copy_selection() {
  const QStringList ids = scene_->selected_node_ids();
  if (ids.isEmpty()) return;
  auto* mime = new QMimeData;
  const QString yaml = doc_->copy_nodes(ids);
  mime->setData(kClipboardMime, yaml.toUtf8());
  mime->setText(yaml);
  QApplication::clipboard()->setMimeData(mime);
  paste_count_ = 0;
}

void MainWindow::paste_clipboard() {
  const QMimeData* mime = QApplication::clipboard()->mimeData();
  if (!mime) return;
  const QString text = mime->hasFormat(kClipboardMime) ? QString::fromUtf8(mime->data(kClipboardMime)) : mime->text();
  QString error;
  ++paste_count_;
  const QPointF at = view_->visible_center() + QPointF(30.0 * paste_count_, 30.0 * paste_count_);
  const QStringList ids = doc_->paste(text, at, &error);
  if (ids.isEmpty()) log(error, true);
  else scene_->select_nodes(ids);
}

void MainWindow::run_all() {
  if (run_->is_running()) return;
  log("Running " + QString::number(doc_->node_ids().size()) + " nodes");
  run_->start();
}

void MainWindow::run_selected() {
  const QStringList ids = scene_->selected_node_ids();
  if (run_->is_running() || ids.isEmpty()) return;
  log("Running up to " + ids.join(", "));
  run_->start(ids);
}

void MainWindow::cancel_run() {
  if (!run_->is_running()) return;
  log("Cancelling…");
  run_->cancel();
}

QStringList MainWindow::show_final_geometry() {
  const QStringList names = final_geometry_outputs(
      doc_->pipeline(), doc_->registry(), [this](const std::string& node, const std::string& port) {
        return run_->output(QString::fromStdString(node), QString::fromStdString(port));
      });
  QStringList shown;
  for (const QString& name : names) {
    const int dot = name.lastIndexOf('.');
    QString error;
    if (view3d_->show_data(name, run_->output(name.left(dot), name.mid(dot + 1)), &error)) shown << name;
    else log(error, true);
  }
  if (!shown.isEmpty()) log("Showing the final geometry: " + shown.join(", ") + " (click an output port to show another)");
  return shown;
}

bool MainWindow::show_output(const QString& node, const QString& port) {
  view_chosen_ = true;  // the user decides what the view shows from now on
  if (run_->is_running()) {
    log("A run is in progress; click the port again when it has finished.");
    return false;
  }
  DataPtr data = run_->output(node, port);
  if (!data) {
    // Not computed for the current parameters: run what it needs, then show it.
    pending_node_ = node;
    pending_port_ = port;
    log("Computing " + node + "." + port + "…");
    if (!run_->start({node})) pending_node_.clear();
    return false;
  }
  const QString name = node + "." + port;
  if (data->type_id() == type_ids::table) {
    show_table(name, data);
    return true;
  }
  if (auto cells = std::dynamic_pointer_cast<const GridCells>(data)) {
    // A grid cell complex is shown as its simple geometry (geometry.cells_to_mesh): 2-cells as
    // triangles, 1-cells as lines, coloured by the manifold class; the data itself stays cells.
    try {
      data = std::make_shared<Mesh>(geometry::cells_to_mesh(*cells));
    } catch (const std::exception& e) {
      log("Cannot show " + name + ": " + QString::fromStdString(e.what()), true);
      return false;
    }
    log("Showing the grid cell complex " + name + " as its simple geometry (as geometry.cells_to_mesh makes it)");
  }
  QString error;
  if (!view3d_->show_data(name, data, &error)) {
    log(error, true);
    return false;
  }
  return true;
}

bool MainWindow::edit_graph(const QString& node, const QString& port) {
  if (run_->is_running()) {
    log("A run is in progress; edit the graph when it has finished.", true);
    return false;
  }
  landmarks_->stop();
  return edit_->start(node, port);
}

void MainWindow::edit_landmarks() {
  edit_->stop();
  landmarks_->start();
}

void MainWindow::show_table(const QString& name, const DataPtr& data) {
  auto t = std::dynamic_pointer_cast<const Table>(data);
  if (!t) return;
  table_->clear();
  table_->setColumnCount(static_cast<int>(t->columns().size()));
  const int rows = static_cast<int>(std::min<int64_t>(t->rows(), 100000));
  table_->setRowCount(rows);
  QStringList headers;
  for (const auto& c : t->columns()) {
    headers << QString::fromStdString(c.name) + (c.unit.empty() ? "" : " [" + QString::fromStdString(c.unit) + "]");
  }
  table_->setHorizontalHeaderLabels(headers);
  for (size_t c = 0; c < t->columns().size(); ++c) {
    for (int r = 0; r < rows; ++r) {
      table_->setItem(r, static_cast<int>(c), new QTableWidgetItem(QString::fromStdString(t->cell(c, r))));
    }
  }
  table_->resizeColumnsToContents();
  if (auto* dock = qobject_cast<QDockWidget*>(table_->parentWidget())) {
    dock->setWindowTitle("Table: " + name);
    dock->raise();
  }
  log("Showing table " + name + " (" + QString::number(t->rows()) + " rows)");
}

}  // namespace skel::gui
